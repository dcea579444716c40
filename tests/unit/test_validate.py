"""validate.py: each check returns the engine's type or raises TypeError / ValueError as "<name> must be <what>, got <value>"."""

from __future__ import annotations

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
