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


_SPHERE = "[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\n"
_CLOTH = '[[cloth]]\nsize = [1, 1]\nposition = [0, 0, 1]\nresolution = [4, 4]\npins = "corners"\n'
_JOINT = '[[joint]]\nkind = "ball"\nanchor = [0, 0, 1]\n'
_FLAT = "[[convex]]\npoints = [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0]]\n"
_SQUARE = "[[convex]]\npoints = [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]]\n"


@pytest.mark.parametrize(
    "text, files, fragments",
    [
        (
            _SPHERE + _JOINT + 'body_a = "sphere[0]"\nbody_b = "sphere[3]"\n',
            {},
            ("[joint[0]] body_b: no body 'sphere[3]': the file has 1 [[sphere]]",),
        ),
        (
            _SPHERE + _JOINT + 'body_a = "box[0]"\nbody_b = "sphere[0]"\n',
            {},
            ("[joint[0]] body_a: no body 'box[0]': the file has 0 [[box]]",),
        ),
        (_CLOTH + 'pin_body = "sphere[0]"\n', {}, ("[cloth[0]] pin_body: no body 'sphere[0]'",)),
        (_CLOTH + 'pin_body = "world"\n', {}, ("[cloth[0]] pin_body: 'world' is not a body",)),
        (
            '[[convex]]\nfile = "nothere.obj"\nposition = [0, 0, 1]\n',
            {},
            ("[convex[0]]", "nothere.obj: no such mesh file"),
        ),
        ('[[mesh]]\nfile = "bad.stl"\n', {"bad.stl": "garbage\n"}, ("[mesh[0]]", "bad.stl: the mesh has no triangles")),
        # a hull of points on one plane (also one that is flat only at its scale, and a convex emitter's)
        (_FLAT + "position = [0, 0, 1]\n", {}, ("[convex[0]]", "points: the points span no volume")),
        (_SQUARE + "position = [0, 0, 1]\nscale = [1, 1, 1e-13]\n", {}, ("[convex[0]]", "span no volume")),
        (
            _FLAT.replace("[[convex]]", '[[emitter]]\nshape = "convex"\nrate = 10\ncount = 2\nposition = [0, 0, 1]'),
            {},
            ("[emitter[0]]", "points: the points span no volume"),
        ),
        (
            '[[convex]]\nfile = "flat.obj"\nposition = [0, 0, 1]\n',
            {"flat.obj": "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n"},
            ("[convex[0]]", "flat.obj: the points span no volume"),
        ),
    ],
)
def test_check_refuses_what_run_refuses(write_scene, capsys, text, files, fragments):
    """Bodies named by joints and cloth pins must be in the file, mesh files must read and convex
    points must make a hull: `check` refuses such a scene in the words `run` (which builds it) uses, with exit 2 and one line."""
    path = write_scene(text, "refs.toml")
    for name, content in files.items():
        (path.parent / name).write_text(content)
    assert main(["check", str(path)]) == 2
    check = capsys.readouterr().err.strip()
    assert check.count("\n") == 0 and all(f in check for f in fragments), check
    assert main(["run", str(path), "--duration", "0.01"]) == 2
    run = capsys.readouterr().err.strip()
    assert run.count("\n") == 0 and all(f in run for f in fragments), run
