"""docs/api.md: generated from the code, and listing every public name that dir() finds."""

from __future__ import annotations

import enum
import typing
from pathlib import Path

import pytest

import tumble
from tumble import apidoc

PAGE = Path(__file__).resolve().parents[2] / "docs" / "api.md"
#: what a class inherits from Python's own bases, which the page does not repeat
BUILTIN = set(dir(int)) | set(dir(tuple)) | set(dir(Exception)) | set(dir(enum.IntEnum)) | set(dir(dict))


def test_the_page_is_up_to_date():
    """docs/api.md is what `python -m tumble.apidoc` writes now (rerun it after changing the API)."""
    assert PAGE.read_text(encoding="utf-8") == apidoc.render(), "docs/api.md is stale: run python -m tumble.apidoc"


def test_every_exported_name_has_a_section():
    """Each name in tumble.__all__ has its own `tumble.<name>` heading."""
    page = apidoc.render()
    for name in tumble.__all__:
        assert f"## `tumble.{name}`" in page, name


@pytest.mark.parametrize("cls", apidoc.CLASSES, ids=lambda c: c.__name__)
def test_every_public_member_is_listed(cls):
    """Every public name dir() finds on the class (and on a World instance) is on the page."""
    page = apidoc.render()
    names = {n for n in dir(cls) if not n.startswith("_")} - BUILTIN
    if issubclass(cls, enum.Enum):
        names |= set(cls.__members__)
    if cls is tumble.World:
        names |= {n for n in dir(tumble.World()) if not n.startswith("_")}
    missing = sorted(n for n in names if f"`{cls.__name__}.{n}`" not in page)
    assert not missing, f"not in docs/api.md: {missing}"
    if typing.is_typeddict(cls):  # a keyword set: a table row for each of its keys, in its own section
        section = page.split(f"## `tumble.{cls.__name__}`")[1].split("\n## ")[0]
        missing = sorted(key for key in cls.__annotations__ if f"| `{key}` |" not in section)
        assert not missing, f"keys not in docs/api.md: {missing}"


def test_the_page_names_nothing_that_does_not_exist():
    """Every `Class.member` the page lists exists, so removed calls leave the page too."""
    import re

    page = apidoc.render()
    classes = {c.__name__: c for c in apidoc.CLASSES}
    world = tumble.World()
    for cls_name, member in re.findall(r"`(\w+)\.(\w+)`", page):
        if cls_name in classes:
            owner = world if cls_name == "World" else classes[cls_name]
            assert (
                hasattr(owner, member)
                or member in getattr(owner, "_fields", ())
                or member in getattr(owner, "__dataclass_fields__", {})
            ), f"{cls_name}.{member}"
