"""tumble.keywords: a method that hands its keywords on shows its target's signature; keyword sets' defaults."""

from __future__ import annotations

import inspect
from typing import Any, TypedDict

import pytest

from tumble.keywords import defaults, defaults_of, given, keywords_of


class Target:
    def build(self, *, size: float = 1.0, name: str = "a") -> tuple[float, str]:
        return size, name


class Front:
    def __init__(self) -> None:
        self.target = Target()

    @keywords_of(Target.build)
    def build(self, **keywords: Any) -> list:
        """Build through the target."""
        return list(self.target.build(**keywords))


def test_a_method_handing_on_shows_the_targets_keywords_and_its_own_return():
    sig = inspect.signature(Front.build)
    assert list(sig.parameters) == ["self", "size", "name"]
    assert sig.parameters["size"].default == 1.0 and sig.parameters["name"].default == "a"
    assert sig.return_annotation == "list"
    assert Front.build.__doc__ == "Build through the target."
    assert Front().build(name="b") == [1.0, "b"]


def test_a_wrong_keyword_names_the_method_called():
    with pytest.raises(TypeError, match=r"^Front.build\(\) got an unexpected keyword argument 'sise'$"):
        Front().build(sise=2.0)


def test_a_target_with_positional_parameters_is_refused():
    def positional(self, size):
        return size

    with pytest.raises(TypeError, match="keyword-only"):
        keywords_of(positional)


class Options(TypedDict, total=False):
    width: float
    label: str


def test_defaults_must_name_exactly_the_keys_and_are_read_only():
    d = defaults(Options, width=2.0, label="x")
    assert dict(d) == {"width": 2.0, "label": "x"} and defaults_of(Options) is d
    with pytest.raises(TypeError):
        d["width"] = 3.0  # type: ignore[index]
    with pytest.raises(TypeError, match=r"\['label'\]"):
        defaults(Options, width=2.0)
    with pytest.raises(TypeError, match=r"\['height'\]"):
        defaults(Options, width=2.0, label="x", height=1.0)


def test_given_fills_in_defaults_and_refuses_unknown_keys():
    d = defaults(Options, width=2.0, label="x")
    assert given({"label": "y"}, d, "f") == {"width": 2.0, "label": "y"}
    with pytest.raises(TypeError, match=r"^f\(\) got an unexpected keyword argument 'hight'$"):
        given({"hight": 1.0}, d, "f")
