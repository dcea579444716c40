"""Fuzzing the scene loader and the CLI with mutated samples: exit 0 or 2, one line, no traceback.

Issue 13 (bad input, huge requests and failed writes). Each example takes a bundled sample and
breaks it: a value replaced by a wrong type, a huge or tiny number, NaN or infinity, a key
removed or an unknown one added, a deeply nested value, or the whole file replaced by binary
junk, an empty file or a truncated one. The property: `tumble check` (and, for fewer
examples, `tumble run` of one step with `--record`) exits 0 or 2; with 2, stderr is one line
"tumble COMMAND: error: ..."; never a traceback; each example within a time budget, and the
whole test within a memory budget (TUMBLE_MEMORY caps what a scene may plan for).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import resource
import time
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tumble.cli import main
from tumble.io.scene import list_samples

SAMPLES = {p.stem: p for p in list_samples()}
# cheap to build and step once: `run` is fuzzed on these (check on every sample)
RUN_SAMPLES = ("bouncing_ball", "ramp", "rain", "box_tower", "hammock", "pebbles")

#: seconds one example may take (a check is ~10 ms; a run of one step well under a second)
BUDGET_S = 20.0
#: memory Tumble may plan a scene with during the test, and the growth of the peak RSS allowed
PLAN_MEMORY = "1G"
RSS_GROWTH_BYTES = 1.5e9

WRONG_TYPES = ["text", True, [1, 2], {"a": 1}, [], [[1], [2]]]
HUGE = [1e308, 1.7e308, 10**18, 2**63 - 1, 1e30, 1e9]
TINY = [5e-324, 1e-300, 1e-30, 0, 0.0, -0.0, -1, -1e308, -(2**63)]
SPECIAL = [math.nan, math.inf, -math.inf]


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def to_toml(doc: dict) -> str:
    """A TOML document from parsed TOML data (tables and arrays of tables at the top only)."""
    lines = []
    for name, value in doc.items():
        if isinstance(value, dict):
            lines.append(f"[{name}]")
            lines += [f"{json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()]
        elif isinstance(value, list) and value and all(isinstance(t, dict) for t in value):
            for table in value:
                lines.append(f"[[{name}]]")
                lines += [f"{json.dumps(k)} = {_toml_value(v)}" for k, v in table.items()]
        else:
            lines.insert(0, f"{json.dumps(name)} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"


def _tables(doc: dict) -> list[tuple[str, int | None]]:
    out = []
    for name, value in doc.items():
        if isinstance(value, dict):
            out.append((name, None))
        elif isinstance(value, list):
            out += [(name, i) for i in range(len(value)) if isinstance(value[i], dict)]
    return out


@st.composite
def mutated_scene(draw, names=tuple(SAMPLES)) -> tuple[str, bytes]:
    """(sample name, bytes of a broken version of it)."""
    name = draw(st.sampled_from(sorted(names)))
    text = SAMPLES[name].read_text(encoding="utf-8")
    kind = draw(st.sampled_from(["value", "value", "value", "value", "remove", "unknown", "deep", "raw"]))
    if kind == "raw":
        raw = draw(st.sampled_from(["empty", "binary", "truncated", "nul", "deep_text"]))
        if raw == "empty":
            return name, b""
        if raw == "binary":
            return name, draw(st.binary(min_size=1, max_size=200))
        if raw == "truncated":
            data = text.encode()
            return name, data[: draw(st.integers(1, max(1, len(data) - 1)))]
        if raw == "nul":
            return name, text.encode().replace(b"\n", b"\x00\n", 1)
        depth = draw(st.sampled_from([100, 1000, 100_000]))
        return name, ("x = " + "[" * depth + "]" * depth + "\n").encode()
    doc = tomllib.loads(text)
    tables = _tables(doc)
    table, index = draw(st.sampled_from(tables))
    target = doc[table] if index is None else doc[table][index]
    if kind == "unknown":
        target[draw(st.sampled_from(["colour", "radiuss", "Dt", "", "x" * 200]))] = 1
    elif kind == "remove":
        if target:
            del target[draw(st.sampled_from(sorted(target)))]
        else:
            del doc[table]
    else:
        keys = sorted(target) or ["dt"]
        key = draw(st.sampled_from(keys))
        pool = draw(st.sampled_from([WRONG_TYPES, HUGE, TINY, SPECIAL]))
        value = draw(st.sampled_from(pool))
        old = target.get(key)
        if kind == "deep":
            depth = draw(st.sampled_from([20, 200, 3000]))
            value = 1
            for _ in range(depth if depth < 500 else 0):
                value = [value]
            if depth >= 500:  # too deep to build as data: write it as text
                target[key] = "DEEP"
                return name, to_toml(doc).replace('"DEEP"', "[" * depth + "]" * depth).encode()
        elif isinstance(old, list) and old and draw(st.booleans()):
            # one component of a vector or range
            value = [value if i == draw(st.integers(0, len(old) - 1)) else x for i, x in enumerate(old)]
        target[key] = value
    return name, to_toml(doc).encode()


def _cli(argv: list[str]) -> tuple[int, str, float]:
    err = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(argv)
    return rc, err.getvalue(), time.perf_counter() - start


def _assert_clean(rc: int, stderr: str, seconds: float, command: str, data: bytes, *, one_line: bool) -> None:
    shown = data[:300]
    assert "Traceback" not in stderr, (stderr, shown)
    assert rc in (0, 2), (rc, stderr, shown)
    # the budget is the command's own work: a kernel module compiled on first use (up to a minute on a
    # cold cache, the time `tumble run` reports) is Warp's one-time cost, not a hang
    compiled = re.search(r"kernels compiled in ([0-9.]+) s", stderr)
    assert seconds - (float(compiled.group(1)) if compiled else 0.0) < BUDGET_S, (seconds, stderr, shown)
    if rc == 2:
        lines = stderr.strip().splitlines()
        assert lines and lines[-1].startswith(f"tumble {command}: error: "), (stderr, shown)
        if one_line:
            assert len(lines) == 1, (stderr, shown)


@pytest.fixture(scope="module")
def rss_budget():
    """Fail when the peak resident memory grows by more than RSS_GROWTH_BYTES over the module."""
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    yield
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    assert after - before < RSS_GROWTH_BYTES, f"peak RSS grew by {(after - before) / 1e9:.2f} GB"


@pytest.fixture
def plan_memory(monkeypatch):
    monkeypatch.setenv("TUMBLE_MEMORY", PLAN_MEMORY)


FUZZ = settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@FUZZ
@given(case=mutated_scene())
def test_check_on_mutated_samples_exits_0_or_2_with_one_line(case, tmp_path, plan_memory, rss_budget):
    """`tumble check` on a broken sample: exit 0 or 2, one line on stderr for 2, never a traceback."""
    name, data = case
    path = tmp_path / f"{name}.toml"
    path.write_bytes(data)
    rc, stderr, seconds = _cli(["check", str(path)])
    _assert_clean(rc, stderr, seconds, "check", data, one_line=True)
    if rc == 2:
        assert f"{name}.toml" in stderr


@settings(FUZZ, max_examples=30)
@given(case=mutated_scene(names=RUN_SAMPLES))
def test_run_on_mutated_samples_exits_0_or_2(case, tmp_path, plan_memory, rss_budget):
    """`tumble run` of one step with --record on a broken sample: exit 0 or 2, never a traceback."""
    name, data = case
    path = tmp_path / f"{name}.toml"
    path.write_bytes(data)
    out = tmp_path / "rec.npz"
    rc, stderr, seconds = _cli(["run", str(path), "--duration", "1e-9", "--record", str(out)])
    # a scene refused on loading says so in one line; one that fails while running comes after
    # the run's progress lines
    _assert_clean(rc, stderr, seconds, "run", data, one_line="preparing" not in stderr and "first" not in stderr)
    assert rc != 0 or out.exists()
