"""validate.py: each check returns the engine's type or raises TypeError / ValueError as "<name> must be <what>, got <value>"."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tumble import validate


def test_number_ranges_and_messages():
    """Finite reals within [low, high] or (low, high]; bools and strings are TypeError."""
    assert validate.number(np.float32(2.5), "x") == 2.5 and type(validate.number(3, "x")) is float
    assert validate.number(0.0, "x", low=0.0) == 0.0
    assert validate.number(np.array(4.0), "x") == 4.0  # a 0-d array is a number
    with pytest.raises(ValueError, match=r"^radius must be a positive number, got 0.0$"):
        validate.positive(0.0, "radius")
    with pytest.raises(ValueError, match=r"^e must be in \[0, 1\], got 1.5$"):
        validate.number(1.5, "e", low=0.0, high=1.0)
    with pytest.raises(ValueError, match=r"^mu must be a number >= 0, got -0.1$"):
        validate.number(-0.1, "mu", low=0.0)
    with pytest.raises(ValueError, match="must be finite, got nan"):
        validate.number(float("nan"), "x")
    for bad in (True, "1.0", None, [1.0]):
        with pytest.raises(TypeError, match="x must be a number"):
            validate.number(bad, "x")


def test_integer_takes_integral_floats_and_refuses_fractions():
    """8.0 -> 8 and np.int64 -> int; 2.5, inf and values under low are ValueError, True is TypeError."""
    assert validate.integer(8.0, "n") == 8 and type(validate.integer(np.int64(3), "n")) is int
    for bad in (2.5, float("inf")):
        with pytest.raises(ValueError, match="n must be an integer"):
            validate.integer(bad, "n")
    with pytest.raises(ValueError, match=r"^substeps must be an integer >= 1, got 0$"):
        validate.integer(0, "substeps", low=1)
    with pytest.raises(TypeError):
        validate.integer(True, "n")


def test_flag_text_and_callable():
    """flag takes only booleans; text checks the choices; callable_or_none refuses other values."""
    assert validate.flag(np.bool_(True), "static") is True
    with pytest.raises(TypeError, match="static must be True or False, got 1"):
        validate.flag(1, "static")
    assert validate.text("box", "shape", ("sphere", "box")) == "box"
    with pytest.raises(ValueError, match=r"^shape must be one of 'sphere', 'box', got 'cone'$"):
        validate.text("cone", "shape", ("sphere", "box"))
    with pytest.raises(TypeError, match="must be a string"):
        validate.text(3, "shape")
    assert validate.callable_or_none(None, "f") is None and validate.callable_or_none(print, "f") is print
    with pytest.raises(TypeError, match="f must be a function or None"):
        validate.callable_or_none(3, "f")


def test_vector_rows_and_positive_rows():
    """Vectors have n finite components; rows broadcast one row to n; positive_rows broadcasts one number."""
    v = validate.vector([1, 2, 3], "position")
    assert v.dtype == np.float64 and v.tolist() == [1.0, 2.0, 3.0]
    with pytest.raises(ValueError, match="position must have 3 components"):
        validate.vector([1, 2], "position")
    with pytest.raises(ValueError, match="position must be finite"):
        validate.vector([1, np.inf, 3], "position")
    with pytest.raises(TypeError):
        validate.vector(["a", "b", "c"], "position")
    with pytest.raises(ValueError):
        validate.vector([[1, 2], [3]], "position")  # ragged
    r = validate.rows([0.0, 0.0, 1.0], "position", 3, n=4)
    assert r.shape == (4, 3) and r.flags.writeable  # a copy, not a read-only broadcast view
    with pytest.raises(ValueError, match=r"shape \(2, 3\)"):
        validate.rows(np.zeros((3, 3)), "position", 3, n=2)
    np.testing.assert_array_equal(validate.positive_rows(0.5, "radius", 3), [0.5, 0.5, 0.5])
    with pytest.raises(ValueError, match="each of the 3"):
        validate.positive_rows([0.5, -1.0, 0.2], "radius", 3)


def test_quaternion_is_normalised_and_zero_is_refused():
    """A quaternion comes back unit length, one or n of them; (0, 0, 0, 0) is ValueError."""
    np.testing.assert_allclose(validate.quaternion([0, 0, 0, 2]), [0, 0, 0, 1])
    q = validate.quaternion([1, 1, 1, 1], n=2)
    assert q.shape == (2, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    with pytest.raises(ValueError, match="non-zero quaternion"):
        validate.quaternion([0, 0, 0, 0])


def test_show_keeps_messages_to_one_short_line():
    """Long values are cut to 60 characters, big arrays named by shape, NumPy scalars shown as Python ones."""
    assert validate.show(np.float64(2.0)) == "2.0"
    assert validate.show(np.zeros((1000, 3))) == "an array of shape (1000, 3)"
    long = validate.show("x" * 500)
    assert len(long) == 60 and long.endswith("...")
    small = validate.show(np.ones((2, 3), dtype=bool))  # a small 2-d array's repr spans lines
    assert "\n" not in small and small.startswith("array([[ True, True, True], [")


def test_the_rules_the_scene_checks_share():
    """is_real refuses bools and strings; within is finite and bounded (open with above/below); is_zero."""
    assert validate.is_real(3) and validate.is_real(np.float32(1.0)) and validate.is_real(np.array(2.0))
    assert not any(validate.is_real(v) for v in (True, np.bool_(False), "1", None, [1.0]))
    assert validate.within(0.0, low=0.0) and not validate.within(0.0, low=0.0, above=True)
    assert validate.within(180.0, high=180.0) and not validate.within(180.0, high=180.0, below=True)
    assert not validate.within(float("nan")) and not validate.within(float("inf"), low=0.0)
    assert validate.is_zero([0.0, 1e-13, 0.0]) and not validate.is_zero([0.0, 0.0, 1e-11])
    with pytest.raises(ValueError, match=r"^fov must be in \(0, 180\), got 180$"):
        validate.number(180, "fov", low=0.0, high=180.0, above=True, below=True)


def test_material_coefficients():
    """restitution lies in [0, 1], friction is >= 0, each named as the API calls it."""
    assert validate.restitution(1) == 1.0 and validate.friction(0) == 0.0
    with pytest.raises(ValueError, match=r"^restitution must be in \[0, 1\], got 1.5$"):
        validate.restitution(1.5)
    with pytest.raises(ValueError, match=r"^friction must be a number >= 0, got -1$"):
        validate.friction(-1)


def test_integers_and_positive_vectors():
    """A resolution is n integers >= low; a size is n numbers each > 0."""
    assert validate.integers((4, 3.0), "resolution", 2, low=1) == (4, 3)
    with pytest.raises(ValueError, match=r"^resolution must be 2 integers, got \(4,\)$"):
        validate.integers((4,), "resolution", 2)
    with pytest.raises(ValueError, match=r"^resolution must be an integer >= 1, got 0$"):
        validate.integers((4, 0), "resolution", 2, low=1)
    with pytest.raises(TypeError, match="resolution must be 2 integers"):
        validate.integers("44", "resolution", 2)
    assert validate.positive_vector((1, 2), "size", 2).tolist() == [1.0, 2.0]
    with pytest.raises(ValueError, match=r"^size must all be > 0, got \(1, 0\)$"):
        validate.positive_vector((1, 0), "size", 2)


def test_direction_is_unit_and_zero_is_refused():
    """A direction comes back unit length; the zero vector raises ValueError naming it."""
    np.testing.assert_array_equal(validate.direction((0, 0, 2), "normal"), [0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r"^normal must not be zero, got \(0, 0, 0\)$"):
        validate.direction((0, 0, 0), "normal")


def test_vectors_whose_squares_overflow_keep_their_direction():
    """A quaternion or direction of components near 1e200 (squares past float64) normalises without a
    warning to the same unit vector; before, its norm overflowed to inf and it became (0, 0, 0, 0)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        q = validate.quaternion([1e200, 1e200, 0, 0])
        rows = validate.quaternion([[0, 0, 0, 1], [0, 0, -1.7e308, 1.7e308]], n=2)
        d = validate.direction((0, 1e300, 1e300), "normal")
        assert not validate.is_zero([1e300, 0, 0])
    np.testing.assert_allclose(q, [2**-0.5, 2**-0.5, 0, 0])
    np.testing.assert_allclose(rows, [[0, 0, 0, 1], [0, 0, -(2**-0.5), 2**-0.5]])
    np.testing.assert_allclose(d, [0, 2**-0.5, 2**-0.5])
    q = np.array([0.0, 0.0, 0.38, 0.92])
    np.testing.assert_array_equal(validate.quaternion(q), q / np.linalg.norm(q))  # ordinary values: bit for bit


def test_scale_is_one_factor_or_three():
    """One positive factor is repeated on every axis; three are taken; others raise ValueError."""
    np.testing.assert_array_equal(validate.scale(2), [2.0, 2.0, 2.0])
    np.testing.assert_array_equal(validate.scale((1, 2, 3)), [1.0, 2.0, 3.0])
    for bad in (0.0, (1, 2), (1, -1, 1), float("nan")):
        with pytest.raises(ValueError, match="scale must be one positive number or three"):
            validate.scale(bad)


def test_bounds_of_values_and_ranges():
    """A number is its own range; [min, max] is taken; vectors have `width` components; min > max is refused."""
    lo, hi = validate.bounds(2, "speed")
    assert lo == hi == 2.0
    lo, hi = validate.bounds([1, 3], "speed")
    assert (lo, hi) == (1.0, 3.0)
    lo, hi = validate.bounds(0.5, "half_extents", 3)
    assert lo.tolist() == hi.tolist() == [0.5, 0.5, 0.5]
    lo, hi = validate.bounds([[1, 1, 1], [2, 2, 2]], "half_extents", 3)
    assert lo.tolist() == [1.0] * 3 and hi.tolist() == [2.0] * 3
    with pytest.raises(ValueError, match=r"^speed: min must not exceed max, got \[3, 1\]$"):
        validate.bounds([3, 1], "speed")
    with pytest.raises(ValueError, match=r"^speed must be a number or a \[min, max\] pair"):
        validate.bounds([1, 2, 3], "speed")
    with pytest.raises(ValueError, match="speed must be finite"):
        validate.bounds([1, float("inf")], "speed")


@pytest.mark.parametrize(
    "mass, inertia, usable",
    [
        (1.0, [0.4, 0.4, 0.4], True),
        ([1.0, 2.0], [[1, 1, 1], [2, 2, 2]], True),
        (1e-300, [1e-300, 1e-300, 1e-300], True),  # tiny but its inverse (1e300) is finite
        (np.inf, [1, 1, 1], False),
        (0.0, [1, 1, 1], False),
        (-1.0, [1, 1, 1], False),
        (1.0, [np.nan, 1, 1], False),
        (1.0, [1e-320, 1, 1], False),  # subnormal: its inverse overflows
        ([1.0, np.inf], [[1, 1, 1], [1, 1, 1]], False),
    ],
)
def test_mass_properties_usable_wants_finite_positive_values_with_finite_inverses(mass, inertia, usable, recwarn):
    """The solver divides by masses and moments: each and its inverse must be finite and > 0; no warning either way."""
    assert validate.mass_properties_usable(mass, np.array(inertia, dtype=float)) is usable
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
