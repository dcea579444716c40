"""io/scene/checks.py: value checks convert TOML values or say why not; cross-key rules blame a key."""

from __future__ import annotations

import pytest

from tumble.io.scene import checks


@pytest.mark.parametrize(
    "check, value, expected",
    [
        (checks.number(low=0, low_open=True), 2, 2.0),
        (checks.integer(low=1), 3, 3),
        (checks.boolean(), False, False),
        (checks.choice("point", "disc"), "disc", "disc"),
        (checks.vector(3), [1, 2, 3], [1.0, 2.0, 3.0]),
        (checks.quaternion(), [0, 0, 0, 2], [0.0, 0.0, 0.0, 2.0]),
        (checks.value_or_range(positive=True), [1, 2], (1.0, 2.0)),
        (checks.size_or_range(), [[1, 1, 1], [2, 2, 2]], ((1.0, 1.0, 1.0), (2.0, 2.0, 2.0))),
        (checks.extent(), 0.5, 0.5),
        (checks.shape_list(), ["sphere", "box"], ["sphere", "box"]),
        (checks.scale_factor(), [1, 2, 3], [1.0, 2.0, 3.0]),
        (checks.per_spring(), {"bend": 1}, {"bend": 1.0}),
        (checks.pins(), [[0, 1]], [(0, 1)]),
        (checks.resolution(), [4, 3], [4, 3]),
    ],
)
def test_checks_convert_good_values(check, value, expected):
    """Return the value the World API takes: floats for numbers, tuples for ranges and pins."""
    out = check(value)
    assert out == expected and type(out) is type(expected)


@pytest.mark.parametrize(
    "check, value, message",
    [
        (checks.number(), True, "must be a number, got true"),
        (checks.number(low=0, low_open=True), 0, "must be > 0, got 0"),
        (checks.number(high=1), 2, "2 is too large: must be <= 1"),
        (checks.integer(low=1), 1.5, "must be an integer, got 1.5"),
        (checks.boolean(), 1, "must be true or false, got 1"),
        (checks.choice("a", "b"), "c", "unknown value 'c': expected one of 'a', 'b'"),
        (checks.vector(3), [1, 2], "must have 3 components, got 2"),
        (checks.vector(3, nonzero=True), [0, 0, 0], "must not be the zero vector"),
        (checks.vector(3), {"x": 1}, "must be a list of 3 numbers, got a table"),
        (checks.quaternion(), [0, 0, 0, 0], "must be a non-zero quaternion [x, y, z, w]"),
        (checks.value_or_range(positive=False), [2, 1], "range [min, max] must have min <= max, got [2, 1]"),
        (checks.per_spring(), {"twist": 1}, "unknown spring kind 'twist'"),
        (checks.per_spring(), {"bend": -1}, "bend must be >= 0, got -1"),
        (checks.pins(), [[0, 1.5]], "each pin must be a grid point [i, j] of two integers"),
    ],
)
def test_checks_refuse_bad_values_with_the_reason(check, value, message):
    """Raise Bad whose message is the reason alone (the parser adds file, table and key)."""
    with pytest.raises(checks.Bad) as info:
        check(value)
    assert str(info.value).startswith(message)


def test_kind_is_the_type_the_reference_shows():
    """Describe each check as docs/scenes.md writes its type."""
    assert checks.number(low=0, low_open=True).kind == "float > 0"
    assert checks.number(low=0, high=1).kind == "float in [0, 1]"
    assert checks.integer(low=1, high=64).kind == "integer in [1, 64]"
    assert checks.choice("a", "b", "c").kind == '"a", "b" or "c"'
    assert checks.vector(3, positive=True).kind == "[x, y, z] floats, each > 0"


def test_show_keeps_toml_spelling_and_long_values_short():
    """Show booleans as TOML writes them, tables as "a table", and cut long values."""
    assert checks.show(True) == "true" and checks.show({"a": 1}) == "a table"
    assert len(checks.show(list(range(100)))) <= 80


@pytest.mark.parametrize(
    "rule, values, key, message",
    [
        (checks.mass_or_density, {"mass": 1.0, "density": 2.0}, "density", "give mass or density, not both"),
        (checks.mass_or_density, {"radius": 1e300, "mass": None, "density": None}, "radius", "must be finite"),
        (checks.convex_rules, {"points": None, "file": None}, "points", "give points or file"),
        (
            checks.emitter_rules,
            {"shape": "box", "region": "point", "half_extents": None},
            "half_extents",
            "a box emitter needs half_extents",
        ),
        (
            checks.cloth_rules,
            {"resolution": [4, 4], "pins": [(4, 0)]},
            "pins",
            "pin [4, 0] is outside the 4 x 4 grid",
        ),
        (
            checks.joint_rules,
            {"body_a": "box[0]", "body_b": "box[0]"},
            "body_b",
            "a joint needs two different bodies",
        ),
        (
            checks.joint_rules,
            {"body_a": "world", "body_b": "box[0]", "lower": 2.0, "upper": 1.0},
            "lower",
            "lower 2 > upper 1",
        ),
    ],
)
def test_cross_key_rules_blame_a_key(rule, values, key, message):
    """Raise KeyBad naming the key at fault when the converted values of a table disagree."""
    with pytest.raises(checks.KeyBad) as info:
        rule(values)
    assert info.value.key == key and message in str(info.value)


def test_cross_key_rules_pass_consistent_values():
    """Let a table that breaks no rule through unchanged."""
    values = {"radius": 0.1, "mass": 1.0, "density": None}
    checks.mass_or_density(values)
    checks.cloth_rules({"resolution": [4, 4], "pins": [(3, 3)]})
    assert values == {"radius": 0.1, "mass": 1.0, "density": None}
