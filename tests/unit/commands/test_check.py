"""`tumble check` (tumble.commands.check): one summary line for a good scene, one error line and exit 2 for a bad one."""

from __future__ import annotations

import pytest

from tumble.cli import main
from tumble.io.scene import SAMPLES_DIR

from ..io.scene import BALL


def test_check_accepts_a_good_file(capsys):
    """Validate a bundled sample without running it and print one summary line."""
    assert main(["check", str(SAMPLES_DIR / "sphere_pile.toml")]) == 0
    out = capsys.readouterr().out.strip()
    assert out.count("\n") == 0
    assert "ok" in out and "5 planes" in out and "1 emitter (1000 bodies)" in out


def test_check_finds_a_sample_by_name(capsys):
    """Accept the bare name of a bundled sample."""
    assert main(["check", "bouncing_ball"]) == 0
    assert "1 sphere" in capsys.readouterr().out


def test_missing_file_exits_2_with_one_line(capsys):
    """A scene file that does not exist: exit status 2 and one line on stderr naming it."""
    assert main(["check", "missing.toml"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no such scene file" in err and "missing.toml" in err


def test_the_summary_counts_what_the_file_holds(write_scene, capsys):
    """The file's path, then "ok:", then its bodies by shape; nothing is simulated (time stays out of it)."""
    path = write_scene(BALL + "\n[[box]]\nposition = [1, 0, 1]\nhalf_extents = [0.1, 0.1, 0.1]\n")
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith(f"{path}: ok: ")
    assert "1 plane" in out and "1 sphere" in out and "1 box" in out


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nmass = -2\n", "mass"),
        ("[world]\ndt = 0\n", "dt"),
    ],
)
def test_bad_values_exit_2_naming_the_key(write_scene, capsys, text, fragment):
    """A negative mass or a zero dt: exit 2, one line naming the file and the key, nothing on stdout."""
    path = write_scene(text, "bad.toml")
    assert main(["check", str(path)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert err.count("\n") == 0 and err.startswith("tumble check: error: ")
    assert "bad.toml" in err and fragment in err
    assert captured.out == ""


def test_check_takes_exactly_one_scene(capsys):
    """No SCENE: argparse's exit 2 with one line saying what is missing."""
    with pytest.raises(SystemExit) as exit_:
        main(["check"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "SCENE" in err[0]
