"""A small wedge on a local 2-worker Dask cluster: manifest, folders, contact sheet, failures, resume,
and each variant identical to a plain `tumble run` with the same values."""

from __future__ import annotations

import csv
import json
import os

import pytest

import tumble
from tumble.cli import main as cli_main

# a ball and a few emitted spheres (so the seed matters), 0.25 s = 60 steps at dt = 1/240
SCENE = """
[world]
dt = 0.004166666666666667
substeps = 4
seed = 7

[[plane]]
normal = [0, 0, 1]

[[sphere]]
position = [0, 0, 0.3]
radius = 0.1
mass = 1.0

[[emitter]]
rate = 400
count = 12
position = [0, 0, 0.8]
region = "box"
extent = [0.3, 0.3, 0.1]
radius = 0.04
mass = 0.1

[camera]
position = [1.5, -1.5, 1.0]
target = [0, 0, 0.2]
"""
DURATION = 0.25


@pytest.fixture(scope="module")
def precision(request):
    """The precision of the tests' worlds (`pytest --precision`, else Tumble's default), written into the
    scene: the wedge's workers are other processes, and `tumble run` builds its world from the file,
    so neither sees the per-test default that tests/conftest.py sets."""
    return request.config.getoption("--precision") or tumble.precision.DEFAULT_PRECISION


@pytest.fixture(scope="module")
def fast(precision):
    """1e300 m/s (1e30 in float32): a speed whose square overflows the precision's floats, so that
    the kinetic energy is inf and the variant launched at it fails in the run itself."""
    return 1e300 if precision == "float64" else 1e30


@pytest.fixture(scope="module")
def vary(fast):
    """The varied values: two seeds, and the ball at rest or launched at `fast`."""
    return {"world.seed": "1..2", "sphere[0].velocity": f"[0, 0, 0], [0, 0, {fast:.0e}]"}


@pytest.fixture(scope="module")
def run(tmp_path_factory, precision, vary):
    """The wedge run once on 2 workers: (scene path, output folder, table)."""
    root = tmp_path_factory.mktemp("wedge")
    scene = root / "balls.toml"
    scene.write_text(SCENE.replace("[world]\n", f'[world]\nprecision = "{precision}"\n'), encoding="utf-8")
    out = root / "out"
    keep = ["record", "usd"] if _has_pxr() else ["record"]
    table = tumble.wedge(scene, vary, out=out, duration=DURATION, workers=2, keep=keep, progress=False)
    return scene, out, table


def _has_pxr() -> bool:
    try:
        import pxr  # noqa: F401
    except ImportError:
        return False
    return True


def _variant(table, seed, diverging):
    for row in table:
        if row["world.seed"] == seed and (row["sphere[0].velocity"][2] > 0) == diverging:
            return row
    raise AssertionError("variant not found")


def test_manifest_has_one_row_per_variant(run, fast):
    """Write manifest.csv and .json with every varied value, the status and the summary figures."""
    _, out, table = run
    assert len(table) == 4
    with open(out / "manifest.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["variant"] for r in rows] == [row["variant"] for row in table]
    assert set(rows[0]) >= {
        "world.seed",
        "sphere[0].velocity",
        "status",
        "error",
        "wall_s",
        "steps_per_s",
        "kinetic_energy_J",
        "max_overlap_m",
        "max_penetration_m",
        "max_strain",
        "body_count",
        "contact_count",
        "state_hash",
    }
    meta = json.loads((out / "manifest.json").read_text())
    assert meta["vary"] == {"world.seed": [1, 2], "sphere[0].velocity": [[0, 0, 0], [0, 0, fast]]}
    assert [r["status"] for r in meta["variants"]] == [r["status"] for r in rows]
    good = _variant(table, 1, False)
    assert good["status"] == "ok" and good["steps"] == 60
    assert good["body_count"] == 2 + 12  # the plane, the ball, every emitted sphere (out within 0.25 s)
    assert good["kinetic_energy_J"] > 0 and good["steps_per_s"] > 0


def test_failing_variant_is_recorded_beside_good_ones(run):
    """Record a diverging variant as failed with a one-line error; the others still finish."""
    _, _, table = run
    for seed in (1, 2):
        bad, good = _variant(table, seed, True), _variant(table, seed, False)
        assert bad["status"] == "failed"
        assert "not finite" in bad["error"] and "\n" not in bad["error"]
        assert good["status"] == "ok" and good["error"] == ""


def test_folders_and_contact_sheet(run):
    """Give each variant a folder (scene, result, final frame, the kept recording) and draw the sheet."""
    from PIL import Image

    _, out, table = run
    for row in table:
        folder = out / row["variant"]
        assert (folder / "scene.toml").is_file() and (folder / "result.json").is_file()
        if row["status"] == "ok":
            assert (folder / "record.npz").is_file()
            assert (folder / "scene.usdc").is_file() == _has_pxr()
    sheet = out / "contact_sheet.png"
    if not any((out / row["variant"] / "final.png").is_file() for row in table):
        pytest.skip("no EGL here: no final frames, no contact sheet")
    image = Image.open(sheet)
    frame = Image.open(out / _variant(table, 1, False)["variant"] / "final.png")
    assert image.width == 2 * frame.width  # 4 variants: a 2 x 2 grid
    assert image.height > 2 * frame.height  # with a label strip under each frame
    assert not [p for p in out.rglob("*.tmp*")]  # every write renamed into place (tumble.io.atomic temp names)


def test_variant_matches_plain_tumble_run(run, capsys):
    """Give the same state hash as `tumble run SCENE --seed 2` (the unvaried velocity is the file's)."""
    scene, _, table = run
    assert cli_main(["run", str(scene), "--seed", "2", "--duration", str(DURATION)]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("state hash"))
    assert line.split()[-1] == _variant(table, 2, False)["state_hash"]
    assert _variant(table, 1, False)["state_hash"] != _variant(table, 2, False)["state_hash"]


def test_rerun_resumes(run, vary):
    """Skip the variants done before; run only one whose result went missing (a crash or Ctrl-C)."""
    scene, out, table = run
    lost = _variant(table, 2, False)["variant"]
    kept = _variant(table, 1, False)["variant"]
    (out / lost / "result.json").unlink()
    stamp = os.stat(out / kept / "result.json").st_mtime_ns
    keep = json.loads((out / kept / "result.json").read_text())["settings"]["keep"]
    again = tumble.wedge(scene, vary, out=out, duration=DURATION, workers=1, keep=keep, progress=False)
    assert os.stat(out / kept / "result.json").st_mtime_ns == stamp  # not run again
    assert (out / lost / "result.json").is_file()
    assert again["state_hash"] == table["state_hash"]
    assert again["status"] == table["status"]

    # nothing left to do: no cluster is started, and the table is read back
    stamps = {p: os.stat(p).st_mtime_ns for p in out.glob("*/result.json")}
    third = tumble.wedge(scene, vary, out=out, duration=DURATION, workers=1, keep=keep, progress=False)
    assert {p: os.stat(p).st_mtime_ns for p in out.glob("*/result.json")} == stamps
    assert third["state_hash"] == table["state_hash"]


def test_plot_draws_summary_figures(run, tmp_path):
    """`tumble plot OUTDIR` draws the summary figures against the varied values."""
    _, out, _ = run
    target = tmp_path / "summary.png"
    assert cli_main(["plot", str(out), "-o", str(target)]) == 0
    assert target.stat().st_size > 10_000


def test_run_variant_keeps_a_video(tmp_path):
    """Write video.mp4 with one frame per 1/fps of simulated time, the first at t = 0 (in this process)."""
    from tumble.io.scene import SAMPLES_DIR
    from tumble.wedge import Settings, run_variant

    settings = Settings(duration=0.25, fps=20, keep=("video",)).identity()
    row = run_variant(
        {
            "name": "v",
            "text": (SAMPLES_DIR / "bouncing_ball.toml").read_text(),
            "path": "ball.toml",
            "folder": str(tmp_path),
            "settings": settings,
        }
    )
    if row.get("image_error"):
        pytest.skip(f"no EGL here: {row['image_error']}")
    assert row["status"] == "ok" and row["files"] == ["video.mp4"]
    import imageio.v2 as imageio

    reader = imageio.get_reader(str(tmp_path / "video.mp4"))
    assert reader.count_frames() == 6  # t = 0, 0.05, ..., 0.25 s
    assert sorted(p.name for p in tmp_path.iterdir()) == ["video.mp4"]
