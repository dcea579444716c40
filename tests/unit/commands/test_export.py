"""`tumble export` (tumble.commands.export): a scene or a recording to a USD stage, and its one-line errors
(a wrong output, a broken or newer recording, no pxr, --seed on a recording)."""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest

pytest.importorskip("pxr")


from tumble.cli import main  # noqa: E402
from tumble.io import atomic, usd  # noqa: E402
from tumble.io.record import FORMAT_VERSION  # noqa: E402

from ..io import open_stage, record_scene  # noqa: E402
from ..io.scene import BALL  # noqa: E402

FRAMES = 6


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """The ball scene recorded for FRAMES frames at 30 fps, as load_recording returns it."""
    return record_scene(tmp_path_factory.mktemp("export") / "ball.toml", BALL, FRAMES, 30.0)


def test_cli_exports_a_scene_and_a_recording(write_scene, recording, tmp_path, capsys):
    """`tumble export SCENE -o` and `tumble export RECORDING.npz -o` write stages and exit 0."""
    scene = write_scene(BALL)
    assert main(["export", str(scene), "-o", str(tmp_path / "a.usda"), "--frames", "4", "--no-progress"]) == 0
    assert open_stage(tmp_path / "a.usda").GetEndTimeCode() == 3
    np.savez_compressed(tmp_path / "r.npz", **recording)
    assert (
        main(
            [
                "export",
                str(tmp_path / "r.npz"),
                "-o",
                str(tmp_path / "r.usdz"),
                "--fps",
                "10",
                "--bodies",
                "xforms",
                "--no-progress",
            ]
        )
        == 0
    )
    assert open_stage(tmp_path / "r.usdz").GetTimeCodesPerSecond() == 10
    assert "wrote" in capsys.readouterr().err


@pytest.mark.parametrize(
    "out, message",
    [
        ("shot.abc", "must end in .usd, .usda, .usdc or .usdz"),
        ("missing/shot.usd", "does not exist"),
        ("file.txt/shot.usd", "does not exist"),
    ],
)
def test_cli_bad_output_is_one_line(write_scene, tmp_path, capsys, monkeypatch, out, message):
    """A wrong extension or a folder that is missing or a file: one line on stderr, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "file.txt").write_text("x", encoding="utf-8")
    scene = write_scene(BALL)
    before = sorted(os.listdir(tmp_path))
    assert main(["export", str(scene), "-o", out, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and err.startswith("tumble export: error:")
    assert sorted(os.listdir(tmp_path)) == before


def test_cli_unwritable_folder_is_one_line(recording, tmp_path, capsys, monkeypatch):
    """A folder the user may not write to: one line, exit 2 (creating a file there is made to fail, since
    root may write anywhere: the same probe every output gets)."""
    np.savez_compressed(tmp_path / "r.npz", **recording)
    real = tempfile.mkstemp

    def mkstemp(*args, dir=None, **kwargs):
        if str(dir) == str(tmp_path / "ro"):
            raise PermissionError(13, "Permission denied")
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(atomic.tempfile, "mkstemp", mkstemp)
    (tmp_path / "ro").mkdir()
    assert main(["export", str(tmp_path / "r.npz"), "-o", str(tmp_path / "ro" / "x.usd")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"cannot write in {str(tmp_path / 'ro')!r} (Permission denied)" in err
    assert os.listdir(tmp_path / "ro") == []


def test_cli_replaces_a_read_only_stage_as_run_replaces_a_recording(recording, tmp_path, capsys, monkeypatch):
    """An existing read-only file is replaced by the rename, as `run --record` and `render` replace theirs
    (export refused it, by its permission bits: faked here for the file, since root may write anything)."""
    np.savez_compressed(tmp_path / "r.npz", **recording)
    target = tmp_path / "x.usda"
    target.write_text("old", encoding="utf-8")
    target.chmod(0o444)
    real = os.access
    monkeypatch.setattr(usd.os, "access", lambda p, mode: False if str(p) == str(target) else real(p, mode))
    assert main(["export", str(tmp_path / "r.npz"), "-o", str(target), "--no-progress"]) == 0
    assert open_stage(target).GetTimeCodesPerSecond() > 0
    assert target.stat().st_mode & 0o777 == 0o444  # its permissions kept, as every replaced output's


def test_cli_newer_recording_is_one_line(recording, tmp_path, capsys):
    """A recording from a newer format version: one line naming the versions, exit 2."""
    newer = dict(recording, format_version=np.int32(FORMAT_VERSION + 1))
    np.savez_compressed(tmp_path / "new.npz", **newer)
    assert main(["export", str(tmp_path / "new.npz"), "-o", str(tmp_path / "x.usdc")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"format version {FORMAT_VERSION + 1} is newer" in err
    assert not (tmp_path / "x.usdc").exists()


def test_cli_broken_recording_is_one_line(tmp_path, capsys):
    """A file that is not a recording: one line, exit 2."""
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    assert main(["export", str(tmp_path / "junk.npz"), "-o", str(tmp_path / "x.usdc")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a readable recording" in err


def test_cli_missing_pxr_names_the_pip_command(write_scene, tmp_path, capsys, monkeypatch):
    """Without pxr: one line naming `pip install 'tumble[usd]'`, exit 2."""
    import sys

    for name in [m for m in sys.modules if m == "pxr" or m.startswith("pxr.")]:
        monkeypatch.setitem(sys.modules, name, None)
    scene = write_scene(BALL)
    assert main(["export", str(scene), "-o", str(tmp_path / "x.usd")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'tumble[usd]'" in err


def test_seed_applies_to_scenes_not_recordings(recording, tmp_path, capsys):
    """--seed with a recording: exit 2, one line saying so, no stage written."""
    np.savez_compressed(tmp_path / "r.npz", **recording)
    assert main(["export", str(tmp_path / "r.npz"), "-o", str(tmp_path / "x.usda"), "--seed", "3"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--seed applies to scenes, not to recordings" in err
    assert not (tmp_path / "x.usda").exists()


def test_frames_and_duration_exclude_each_other(write_scene, tmp_path, capsys):
    """--frames and --duration together: argparse's exit 2 with one line naming both."""
    with pytest.raises(SystemExit) as exit_:
        main(["export", str(write_scene(BALL)), "-o", str(tmp_path / "x.usda"), "--frames", "3", "--duration", "1"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--frames" in err[0] and "--duration" in err[0]


def test_a_recording_exports_every_recorded_frame_by_default(recording, tmp_path):
    """Without --fps or --duration a recording exports all its frames at the recorded rate."""
    np.savez_compressed(tmp_path / "r.npz", **recording)
    assert main(["export", str(tmp_path / "r.npz"), "-o", str(tmp_path / "all.usda"), "--no-progress"]) == 0
    stage = open_stage(tmp_path / "all.usda")
    assert stage.GetTimeCodesPerSecond() == 30
    assert stage.GetEndTimeCode() - stage.GetStartTimeCode() == FRAMES - 1


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_cli_precision_replaces_the_scenes_and_is_refused_for_a_recording(
    write_scene, recording, tmp_path, capsys, monkeypatch, precision
):
    """`export SCENE --precision P` simulates the scene in P; a recording was simulated already, so
    `export RECORDING.npz --precision` is one line and exit 2, as --seed is."""
    import tumble.io.scene as scenes

    load = scenes.load_scene
    made = []
    monkeypatch.setattr(
        scenes, "load_scene", lambda path, **overrides: made.append(load(path, **overrides)) or made[-1]
    )
    scene = write_scene(BALL)
    argv = ["export", str(scene), "-o", str(tmp_path / "a.usda"), "--frames", "3", "--no-progress"]
    assert main([*argv, "--precision", precision]) == 0
    assert [w.precision for w in made] == [precision]
    capsys.readouterr()
    np.savez_compressed(tmp_path / "r.npz", **recording)
    assert main(["export", str(tmp_path / "r.npz"), "-o", str(tmp_path / "b.usda"), "--precision", precision]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["tumble export: error: --precision applies to scenes, not to recordings"]
    assert not (tmp_path / "b.usda").exists()
