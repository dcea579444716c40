"""Key paths, values and variant planning of `tumble.wedge` (no cluster, no simulation)."""

from __future__ import annotations

import contextlib
import importlib
import os
import tomllib

import pytest

from tumble.io.scene import parse_scene
from tumble.limits import LimitError
from tumble.wedge import (
    MAX_VARIANTS,
    KeyPath,
    WedgeError,
    apply_value,
    parse_key,
    parse_values,
    parse_vary,
    plan_wedge,
    scene_text,
)

SCENE = """
[world]
seed = 1

[[plane]]
normal = [0, 0, 1]

[[plane]]
normal = [1, 0, 0]
offset = -0.5

[[emitter]]
rate = 100
count = 10
position = [0, 0, 1]
radius = 0.05
stiff = { a = 1 }
"""


@pytest.fixture
def scene_file(write_scene):
    return write_scene(SCENE.replace("stiff = { a = 1 }\n", ""))


@pytest.fixture
def doc(scene_file):
    return tomllib.loads(scene_file.read_text())


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("world.gravity", KeyPath("world", None, "gravity")),
        ("seed", KeyPath("world", None, "seed")),
        ("plane[1].friction", KeyPath("plane", 1, "friction")),
        ("plane[*].friction", KeyPath("plane", "*", "friction")),
        ("emitter[0].rate", KeyPath("emitter", 0, "rate")),
        ("wind.velocity[0]", KeyPath("wind", None, "velocity", 0)),
    ],
)
def test_parse_key_resolves_paths(text, expected, doc):
    """Resolve table, index, key and component of each accepted key path form."""
    assert parse_key(text, doc) == expected


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("emitter[0].rat", "did you mean 'emitter[0].rate'"),
        ("wrld.gravity", "did you mean 'world.gravity'"),
        ("plane.friction", "plane[0].friction"),
        ("plane[2].friction", "the scene has 2 [[plane]] tables"),
        ("cloth[0].max_stretch", "no [[cloth]] table"),
        ("world[0].seed", "single table"),
        ("friction", "should look like table.key"),
    ],
)
def test_parse_key_rejects_with_a_hint(text, message, doc):
    """Name the nearest key path, or say what is wrong with the index, in one line."""
    with pytest.raises(WedgeError) as info:
        parse_key(text, doc)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("text", "values"),
    [
        ("0.2,0.5,0.8", [0.2, 0.5, 0.8]),
        ("0:1:5", [0.0, 0.25, 0.5, 0.75, 1.0]),
        ("0:1:11", [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]),  # rounded, not 0.30000000000000004
        ("100:900:5", [100, 300, 500, 700, 900]),  # whole numbers stay integers
        ("1:2:1", [1]),
        ("0..3", [0, 1, 2, 3]),
        ("5..5", [5]),
        ("[0,0,-9.81],[0,0,-1.62]", [[0, 0, -9.81], [0, 0, -1.62]]),
        ("box,disc", ["box", "disc"]),
        ('"sphere", true, 3', ["sphere", True, 3]),
        ([1, 2], [1, 2]),
    ],
)
def test_parse_values_forms(text, values):
    """Read lists, start:stop:count ranges (both ends included) and a..b integer ranges."""
    assert parse_values(text) == values


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no values"),
        ("5..4", "empty range"),
        ("0:1:0", "empty range"),
        ("0:1", "start:stop:count"),
        ("0:1:2.5", "count must be a whole number"),
        ("a:1:3", "start must be a finite number"),
        ("0.1..3", "a..b takes two integers"),
        ("1,,2", "empty value"),
        ("1,2,1", "given twice"),
        ([], "empty list"),
        # refused before expanding: a billion values would take minutes and gigabytes to build
        ("0..1000000000", "gives 1,000,000,001 values; a wedge takes at most 100,000"),
        ("0:1:100000001", "gives 100,000,001 values"),
    ],
)
def test_parse_values_rejects(text, message):
    """Reject empty and malformed ranges and repeated values with one line."""
    with pytest.raises(WedgeError) as info:
        parse_values(text)
    assert message in str(info.value)


def test_parse_vary_splits_key_and_values():
    """Split KEY=VALUES at the first '=' and name the --vary in errors."""
    assert parse_vary("world.seed=0..2") == ("world.seed", [0, 1, 2])
    with pytest.raises(WedgeError, match="KEY=VALUES"):
        parse_vary("world.seed")
    with pytest.raises(WedgeError, match=r"--vary world.seed=3..1: empty range"):
        parse_vary("world.seed=3..1")


def test_scene_text_round_trips_through_the_loader():
    """Write a document back as TOML that tomllib reads to the same values (inline tables too)."""
    doc = tomllib.loads(SCENE)
    assert tomllib.loads(scene_text(doc, "a header")) == doc


def test_apply_value_every_entry_and_one_component(doc):
    """Set plane[*] on every plane, and one component of a list, adding a missing [wind]."""
    apply_value(doc, parse_key("plane[*].friction", doc), 0.9)
    apply_value(doc, parse_key("wind.velocity[0]", doc), 4.0)
    assert [p["friction"] for p in doc["plane"]] == [0.9, 0.9]
    assert doc["wind"]["velocity"] == [4.0, 0.0, 0.0]
    scene = parse_scene(scene_text(doc))
    assert scene.table("wind")["velocity"] == [4.0, 0.0, 0.0]


def test_plan_expands_the_grid_last_key_fastest(scene_file):
    """Make one validated variant per combination, named by its values, the last key varying fastest."""
    plan = plan_wedge(scene_file, {"plane[0].friction": "0.2,0.8", "seed": "0..2"})
    assert [v.values for v in plan.variants][:4] == [
        {"plane[0].friction": 0.2, "world.seed": 0},
        {"plane[0].friction": 0.2, "world.seed": 1},
        {"plane[0].friction": 0.2, "world.seed": 2},
        {"plane[0].friction": 0.8, "world.seed": 0},
    ]
    assert len({v.name for v in plan.variants}) == 6
    assert plan.variants[0].name == "plane0.friction=0.2__world.seed=0"
    scene = parse_scene(plan.variants[5].text)
    assert scene.items("plane")[0]["friction"] == 0.8 and scene.table("world")["seed"] == 2
    assert scene.items("plane")[1]["friction"] == 0.5  # untouched


@pytest.mark.parametrize(
    ("vary", "message"),
    [
        ({"world.substeps": "1.5"}, "[world] substeps: must be an integer, got 1.5"),
        ({"emitter[0].rate": "-5,5"}, "--vary emitter[0].rate=-5: "),
        ({"world.gravity": "1,2"}, "gravity: must be a list of 3 numbers"),
        ({"plane[0].friction": "0.1", "plane[0].friction ": "0.2"}, "varied twice"),
        ({}, "nothing to vary"),
    ],
)
def test_plan_rejects_bad_values_naming_the_key(scene_file, vary, message):
    """Validate every value through the scene loader, naming the key and the value."""
    with pytest.raises(WedgeError) as info:
        plan_wedge(scene_file, vary)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_plan_limit_needs_yes(scene_file):
    """Refuse more than MAX_VARIANTS variants without yes=True, before expanding them."""
    n = MAX_VARIANTS + 1
    with pytest.raises(WedgeError, match=f"{n:,} variants is more than the limit"):
        plan_wedge(scene_file, {"seed": f"0..{n - 1}"})
    assert len(plan_wedge(scene_file, {"seed": f"0..{n - 1}"}, yes=True).variants) == n


def test_contact_sheet_without_frames_says_why(scene_file, tmp_path):
    """Write no sheet, and say why in one line, when no variant has a final frame (no EGL)."""
    from tumble.wedge import write_contact_sheet

    plan = plan_wedge(scene_file, {"seed": "0..1"})
    for v in plan.variants:
        (tmp_path / v.name).mkdir()
        (tmp_path / v.name / "result.json").write_text('{"status": "ok", "image_error": "TumbleError: no EGL"}')
    rows = [{"variant": v.name, "status": "ok", **v.values} for v in plan.variants]
    message = write_contact_sheet(plan, rows, tmp_path)
    assert message == "no contact sheet: no variant has a final frame (TumbleError: no EGL)"
    assert not (tmp_path / "contact_sheet.png").exists()


def test_variant_folder_names_are_readable_and_unique(scene_file):
    """Name folders key=value joined by '__', lists without brackets, one name per variant."""
    plan = plan_wedge(scene_file, {"world.gravity": "[0,0,-9.81],[0,0,-1.62]", "plane[*].friction": "0.5"})
    assert [v.name for v in plan.variants] == [
        "world.gravity=0,0,-9.81__plane.friction=0.5",
        "world.gravity=0,0,-1.62__plane.friction=0.5",
    ]


def test_local_workers_are_capped_and_checked_before_the_cluster_starts(scene_file, tmp_path, monkeypatch):
    """`--workers 1000000` asked Dask for a million worker processes (no answer until killed, then a
    traceback at exit): a local cluster gets no more workers than variants to run, and workers beyond
    the available memory are refused in one line before anything starts or is written."""
    wedge_module = importlib.import_module("tumble.wedge")  # (`tumble.wedge` is also the function)
    started = []

    class Started(Exception):
        pass

    def cluster(address=None, *, workers=None, timeout=None):
        started.append(workers)
        raise Started

    monkeypatch.setattr(wedge_module, "cluster", cluster)
    out = tmp_path / "out"
    with pytest.raises(Started):
        wedge_module.wedge(scene_file, {"seed": "0..2"}, out=out, workers=1_000_000, progress=False)
    assert started == [3]
    monkeypatch.setenv("TUMBLE_MEMORY", "1G")
    with pytest.raises(LimitError, match="--workers: 3 worker processes need about 1.6 GB of memory"):
        wedge_module.wedge(scene_file, {"seed": "0..2"}, out=out, workers=3, progress=False)
    with pytest.raises(ValueError, match="workers must be an integer >= 1, got 0"):
        wedge_module.wedge(scene_file, {"seed": "0..2"}, out=out, workers=0, progress=False)
    assert started == [3] and not out.exists()


def test_a_duration_of_too_many_steps_is_refused_before_the_cluster_starts(scene_file, tmp_path, monkeypatch):
    """`--duration 1e12` started every variant on a run of 10^14 steps that never ended (`tumble run`
    refuses it): the steps at the smallest dt of the plan are checked against limits.MAX_STEPS first."""
    wedge_module = importlib.import_module("tumble.wedge")
    started = []
    monkeypatch.setattr(wedge_module, "cluster", lambda *a, **k: started.append(1))
    out = tmp_path / "out"
    vary = {"world.dt": "0.01,0.001"}
    with pytest.raises(WedgeError, match=r"duration: 2e\+06 s at dt 0.001 s is 2,000,000,000 steps; .*\(variant "):
        wedge_module.wedge(scene_file, vary, out=out, duration=2e6, progress=False)
    assert not started and not out.exists()
    assert min(v.dt for v in plan_wedge(scene_file, vary).variants) == 0.001
    assert [v.dt for v in plan_wedge(scene_file, {"seed": "0..1"}).variants] == [1 / 240, 1 / 240]  # the default


def _blocked_signals(pid: int) -> int:
    """The signal mask of process `pid`'s main thread (Linux), as a bit set: bit n - 1 for signal n."""
    with open(f"/proc/{pid}/status") as f:
        return int(next(line for line in f if line.startswith("SigBlk:")).split()[1], 16)


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="reads the signal mask from /proc (Linux)")
def test_processes_spawned_for_a_local_cluster_start_with_sigint_blocked():
    """A Ctrl-C reaching a worker of a local cluster while it was still importing (before its preload
    ignores SIGINT) printed a KeyboardInterrupt traceback: processes spawned while the cluster starts
    begin with SIGINT blocked; after it, spawning is as before, and the spawning thread's mask too."""
    import multiprocessing
    import signal
    import time

    from tumble.wedge import _spawned_without_sigint

    context = multiprocessing.get_context("spawn")
    sigint = 1 << (signal.SIGINT - 1)
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    masks = []
    for protected in (True, False):
        child = context.Process(target=time.sleep, args=(30,))
        with _spawned_without_sigint() if protected else contextlib.nullcontext():
            child.start()
        try:
            masks.append(_blocked_signals(child.pid) & sigint)
        finally:
            child.kill()
            child.join()
    assert masks == [sigint, 0]
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == before


def test_a_sigterm_while_a_local_cluster_starts_is_held_back_until_it_has_started(tumble_subprocess_env):
    """SIGTERM reaching a local cluster half started left Dask's exit handler to close it, which failed
    with a traceback (AssertionError: Status.init): `interrupt_after` holds it back, as a Ctrl-C, until
    the block has run, then the command's handler raises Terminated; also in place of an error the
    block raised meanwhile."""
    import subprocess
    import sys

    script = """
import os, signal
from tumble import cli
from tumble.wedge import interrupt_after
interrupts = cli._Interrupts()
interrupts.install()
for fails in (False, True):
    steps = []
    try:
        with interrupt_after():
            os.kill(os.getpid(), signal.SIGTERM)
            steps.append("ran on")
            if fails:
                raise RuntimeError("a worker stopped as it started")
    except cli.Terminated:
        steps.append("terminated")
    except RuntimeError:
        steps.append("the error")
    interrupts.restore()
    interrupts.install()
    print(steps)
"""
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=tumble_subprocess_env
    )
    assert result.stdout.splitlines() == ["['ran on', 'terminated']"] * 2, result.stdout + result.stderr
