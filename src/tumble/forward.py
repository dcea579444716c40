"""Methods that hand their keywords on to another callable, with the argument list written once.

- `keywords_of(source)`: a method whose parameters are `source`'s (a method or a function, its first
  parameter left out): the signature (`inspect.signature`, docs/api.md) and the static types (mypy)
  are `source`'s, the return type and the docstring the method's own;
- `arguments(locals())`: a method's arguments by name, for a method that keeps a signature of its
  own (other types or defaults) and forwards them all.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from typing import Any, Concatenate, ParamSpec, TypeVar

P = ParamSpec("P")
R = TypeVar("R")
S = TypeVar("S")


def keywords_of(
    source: Callable[Concatenate[Any, P], object],
) -> Callable[[Callable[Concatenate[S, ...], R]], Callable[Concatenate[S, P], R]]:
    """Decorate a method `f(self, **keywords)` to take `source`'s parameters (all but its first, e.g. `self`).

    The method's signature becomes `(self, <source's parameters>) -> <the method's return annotation>`;
    it is called with the keywords as given (the defaults are `source`'s, applied when it is called).
    """
    parameters = list(inspect.signature(source).parameters.values())[1:]
    if any(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD, p.VAR_POSITIONAL) for p in parameters):
        raise TypeError(f"keywords_of: {source.__qualname__} takes positional arguments; it is for keyword-only ones")

    def decorate(method: Callable[Concatenate[S, ...], R]) -> Callable[Concatenate[S, P], R]:
        own = inspect.signature(method)
        first = next(iter(own.parameters.values()))

        signature = own.replace(parameters=[first, *parameters])

        @functools.wraps(method)
        def forwarding(self: S, *args: P.args, **keywords: P.kwargs) -> R:
            try:
                signature.bind(self, *args, **keywords)
            except TypeError as exc:  # named as Python names a bad call, by this method
                raise TypeError(f"{method.__qualname__}() {exc}") from None
            return method(self, *args, **keywords)

        del forwarding.__wrapped__  # the signature is the one below, not the method's (**keywords)
        forwarding.__signature__ = signature  # type: ignore[attr-defined]
        return forwarding

    return decorate


def arguments(frame_locals: dict[str, Any]) -> dict[str, Any]:
    """A method's arguments by name, from its `locals()` taken before it binds any other name; `self` left out."""
    return {name: value for name, value in frame_locals.items() if name != "self"}
