"""forward.py: a forwarding method shows and checks its source's parameters; `arguments` drops only `self`."""

from __future__ import annotations

import inspect
from typing import Any

import pytest

import tumble
from tumble.forward import arguments, keywords_of


class _Source:
    def build(self, *, size: int = 3, name: str = "a") -> tuple[int, str]:
        """The source's doc."""
        return size, name


class _Front:
    @keywords_of(_Source.build)
    def build(self, **keywords: Any) -> list:
        """The front's doc."""
        return [self, *_Source().build(**keywords)]

    def collect(self, *, a: int = 1, b: str = "x") -> dict[str, Any]:
        return arguments(locals())


def test_keywords_of_takes_the_source_parameters_and_keeps_its_own_return_and_doc():
    """Signature: self, then the source's keyword-only parameters with their defaults; return and doc the method's."""
    sig = inspect.signature(_Front.build)
    assert list(sig.parameters) == ["self", "size", "name"]
    assert sig.parameters["size"].default == 3 and sig.parameters["name"].kind is inspect.Parameter.KEYWORD_ONLY
    assert sig.return_annotation == "list"
    assert _Front.build.__doc__ == "The front's doc." and _Front.build.__name__ == "build"
    front = _Front()
    assert front.build() == [front, 3, "a"] and front.build(name="b") == [front, 3, "b"]


def test_keywords_of_names_the_method_in_a_bad_call():
    """An unknown keyword or a positional argument is the method's TypeError, before the source runs."""
    with pytest.raises(TypeError, match=r"^_Front.build\(\) got an unexpected keyword argument 'colour'$"):
        _Front().build(colour=1)
    with pytest.raises(TypeError, match=r"^_Front.build\(\) too many positional arguments$"):
        _Front().build(4)  # type: ignore[call-arg]


def test_keywords_of_refuses_a_source_with_positional_parameters():
    def positional(self, size):
        return size

    with pytest.raises(TypeError, match="keyword-only"):
        keywords_of(positional)


def test_arguments_are_the_call_s_values_without_self():
    assert _Front().collect() == {"a": 1, "b": "x"}
    assert _Front().collect(b="y") == {"a": 1, "b": "y"}


def test_world_methods_show_their_source_s_signature():
    """World.add_cloth / set_wind / add_emitter document ClothSystem's and Emitter's keywords, as docs/api.md does."""
    for method, source in (
        (tumble.World.add_cloth, tumble.ClothSystem.add_cloth),
        (tumble.World.set_wind, tumble.ClothSystem.set_wind),
        (tumble.World.add_emitter, tumble.Emitter.__init__),
    ):
        ours, theirs = inspect.signature(method).parameters, inspect.signature(source).parameters
        assert list(ours.values())[1:] == list(theirs.values())[1:]
    assert inspect.signature(tumble.World.add_cloth).return_annotation == "ClothId"
