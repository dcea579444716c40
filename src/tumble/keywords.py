"""Keyword lists written once, for API calls that share them.

- `keywords_of(target)`: a method `f(self, **keywords)` that hands every keyword on to the method
  `target` takes `target`'s signature, defaults included, for `inspect`, the API page, the scene
  schema's defaults and type checkers (through a ParamSpec). A wrong keyword is the TypeError Python
  raises for a bad call, naming the method called.
- A set of keywords that several calls take beside their own (`tumble.SolidOptions`: the solid body
  adders') is a TypedDict, taken as `**options: Unpack[...]`, so that type checkers and IDEs know its
  keys and types. Its defaults sit beside it, in one mapping made by `defaults` (which checks, when the
  module is imported, that they name exactly the TypedDict's keys); `given` fills them in.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any, Concatenate, ParamSpec, TypeVar

_P = ParamSpec("_P")
_R = TypeVar("_R")
_S = TypeVar("_S")


def keywords_of(
    target: Callable[Concatenate[Any, _P], object],
) -> Callable[[Callable[..., _R]], Callable[Concatenate[_S, _P], _R]]:
    """Give a method `f(self, **keywords)` the keyword-only parameters of the method `target` (its first
    parameter, `self`, left out), with the method's own return type."""
    parameters = list(inspect.signature(target).parameters.values())[1:]
    if any(p.kind is not p.KEYWORD_ONLY for p in parameters):
        raise TypeError(f"keywords_of: {target.__qualname__} must take keyword-only parameters after self")

    def decorate(method: Callable[..., _R]) -> Callable[Concatenate[_S, _P], _R]:
        own = inspect.signature(method)
        signature = own.replace(parameters=[next(iter(own.parameters.values())), *parameters])

        @functools.wraps(method)
        def handing_on(self: _S, *args: _P.args, **keywords: _P.kwargs) -> _R:
            try:
                signature.bind(self, *args, **keywords)
            except TypeError as exc:
                raise TypeError(f"{method.__qualname__}() {exc}") from None
            return method(self, *args, **keywords)

        del handing_on.__wrapped__  # inspect shows `signature`, not the method's (self, **keywords)
        handing_on.__signature__ = signature  # type: ignore[attr-defined]
        return handing_on

    return decorate


#: each keyword set's defaults, by its TypedDict (`defaults`)
_DEFAULTS: dict[type, Mapping[str, Any]] = {}


def defaults(options: type, **values: Any) -> Mapping[str, Any]:
    """The defaults of the keyword set `options` (a TypedDict): `values`, which must name every key of it
    and no other (a TypeError at import otherwise). Read-only; `defaults_of(options)` finds them again."""
    keys = set(options.__annotations__)
    if set(values) != keys:
        odd = sorted(set(values) ^ keys)
        raise TypeError(f"defaults of {options.__name__} must name exactly its keys; these differ: {odd}")
    _DEFAULTS[options] = MappingProxyType(values)
    return _DEFAULTS[options]


def defaults_of(options: type) -> Mapping[str, Any]:
    """The defaults `defaults` declared for the keyword set `options` (a KeyError for another class)."""
    return _DEFAULTS[options]


def given(options: Mapping[str, Any], default: Mapping[str, Any], caller: str) -> dict[str, Any]:
    """The keywords a call was given as `**options`, with `default`'s for the rest; a keyword `default`
    does not know is the TypeError Python raises for a bad call, naming `caller`."""
    for key in options:
        if key not in default:
            raise TypeError(f"{caller}() got an unexpected keyword argument '{key}'")
    return {**default, **options}
