"""Outputs are checked before the run, written atomically, and kept on failure or Ctrl-C.

Issue 13 (bad input, huge requests and failed writes). The tests run as root, so permission
bits do not stop a write: an unwritable folder is a path under a regular file or under /proc,
and a full disk is a file-size limit (RLIMIT_FSIZE) set in a subprocess.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import tumble.world
from tumble.cli import main
from tumble.io import atomic
from tumble.io.atomic import OutputError, atomic_folder, atomic_path, check_output
from tumble.io.record import load_recording

BALL = "[[plane]]\n[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nmass = 1.0\n"
OLD = b"an existing file that must survive"


def _unwritable(tmp_path: Path) -> list[tuple[str, Path]]:
    (tmp_path / "regular").write_text("x")
    return [("under a regular file", tmp_path / "regular" / "out"), ("in /proc", Path("/proc/tumble-out"))]


def _leftovers(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if ".tmp" in p.name or p.name.startswith(".tumble-probe")]


@pytest.fixture
def no_stepping(monkeypatch):
    """Fail the test if any world steps (the output must be refused before the run)."""

    def step(self, dt=None):
        raise AssertionError("the world stepped before the output was checked")

    monkeypatch.setattr(tumble.world.World, "step", step)


def test_record_to_an_unwritable_place_is_refused_before_the_run(write_scene, tmp_path, capsys, no_stepping):
    """run --record under a file, in /proc, onto a folder, into a missing folder: exit 2 at once."""
    scene = str(write_scene(BALL))
    (tmp_path / "folder.npz").mkdir()
    cases = [(why, str(p) + ".npz") for why, p in _unwritable(tmp_path)]
    cases += [
        ("a directory", str(tmp_path / "folder.npz")),
        ("missing folder", str(tmp_path / "no" / "r.npz")),
        ("unknown suffix", str(tmp_path / "r.csv")),
    ]
    for why, out in cases:
        assert main(["run", scene, "--record", out]) == 2, why
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and f"--record {out!r}" in err, (why, err)


def test_render_and_plot_outputs_are_refused_first(tmp_path, capsys, monkeypatch):
    """render -o and plot -o to unwritable places: exit 2 before any context, scene or recording."""
    import tumble.render

    def no_context(*args, **kwargs):
        raise AssertionError("an OpenGL context was made before the output was checked")

    monkeypatch.setattr(tumble.render, "create_context", no_context)
    for why, p in _unwritable(tmp_path):
        for argv in (
            ["render", "bouncing_ball", "-o", f"{p}.mp4"],
            ["render", "bouncing_ball", "-o", f"{p}.gif"],
            ["render", "bouncing_ball", "-o", str(p / "frames")],
            ["plot", str(tmp_path / "missing.npz"), "-o", f"{p}.png"],
        ):
            assert main(argv) == 2, (why, argv)
            err = capsys.readouterr().err.strip()
            assert err.count("\n") == 0 and f"-o '{p}" in err, (why, err)
    assert main(["plot", str(tmp_path / "missing.npz"), "-o", str(tmp_path / "p.txt")]) == 2
    assert ".png" in capsys.readouterr().err


def test_check_output_rules(tmp_path):
    """check_output refuses a directory, a wrong suffix, a missing or unwritable folder; accepts the rest."""
    (tmp_path / "d.npz").mkdir()
    with pytest.raises(OutputError, match="is a directory"):
        check_output(tmp_path / "d.npz", suffixes=(".npz",))
    with pytest.raises(OutputError, match="must end in .npz"):
        check_output(tmp_path / "r.npy", suffixes=(".npz",))
    with pytest.raises(OutputError, match="no such directory"):
        check_output(tmp_path / "none" / "r.npz")
    for _, p in _unwritable(tmp_path):
        with pytest.raises(OutputError):
            check_output(p)
    (tmp_path / "frames.png").write_text("x")
    with pytest.raises(OutputError, match="not a folder"):
        check_output(tmp_path / "frames.png", folder=True)
    assert check_output(tmp_path / "ok.npz", suffixes=(".npz",)) == tmp_path / "ok.npz"
    assert _leftovers(tmp_path) == []


def test_a_failed_write_keeps_the_existing_file(tmp_path):
    """A write that fails halfway (disk full, Ctrl-C) leaves the old file and no temporary file."""
    target = tmp_path / "keep.npz"
    target.write_bytes(OLD)
    for error in (OSError(28, "No space left on device"), KeyboardInterrupt()):
        with pytest.raises((OutputError, KeyboardInterrupt)) as info:
            with atomic_path(target) as tmp:
                tmp.write_bytes(b"half a fi")
                raise error
        if isinstance(error, OSError):
            assert "No space left on device" in str(info.value) and str(target) in str(info.value)
        assert target.read_bytes() == OLD
        assert _leftovers(tmp_path) == []


def test_a_completed_write_replaces_the_file_keeping_its_mode(tmp_path):
    """Success renames the new file over the old one, with the old one's permissions."""
    target = tmp_path / "plot.png"
    target.write_bytes(OLD)
    os.chmod(target, 0o640)
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png" and target.read_bytes() == OLD
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new"
    assert target.stat().st_mode & 0o777 == 0o640
    assert _leftovers(tmp_path) == []


def test_frame_folders_are_replaced_whole_or_not_at_all(tmp_path):
    """A new PNG set replaces the old frames (user files stay); a failure leaves the old set."""
    out = tmp_path / "frames"
    out.mkdir()
    for k in range(5):
        (out / f"frame_{k:05d}.png").write_bytes(OLD)
    (out / "notes.txt").write_text("mine")
    with pytest.raises(RuntimeError):
        with atomic_folder(out) as tmp:
            (tmp / "frame_00000.png").write_bytes(b"new")
            raise RuntimeError("encoder failed")
    assert sorted(p.name for p in out.iterdir()) == [f"frame_{k:05d}.png" for k in range(5)] + ["notes.txt"]
    assert (out / "frame_00000.png").read_bytes() == OLD
    with atomic_folder(out) as tmp:
        for k in range(2):
            (tmp / f"frame_{k:05d}.png").write_bytes(b"new")
    assert sorted(p.name for p in out.iterdir()) == ["frame_00000.png", "frame_00001.png", "notes.txt"]
    assert (out / "frame_00001.png").read_bytes() == b"new"
    with atomic_folder(tmp_path / "fresh") as tmp:
        (tmp / "frame_00000.png").write_bytes(b"new")
    assert [p.name for p in (tmp_path / "fresh").iterdir()] == ["frame_00000.png"]
    assert _leftovers(tmp_path) == []


def _limit_file_size(nbytes: int):
    def apply():
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))

    return apply


def _tumble(args, env, *, limit: int | None = None, timeout: float = 240) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "tumble", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
        preexec_fn=None if limit is None else _limit_file_size(limit),
    )


def test_a_full_disk_keeps_the_old_recording_and_plot(tmp_path, tumble_subprocess_env, write_scene):
    """With a 20 kB file-size limit, run --record and plot fail in one line; the old files survive."""
    scene = write_scene(
        BALL + "[[emitter]]\nrate = 2000\ncount = 300\nposition = [0, 0, 2]\nregion = 'box'\n"
        "extent = [1, 1, 0.5]\nradius = 0.03\n"
    )
    record = tmp_path / "rec.npz"
    record.write_bytes(OLD)
    result = _tumble(
        ["run", str(scene), "--duration", "0.5", "--record", str(record)], tumble_subprocess_env, limit=20_000
    )
    assert result.returncode == 2, result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("tumble run: error: cannot write") and "File too large" in last
    assert "Traceback" not in result.stderr
    assert record.read_bytes() == OLD and _leftovers(tmp_path) == []

    # a real recording, then a plot over an existing image under a limit too small for it
    good = tmp_path / "good.npz"
    assert (
        _tumble(["run", str(scene), "--duration", "0.2", "--record", str(good)], tumble_subprocess_env).returncode == 0
    )
    image = tmp_path / "plot.png"
    image.write_bytes(OLD)
    # as on a machine's first plot: matplotlib's font cache is built and cannot be saved either
    cold = {**tumble_subprocess_env, "MPLCONFIGDIR": str(tmp_path / "mpl")}
    result = _tumble(["plot", str(good), "-o", str(image)], cold, limit=5_000)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "File too large" in result.stderr
    assert image.read_bytes() == OLD and _leftovers(tmp_path) == []


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_a_full_disk_keeps_the_old_video(tmp_path, tumble_subprocess_env, suffix):
    """render under a 3 kB file-size limit: one line (ffmpeg summarized), the old video survives."""
    pytest.importorskip("moderngl")
    out = tmp_path / f"v{suffix}"
    out.write_bytes(OLD)
    result = _tumble(
        ["render", "bouncing_ball", "-o", str(out), "--duration", "1", "--size", "160x120", "--no-progress"],
        tumble_subprocess_env,
        limit=3_000,
    )
    if "no OpenGL context" in result.stderr:
        pytest.skip("no headless OpenGL on this machine")
    assert result.returncode == 2, result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr, result.stderr
    assert result.stderr.startswith(f"tumble render: error: cannot write {str(out)!r}")
    if suffix == ".mp4":
        assert "ffmpeg" in result.stderr
    assert out.read_bytes() == OLD and _leftovers(tmp_path) == []


def test_ctrl_c_during_a_recording_saves_the_frames_so_far(tmp_path, tumble_subprocess_env):
    """SIGINT during run --record: exit 130, says how many frames went where, and the file holds them."""
    record = tmp_path / "long.npz"
    proc = subprocess.Popen(
        [sys.executable, "-m", "tumble", "run", "sphere_pile", "--duration", "600", "--record", str(record)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=tumble_subprocess_env,
    )
    try:
        # wait until the run is stepping (the first step is reported on stderr), then a little more
        deadline = time.monotonic() + 180
        seen = ""
        while "first step" not in seen and time.monotonic() < deadline and proc.poll() is None:
            seen += proc.stderr.readline()
        time.sleep(1.5)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    line = err.strip().splitlines()[-1]
    assert line.startswith("tumble run: interrupted") and str(record) in line
    frames = int(line.split("saved the ")[1].split(" frames")[0].replace(",", ""))
    rec = load_recording(record)
    assert frames >= 2 and rec["time"].shape == (frames,) and rec["position"].shape[0] == frames
    assert np.all(np.diff(rec["time"]) > 0)
    assert zipfile.is_zipfile(record) and _leftovers(tmp_path) == []


def test_view_refuses_an_unwritable_out_dir(tmp_path, capsys):
    """view --out-dir must be a folder Tumble can write in, checked before any window opens."""
    for _, p in _unwritable(tmp_path):
        assert main(["view", "bouncing_ball", "--out-dir", str(p)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "--out-dir" in err


def test_the_probe_leaves_nothing_behind(tmp_path):
    """Checking a folder creates and removes its probe file."""
    atomic.check_folder(tmp_path, option="--out-dir")
    assert list(tmp_path.iterdir()) == []
