"""Tolerances derived from the precision the tests' worlds run in.

A test's worlds run in Tumble's default precision, or in the one `pytest --precision` names, or in
float64 when the test is marked `@pytest.mark.float64("why")` (`tests/conftest.py`). A bound that
means "exact but for rounding" is a number of ulps of the compared quantity in that precision:
~1e-16 relative in float64, ~1e-7 in float32. Bounds that come from the physics (dt, the contact
stiffness, the slop) do not depend on the precision and are written out in each test.

Read the precision when the test runs (inside the test body), never at import: the fixture that
sets it runs per test.
"""

from __future__ import annotations

import numpy as np

from tumble import precision


def eps() -> float:
    """Machine epsilon (the spacing of floats at 1) of the precision the test's worlds run in."""
    return precision.types_of(precision.DEFAULT_PRECISION).eps


def is_float32() -> bool:
    """Whether the test's worlds run in float32."""
    return precision.DEFAULT_PRECISION == "float32"


def dtype() -> type:
    """The NumPy scalar type of the test's worlds' float arrays (np.float32 or np.float64)."""
    return precision.types_of(precision.DEFAULT_PRECISION).numpy


def stored(values) -> np.ndarray:
    """`values` as a world in the test's precision holds them, as float64: rounded to its dtype (0.1 reads
    back 0.10000000149 in float32), and a magnitude below the dtype's smallest normal (1.2e-38 in
    float32, which a float32 world refuses) made 0. Inputs that Hypothesis draws near zero (1e-220)
    are passed through it, so that a test of "any placement" places what the world can hold, and
    computes its reference from that; in float64 it changes nothing."""
    given = np.asarray(values, dtype=np.float64)
    t = dtype()
    if t is np.float64:
        return given
    flushed = np.where(np.abs(given) < np.finfo(t).tiny, 0.0, given)
    return flushed.astype(t).astype(np.float64)


def ulps(scale: float, n: float = 16.0) -> float:
    """`n` ulps of a quantity of size `scale` in the test's precision (a floor of `n` ulps of 1e-300)."""
    return n * eps() * max(abs(scale), 1e-300)


def resolution(bound: float, scale: float, n: float = 16.0) -> float:
    """`bound`, or `n` ulps of `scale` in the precision the test's worlds run in, the larger: a bound
    written as "exact up to rounding" in float64 (1e-9 against ~1e-16) where float32 resolves ~1e-7."""
    return max(bound, ulps(scale, n))


def rounding() -> float:
    """Relative bound on rounding accumulated over ~10^4 substeps: 1e-12 in float64 (~4,500 ulps at 1),
    as many ulps of the precision the test's worlds run in."""
    return 1e-12 * eps() / precision.types_of("float64").eps


def in_float32(bound: float, term: float) -> float:
    """`bound` as written in float64 (never loosened there); in float32 the larger of it and `term`, a
    float32-only allowance (rounding accumulated over many substeps, or the float32 solver's documented
    tolerances) whose float64 counterpart may exceed a bound written as "exact up to rounding"."""
    return max(bound, term) if is_float32() else bound
