"""io/scene/parse.py: parsing, defaults, every kind of bad input, finding the samples."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import tumble
from tumble.errors import SceneError
from tumble.io import scene as scene_io

from . import BALL

# (id, TOML text, table named in the error, key named in the error or None, fragment of the message)
BAD_SCENES = [
    (
        "unknown key",
        "[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nraduis = 2",
        "sphere[0]",
        "raduis",
        "did you mean 'radius'",
    ),
    ("wrong type", '[[sphere]]\nposition = [0, 0, 1]\nradius = "big"', "sphere[0]", "radius", "number"),
    ("wrong type bool", "[world]\nsubsteps = true", "world", "substeps", "integer"),
    ("wrong length", "[world]\ngravity = [0, -9.81]", "world", "gravity", "3 components"),
    ("negative radius", "[[sphere]]\nposition = [0, 0, 1]\nradius = -0.1", "sphere[0]", "radius", "> 0"),
    ("zero radius", "[[sphere]]\nposition = [0, 0, 1]\nradius = 0", "sphere[0]", "radius", "> 0"),
    ("zero mass", "[[box]]\nposition = [0, 0, 1]\nhalf_extents = [1, 1, 1]\nmass = 0", "box[0]", "mass", "> 0"),
    ("negative mass", "[[sphere]]\nposition = [0, 0, 1]\nradius = 1\nmass = -2", "sphere[0]", "mass", "> 0"),
    ("zero half extent", "[[box]]\nposition = [0, 0, 1]\nhalf_extents = [1, 0, 1]", "box[0]", "half_extents", "> 0"),
    ("nan", "[[sphere]]\nposition = [0, 0, nan]\nradius = 0.1", "sphere[0]", "position", "finite"),
    ("inf", "[world]\ndt = inf", "world", "dt", "finite"),
    ("zero normal", "[[plane]]\nnormal = [0, 0, 0]", "plane[0]", "normal", "zero"),
    (
        "unknown shape",
        '[[emitter]]\nshape = "cone"\nrate = 1\ncount = 1\nposition = [0, 0, 1]\nradius = 0.1',
        "emitter[0]",
        "shape",
        "unknown shape 'cone'",
    ),
    (
        "unknown shape in list",
        '[[emitter]]\nshape = ["sphere", "cube"]\nrate = 1\ncount = 1\nposition = [0, 0, 1]\nradius = 0.1',
        "emitter[0]",
        "shape",
        "unknown shape 'cube'",
    ),
    ("restitution above 1", "[[plane]]\nrestitution = 1.5", "plane[0]", "restitution", "<= 1"),
    ("negative friction", "[[plane]]\nfriction = -0.1", "plane[0]", "friction", ">= 0"),
    (
        "mass and density",
        "[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nmass = 1\ndensity = 1000",
        "sphere[0]",
        "density",
        "not both",
    ),
    ("missing key", "[[sphere]]\nposition = [0, 0, 1]", "sphere[0]", "radius", "missing"),
    (
        "third table",
        "[[sphere]]\nposition = [0, 0, 1]\nradius = 1\n" * 2
        + "[[sphere]]\nposition = [0, 0, 1]\nradius = 1\nvelocity = [1, 2]",
        "sphere[2]",
        "velocity",
        "3 components",
    ),
    (
        "bad speed range",
        "[[emitter]]\nrate = 1\ncount = 1\nposition = [0, 0, 1]\nradius = 0.1\nspeed = [2, 1]",
        "emitter[0]",
        "speed",
        "min <= max",
    ),
    (
        "box region without extent",
        '[[emitter]]\nrate = 1\ncount = 1\nposition = [0, 0, 1]\nradius = 0.1\nregion = "box"',
        "emitter[0]",
        "extent",
        "half-sizes",
    ),
    (
        "sphere emitter without radius",
        "[[emitter]]\nrate = 1\ncount = 1\nposition = [0, 0, 1]",
        "emitter[0]",
        "radius",
        "needs radius",
    ),
    (
        "cloth pin outside grid",
        "[[cloth]]\nsize = [1, 1]\nresolution = [4, 4]\nposition = [0, 0, 1]\npins = [[0, 0], [4, 3]]",
        "cloth[0]",
        "pins",
        "outside",
    ),
    (
        "cloth unknown pin name",
        '[[cloth]]\nsize = [1, 1]\nresolution = [4, 4]\nposition = [0, 0, 1]\npins = "left-edge"',
        "cloth[0]",
        "pins",
        "unknown value",
    ),
    (
        "cloth unknown spring kind",
        "[[cloth]]\nsize = [1, 1]\nresolution = [4, 4]\nposition = [0, 0, 1]\n"
        "stiffness = { structural = 1, twist = 2 }",
        "cloth[0]",
        "stiffness",
        "twist",
    ),
    (
        "cloth mass and areal density",
        "[[cloth]]\nsize = [1, 1]\nresolution = [4, 4]\nposition = [0, 0, 1]\nmass = 0.2\nareal_density = 0.1",
        "cloth[0]",
        "areal_density",
        "not both",
    ),
    (
        "cloth tiny resolution",
        "[[cloth]]\nsize = [1, 1]\nresolution = [1, 4]\nposition = [0, 0, 1]",
        "cloth[0]",
        "resolution",
        ">= 2",
    ),
    (
        "static body with a velocity",
        "[[box]]\nposition = [0, 0, 1]\nhalf_extents = [1, 1, 1]\nstatic = true\nvelocity = [1, 0, 0]",
        "box[0]",
        "velocity",
        "kinematic = true",
    ),
    (
        "static body with a spin",
        "[[sphere]]\nposition = [0, 0, 1]\nradius = 1\nstatic = true\nangular_velocity = [0, 0, 2]",
        "sphere[0]",
        "angular_velocity",
        "a static body never moves",
    ),
    ("camera fov", "[camera]\nfov = 0", "camera", "fov", "> 0"),
    ("unknown table", "[planet]\nradius = 1", "planet", None, "unknown table 'planet'"),
    ("single table for array", "[sphere]\nposition = [0, 0, 1]\nradius = 1", "sphere", None, "[[sphere]]"),
    ("array for single table", "[[world]]\ndt = 0.01", "world", None, "[world]"),
]


@pytest.mark.parametrize(
    "text, table, key, fragment", [case[1:] for case in BAD_SCENES], ids=[case[0] for case in BAD_SCENES]
)
def test_bad_scene_names_file_table_and_key(write_scene, text, table, key, fragment):
    """Reject each malformed scene with a SceneError naming the file, the table and the key."""
    path = write_scene(text, "bad.toml")
    with pytest.raises(SceneError) as info:
        scene_io.validate_scene(path)
    exc = info.value
    message = str(exc)
    assert exc.path == str(path) and str(path) in message
    assert exc.table == table and f"[{table}]" in message
    if key is not None:
        assert exc.key == key and key in message
    assert fragment in message
    assert "\n" not in message


def test_malformed_toml_names_file_and_line(write_scene):
    """Report a TOML syntax error with the file and the line it is on."""
    path = write_scene("[world]\ngravity = [0, 0, -9.81]\ndt = = 0.01\n", "broken.toml")
    with pytest.raises(SceneError) as info:
        tumble.load_scene(path)
    assert str(path) in str(info.value)
    assert "line 3" in str(info.value)


def test_a_npz_archive_given_as_a_scene_says_what_it_is(tmp_path):
    """A recording or saved state given where a scene is expected is named as a .npz archive (it was
    "not a UTF-8 text file"); other binary files keep that message."""
    archive = tmp_path / "shot.npz"
    np.savez(archive, time=np.zeros(2))
    with pytest.raises(
        SceneError, match=r"shot.npz: a .npz archive \(a recording or a saved state\), not a scene file"
    ):
        scene_io.read_scene(archive)
    junk = tmp_path / "junk.toml"
    junk.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(SceneError, match="not a UTF-8 text file"):
        scene_io.read_scene(junk)


def assert_refused(path, content, match):
    """A file holding `content` at `path` is refused as a scene by both readers, with `match`."""
    path.write_bytes(content)
    with pytest.raises(SceneError, match=match):
        scene_io.read_scene(path)
    with pytest.raises(SceneError, match=match):
        tumble.load_scene(path)


@pytest.mark.parametrize("content", [b"", b"\n", b"[world]\n"], ids=["empty", "newline", "toml"])
def test_a_file_named_npz_is_never_read_as_a_scene(tmp_path, content):
    """A .npz path is a recording or a saved state even when it is empty or holds text: it was read
    as TOML, so a zero-byte one ran as an empty scene and `tumble check` said ok."""
    assert_refused(tmp_path / "cut.npz", content, r"cut.npz: a .npz archive .*not a scene file")


@pytest.mark.parametrize(
    "content, what", [(b"", "empty"), (b"  \n\n", "empty"), (b"# a scene, some day\n", "only comments")]
)
def test_an_empty_scene_file_is_refused(tmp_path, content, what):
    """A scene file with no table in it (zero bytes, blank lines, comments) is refused by name: it ran
    as a world of nothing, and `tumble check` said ok, where the file was most likely cut short."""
    path = tmp_path / "cut.toml"
    assert_refused(path, content, rf"cut.toml: the file is {what}, not a scene")
    path.write_bytes(content + b"[world]\n")  # a world and nothing in it yet is a scene
    assert scene_io.read_scene(path).table("world") is not None


def test_a_scene_file_over_the_size_limit_is_refused_without_reading_it_to_the_end(tmp_path, monkeypatch):
    """A file larger than limits.MAX_SCENE_BYTES is refused by size: /dev/zero given as a scene was read
    until the machine ran out of memory (a device is now refused before it is opened, as a pipe is). A
    file at the limit still reads."""
    from tumble import limits

    monkeypatch.setattr(limits, "MAX_SCENE_BYTES", 1000)
    text = b"[world]\ndt = 0.01\n"
    path = tmp_path / "big.toml"
    assert_refused(path, text + b"#" * (1001 - len(text)), r"big.toml: larger than 1.0 kB, too large for a scene file")
    path.write_bytes(text + b"#" * (1000 - len(text)))
    assert scene_io.read_scene(path).table("world")["dt"] == 0.01
    if Path("/dev/zero").exists():
        with pytest.raises(SceneError, match="/dev/zero: not a regular file"):
            scene_io.read_scene("/dev/zero")


def test_a_scene_reads_any_newlines(tmp_path):
    """Windows (CR LF) and old Mac (CR) line ends read like LF ones."""
    for newline in (b"\r\n", b"\r"):
        path = tmp_path / "ends.toml"
        path.write_bytes(
            newline.join([b"[world]", b"dt = 0.01", b"[[sphere]]", b"position = [0, 0, 1]", b"radius = 0.1"])
        )
        scene = scene_io.read_scene(path)
        assert scene.table("world")["dt"] == 0.01 and len(scene.items("sphere")) == 1


def test_missing_file_is_an_oserror(tmp_path):
    """Raise FileNotFoundError (mapped to exit 2 by the CLI) for a missing scene file."""
    with pytest.raises(FileNotFoundError, match="no such scene file"):
        scene_io.validate_scene(tmp_path / "nope.toml")


def test_defaults_are_filled_in():
    """Fill every omitted key with its documented default."""
    scene = scene_io.parse_scene(BALL)
    (plane,) = scene.items("plane")
    (ball,) = scene.items("sphere")
    assert plane == {"normal": [0.0, 0.0, 1.0], "offset": 0.0, "restitution": 0.5, "friction": 0.5}
    assert ball["velocity"] == [0.0, 0.0, 0.0]
    assert ball["orientation"] == [0.0, 0.0, 0.0, 1.0]
    assert ball["static"] is False and ball["density"] is None
    assert scene.table("world") is None
    assert scene.summary() == "1 plane, 1 sphere"


def test_summary_says_meshes():
    """Name two [[mesh]] tables '2 meshes' (it said '2 meshs')."""
    scene = scene_io.parse_scene('[[mesh]]\nfile = "a.obj"\n[[mesh]]\nfile = "b.obj"\n')
    assert scene.summary() == "2 meshes"


def test_values_and_ranges_are_converted():
    """Convert integers to floats, ranges to tuples and keep shape lists."""
    scene = scene_io.parse_scene(
        "[[emitter]]\nshape = ['sphere', 'box']\nrate = 10\ncount = 3\nposition = [0, 0, 1]\n"
        "radius = [0.01, 0.02]\nhalf_extents = 0.05\nspeed = 2\nregion = 'disc'\nextent = 1\n"
        "angular_speed = [0, 3]\nrandom_orientation = true\n"
    )
    (e,) = scene.items("emitter")
    assert e["shape"] == ["sphere", "box"]
    assert e["rate"] == 10.0 and isinstance(e["rate"], float)
    assert e["radius"] == (0.01, 0.02)
    assert e["half_extents"] == 0.05 and e["speed"] == 2.0 and e["extent"] == 1.0
    assert e["angular_speed"] == (0.0, 3.0) and e["random_orientation"] is True
    assert e["direction"] == [0.0, 0.0, -1.0] and e["cone_angle"] == 0.0


def test_cloth_table_accepts_per_kind_springs_and_pin_lists():
    """Accept stiffness as a per-kind table, damping as one number and pins as [i, j] points."""
    scene = scene_io.parse_scene(
        "[[cloth]]\nsize = [1, 2]\nresolution = [8, 16]\nposition = [0, 0, 1]\n"
        "stiffness = { structural = 1000, bend = 10 }\ndamping = 0.5\npins = [[0, 15], [7, 15]]\n"
        "[wind]\nvelocity = [3, 0, 0]\nturbulence = 1\n"
    )
    (c,) = scene.items("cloth")
    assert c["stiffness"] == {"structural": 1000.0, "bend": 10.0}
    assert c["damping"] == 0.5 and c["pins"] == [(0, 15), (7, 15)]
    assert c["max_stretch"] == 0.1
    assert scene.table("wind") == {
        "velocity": [3.0, 0.0, 0.0],
        "turbulence": 1.0,
        "scale": 1.0,
        "seed": 0,
        "drag": 1.2,
        "lift": 0.3,
        "air_density": 1.2,
    }
    assert "(128 particles)" in scene.summary()


def test_bare_sample_name_resolves_to_the_samples_dir():
    """Find a bundled sample by its bare name."""
    assert scene_io.resolve_scene_path("bouncing_ball") == scene_io.SAMPLES_DIR / "bouncing_ball.toml"
    assert scene_io.SAMPLES_DIR / "sphere_pile.toml" in scene_io.list_samples()
