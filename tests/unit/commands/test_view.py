"""`tumble view` (tumble.commands.view): its arguments and its one-line errors, before any window opens."""

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tumble.commands.view import parse_size


def _view_only(monkeypatch):
    """The CLI with just the view command (the test needs no other command's imports)."""
    from tumble import cli

    monkeypatch.setattr(cli, "COMMANDS", {"view": "view"})
    return cli.main


def test_view_command_missing_scene_exits_2(capsys, tmp_path, monkeypatch):
    """`tumble view` on a missing file exits 2 with one line naming it."""
    pytest.importorskip("tumble.io.scene")  # the scene loader lives on its own branch until merged
    main = _view_only(monkeypatch)

    missing = tmp_path / "nope.toml"
    assert main(["view", str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope.toml" in err[0] and "no such scene file" in err[0]


def test_view_command_rejects_a_bad_size():
    """--size must look like WxH."""
    assert parse_size("320x240") == (320, 240)
    with pytest.raises(argparse.ArgumentTypeError, match="1280x720"):
        parse_size("big")
    with pytest.raises(argparse.ArgumentTypeError):
        parse_size("8x8")  # under 16 a side


def test_view_command_broken_scene_exits_2(capsys, tmp_path, monkeypatch):
    """`tumble view` on a malformed scene exits 2 with one line naming the file, before any window."""
    pytest.importorskip("tumble.io.scene")  # the scene loader lives on its own branch until merged
    main = _view_only(monkeypatch)

    broken = tmp_path / "broken.toml"
    broken.write_text("[[sphere]]\nposition = [0, 0, 1]\nradius = 'big'\n")
    assert main(["view", str(broken)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "broken.toml" in err[0]


@pytest.mark.parametrize("argv", [["--size", "wide"], ["--view", "vulkan"]])
def test_view_command_bad_options_exit_2_with_one_line(argv, capsys, monkeypatch):
    """A bad --size or --view: exit 2 (argparse's) and one line naming the option, before the scene is loaded."""
    main = _view_only(monkeypatch)
    with pytest.raises(SystemExit) as exit_:
        main(["view", "no_such_scene.toml", *argv])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tumble view: error:") and argv[0] in err[0]
    assert "no_such_scene" not in err[0]


def test_view_command_opens_the_viewer_on_the_loaded_scene(monkeypatch, tmp_path):
    """A good scene is loaded once before any window, then handed to run_viewer with the options given."""
    pytest.importorskip("PySide6")
    import tumble.viewer

    seen = {}

    def run_viewer(world, **kwargs):
        seen.update(kwargs, world=world, rebuilt=kwargs["factory"]())
        return 0

    monkeypatch.setattr(tumble.viewer, "run_viewer", run_viewer)
    main = _view_only(monkeypatch)
    assert (
        main(["view", "bouncing_ball", "--size", "320x200", "--paused", "--view", "image", "--out-dir", str(tmp_path)])
        == 0
    )
    assert seen["size"] == (320, 200) and seen["paused"] is True and seen["view"] == "image"
    assert seen["title"] == "bouncing_ball" and str(seen["output_dir"]) == str(tmp_path)
    assert seen["world"].body_count == seen["rebuilt"].body_count > 1  # the factory reloads the same scene
    assert seen["rebuilt"] is not seen["world"]


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_view_command_precision_replaces_the_scenes(monkeypatch, tmp_path, precision):
    """--precision builds the viewed world, and the one its reset rebuilds, in that precision (the
    sample names none: it would be Tumble's default)."""
    pytest.importorskip("PySide6")
    import tumble.viewer

    seen = {}
    monkeypatch.setattr(
        tumble.viewer, "run_viewer", lambda world, **kw: seen.update(world=world, again=kw["factory"]())
    )
    main = _view_only(monkeypatch)
    assert main(["view", "bouncing_ball", "--precision", precision, "--out-dir", str(tmp_path)]) == 0
    assert seen["world"].precision == seen["again"].precision == precision


def test_view_command_ends_on_sigterm_without_a_traceback(tmp_path):
    """SIGTERM closes the viewer with status 143 and one line: it printed a traceback from a Qt slot and ran on."""
    pytest.importorskip("PySide6")
    src = Path(__file__).resolve().parents[3] / "src"
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "PYTHONPATH": str(src)}
    env.pop("TUMBLE_DEBUG", None)
    argv = [sys.executable, "-m", "tumble", "view", "bouncing_ball", "--size", "64x48", "--out-dir", str(tmp_path)]
    proc = subprocess.Popen(argv, env=env, stderr=subprocess.PIPE, text=True)
    time.sleep(6)  # the window is up and the timer ticking
    proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail("tumble view ran on after SIGTERM")
    if proc.returncode == 2 and "viewer" in err.lower():  # no window possible on this machine
        pytest.skip(err.strip())
    assert "Traceback" not in err
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == "tumble view: terminated"
