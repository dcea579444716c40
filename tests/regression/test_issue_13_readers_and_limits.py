"""Broken recordings, huge requests and unexpected errors: one line naming the problem, never a traceback.

Issue 13 (bad input, huge requests and failed writes).
"""

from __future__ import annotations

import io
import subprocess
import sys
import zipfile

import numpy as np
import pytest

import tumble
import tumble.cli
import tumble.io.record
from tolerances import is_float32, resolution
from tumble import limits
from tumble.cli import main
from tumble.io.record import RecordingError, load_recording
from tumble.io.scene import SAMPLES_DIR, build_world, parse_scene

BALL = "[[plane]]\n[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nmass = 1.0\n"


# ------------------------------------------------------------------------------ recordings


def _recording(path):
    t = np.linspace(0.0, 1.0, 50)
    np.savez(path, time=t, position=np.zeros((50, 1, 3)), velocity=np.zeros((50, 1, 3)), mass=np.ones(1))
    return path


def _bad_recordings(tmp_path) -> dict[str, tuple[object, str]]:
    """name -> (path, a fragment of the message)"""
    good = _recording(tmp_path / "good.npz").read_bytes()
    cases = {}
    (tmp_path / "truncated.npz").write_bytes(good[: len(good) // 2])
    cases["truncated"] = (tmp_path / "truncated.npz", "truncated or corrupt")
    # flip one byte inside the stored data of the first member (np.savez does not compress)
    flipped = bytearray(good)
    flipped[200] ^= 0xFF
    (tmp_path / "crc.npz").write_bytes(bytes(flipped))
    cases["bad crc"] = (tmp_path / "crc.npz", "CRC")
    (tmp_path / "empty.npz").write_bytes(b"")
    cases["empty"] = (tmp_path / "empty.npz", "empty")
    cases["scene file"] = (SAMPLES_DIR / "rain.toml", "scene")
    np.save(tmp_path / "single.npy", np.zeros(3))
    cases["npy"] = (tmp_path / "single.npy", ".npy")
    np.savez(tmp_path / "pickled.npz", time=np.array([0.0, 1.0]), junk=np.array([{"a": 1}], dtype=object))
    cases["pickled"] = (tmp_path / "pickled.npz", "pickled")
    (tmp_path / "binary.npz").write_bytes(bytes(range(256)))
    cases["binary"] = (tmp_path / "binary.npz", "binary")
    np.savez(tmp_path / "notime.npz", position=np.zeros((2, 1, 3)))
    cases["no time"] = (tmp_path / "notime.npz", "'time'")
    (tmp_path / "folder.npz").mkdir()
    cases["directory"] = (tmp_path / "folder.npz", "directory")
    _lying_archive(tmp_path / "lying.npz", shape=(10**6, 10**6, 3))
    cases["header declares more than it holds"] = (
        tmp_path / "lying.npz",
        "'position' declares 24.0 TB of data but holds",
    )
    with zipfile.ZipFile(tmp_path / "text_member.npz", "w") as archive:
        archive.writestr("time.npy", b"0.0 1.0\n")
    cases["a member not an array"] = (tmp_path / "text_member.npz", "member 'time' is not a valid .npy array")
    return cases


def _lying_archive(path, shape, data=b"\0" * 64, compression=zipfile.ZIP_STORED):
    """An .npz with a good 'time' and a 'position' member whose header declares `shape` of float64
    over `data`: NumPy allocated what the header said before reading a byte."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w", compression=compression) as archive:
        time = io.BytesIO()
        np.save(time, np.array([0.0, 0.1]))
        archive.writestr("time.npy", time.getvalue())
        archive.writestr("position.npy", header.getvalue() + data)
    return path


def test_a_recording_too_large_for_the_memory_is_refused_before_it_is_read(tmp_path, monkeypatch, capsys):
    """An archive of well-compressed zeros (20 MB of arrays in a few kB, consistent headers) is refused by
    its declared size against the memory available ($TUMBLE_MEMORY here), by every reader, before it is
    expanded: one of 19 GB took tumble export 100 s and 19 GB of memory before it said a key was missing."""
    bodies = 20 * 10**6 // 48  # two frames of positions
    path = _lying_archive(tmp_path / "zeros.npz", (2, bodies, 3), bytes(48 * bodies), zipfile.ZIP_DEFLATED)
    assert path.stat().st_size < 100_000
    monkeypatch.setenv("TUMBLE_MEMORY", "30M")  # the arrays hold 20 MB; reading needs about twice that
    with pytest.raises(RecordingError, match=r"zeros.npz: its arrays hold 20.0 MB, .* about 40.0 MB of memory"):
        load_recording(path)
    for command in (["plot", str(path), "-o", str(tmp_path / "e.png")], ["run", "--resume", str(path)]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "its arrays hold 20.0 MB" in err, err
    monkeypatch.setenv("TUMBLE_MEMORY", "50M")
    assert load_recording(path)["position"].shape == (2, bodies, 3)


def test_broken_recordings_raise_one_named_error(tmp_path):
    """load_recording: each broken kind raises RecordingError naming the file and the problem."""
    for why, (path, fragment) in _bad_recordings(tmp_path).items():
        with pytest.raises(RecordingError) as info:
            load_recording(path)
        message = str(info.value)
        assert str(path) in message and fragment in message and "\n" not in message, (why, message)
        assert "pickled data" not in message or why == "pickled"


@pytest.mark.parametrize(
    "times", [[0.0, 0.5, 0.25, 1.0], [1.0, 0.5, 0.0], [0.0, float("nan"), 1.0], [0.0, float("inf")], [0.5, 0.5]]
)
def test_a_recording_whose_times_do_not_increase_is_refused(tmp_path, capsys, times):
    """A recording with its times reversed made `tumble export` say only "attempt to get argmax of an
    empty sequence" (and plot draw it); times out of order, NaN or infinite are refused naming the file."""
    path = tmp_path / "edited.npz"
    good = tumble.io.record.load_recording(_recording_of_ball(tmp_path, len(times)))
    np.savez(path, **{**good, "time": np.array(times)})
    with pytest.raises(RecordingError, match="'time' is not finite and increasing") as info:
        load_recording(path)
    assert str(path) in str(info.value)
    for argv in (
        ["export", str(path), "-o", str(tmp_path / "x.usda")],
        ["plot", str(path), "-o", str(tmp_path / "x.png")],
    ):
        if argv[0] == "export":
            pytest.importorskip("pxr")
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "'time' is not finite and increasing" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ball.npz", "edited.npz"]


def _recording_of_ball(tmp_path, frames: int):
    """A real recording of a ball, `frames` frames (every array a reader checks)."""
    world = build_world(parse_scene(BALL))
    recorder = tumble.io.record.Recorder(world, fps=1.0 / world.dt)
    for _ in range(frames - 1):  # and the frame it takes of the start
        world.step()
        recorder(world)
    return recorder.save(tmp_path / "ball.npz")


def test_plot_of_broken_recordings_exits_2_with_one_line(tmp_path, tumble_subprocess_env):
    """`tumble plot` on each broken kind: exit 2, one line naming the file, no traceback, no image."""
    for why, (path, fragment) in _bad_recordings(tmp_path).items():
        out = tmp_path / f"{why.replace(' ', '_')}.png"
        result = subprocess.run(
            [sys.executable, "-m", "tumble", "plot", str(path), "-o", str(out)],
            capture_output=True,
            text=True,
            env=tumble_subprocess_env,
            timeout=120,
        )
        assert result.returncode == 2, (why, result.stderr)
        assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr, (why, result.stderr)
        assert result.stderr.startswith("tumble plot: error: ") and str(path) in result.stderr, why
        assert fragment in result.stderr and not out.exists(), why
    result = subprocess.run(
        [sys.executable, "-m", "tumble", "plot", str(SAMPLES_DIR / "rain.toml"), "-o", str(tmp_path / "r.png")],
        capture_output=True,
        text=True,
        env=tumble_subprocess_env,
    )
    assert "tumble run" in result.stderr and "--record" in result.stderr  # says how to make a recording


# ------------------------------------------------------------------------------ limits

HUGE_REQUESTS = {
    "substeps": ("[world]\nsubsteps = 1000000000\n" + BALL, "substeps", "1,000"),
    "dt": ("[world]\ndt = 1e9\n" + BALL, "dt", "0.1"),
    "emitter count": (
        BALL + "[[emitter]]\nrate = 100\ncount = 1000000000000\nposition = [0, 0, 2]\nradius = 0.05\n",
        "count",
        "available",
    ),
    "emitter rate": (
        BALL + "[[emitter]]\nrate = 1e9\ncount = 1000000000\nposition = [0, 0, 2]\nradius = 0.05\n",
        "rate",
        "1,000 a step",
    ),
    "cloth int32": (
        "[[cloth]]\nsize = [1, 1]\nresolution = [100000, 100000]\nposition = [0, 0, 1]\n",
        "resolution",
        "int32",
    ),
    "cloth memory": (
        "[[cloth]]\nsize = [1, 1]\nresolution = [4000, 4000]\nposition = [0, 0, 1]\n",
        "resolution",
        "available",
    ),
    "check duration": (BALL + "[check]\nduration = 1e300\n", "duration", "1,000,000,000 steps"),
}


@pytest.mark.parametrize("case", list(HUGE_REQUESTS))
def test_huge_requests_are_refused_alike_by_every_command(case, write_scene, capsys, monkeypatch):
    """check, run, view and render refuse each huge request with the same line: key, request, limit."""
    import tumble.render

    monkeypatch.setenv("TUMBLE_MEMORY", "1G")
    monkeypatch.setattr(tumble.render, "create_context", lambda *a, **k: _NoContext())
    monkeypatch.setattr(tumble.render, "Renderer", _NoRenderer)
    text, key, limit = HUGE_REQUESTS[case]
    path = write_scene(text, "huge.toml")
    messages = set()
    for argv in (
        ["check", str(path)],
        ["run", str(path)],
        ["view", str(path)],
        ["render", str(path), "-o", str(path.parent / "v.mp4")],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0, err
        command = argv[0]
        assert err.startswith(f"tumble {command}: error: {path}") and key in err and limit in err, err
        messages.add(err.split(": error: ", 1)[1])
    assert len(messages) == 1, messages


class _NoContext:
    def release(self):
        pass


class _NoRenderer:
    def __init__(self, *args, **kwargs):
        pass

    def release(self):
        pass


def test_memory_limit_follows_the_available_memory(monkeypatch):
    """The body limit is the available memory over BYTES_PER_BODY: 10,000 bodies fit in 1G, 10^6 do not."""
    scene = BALL + "[[emitter]]\nrate = 100\ncount = {n}\nposition = [0, 0, 2]\nradius = 0.05\n"
    monkeypatch.setenv("TUMBLE_MEMORY", "1G")
    assert limits.available_memory() <= 2**30
    parse_scene(scene.format(n=10_000))
    most = (2**30 - 2 * limits.BYTES_PER_BODY) // limits.BYTES_PER_BODY  # beside the plane and the ball
    with pytest.raises(ValueError, match=f"at most {most:,} bodies"):
        parse_scene(scene.format(n=10**6))


def test_parse_bytes():
    """TUMBLE_MEMORY sizes: binary multiples, plain bytes, and a clear error otherwise."""
    assert limits.parse_bytes("2G") == 2 * 2**30
    assert limits.parse_bytes("512m") == 512 * 2**20
    assert limits.parse_bytes("1.5 GiB") == int(1.5 * 2**30)
    assert limits.parse_bytes("100000") == 100000
    with pytest.raises(limits.LimitError, match="TUMBLE_MEMORY"):
        limits.parse_bytes("lots")


def test_run_refuses_too_many_steps_and_a_recording_too_big(write_scene, capsys, monkeypatch):
    """--duration beyond 10^9 steps, and a --record whose frames exceed memory: one line each."""
    path = str(write_scene(BALL))
    assert main(["run", path, "--duration", "1e300"]) == 2
    assert "1,000,000,000 steps" in capsys.readouterr().err
    monkeypatch.setenv("TUMBLE_MEMORY", "1M")
    assert main(["run", path, "--duration", "100", "--record", str(write_scene("", "r.npz"))]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--record" in err and "frames" in err and "--fps" in err


def test_a_huge_emitter_rate_from_python_does_not_hang():
    """An emitter asking for 10^9 bodies at 10^9/s releases at most MAX_RELEASE_PER_STEP a step, and
    the world holds no more rows than it released (nothing sized for the 10^9 asked for)."""
    import tumble

    world = tumble.World()
    world.add_plane()
    world.add_emitter(rate=1e9, count=10**9, position=(0, 0, 50), region="box", extent=(40, 40, 40), radius=0.05)
    world.step()
    released = world.body_count - 1
    assert 0 < released <= limits.MAX_RELEASE_PER_STEP
    world.step()
    assert released < world.body_count - 1 <= 2 * limits.MAX_RELEASE_PER_STEP
    assert world.state.bodies.capacity <= 2 * world.body_count  # rows for what was released, not what was asked


def test_deeply_nested_toml_is_one_line(write_scene, capsys):
    """A value nested 100,000 deep is a clean error in check and run."""
    path = write_scene("x = " + "[" * 100_000 + "]" * 100_000 + "\n", "deep.toml")
    for command in ("check", "run"):
        assert main([command, str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "nested too deeply" in err


# ------------------------------------------------------------------------------ no tracebacks


def test_an_unexpected_error_is_one_line_with_how_to_debug(monkeypatch, capsys, tumble_subprocess_env):
    """A bug: exit 1, one line naming it and --debug / TUMBLE_DEBUG; with them, the traceback."""
    from tumble.commands import check

    def broken(args):
        raise RuntimeError("something broke")

    monkeypatch.setattr(check, "main", broken)
    assert main(["check", "bouncing_ball"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "RuntimeError: something broke" in err
    assert "--debug" in err and "TUMBLE_DEBUG=1" in err
    for argv in (["--debug", "check", "bouncing_ball"], ["check", "bouncing_ball", "--debug"]):
        with pytest.raises(RuntimeError):
            main(argv)
    monkeypatch.setenv("TUMBLE_DEBUG", "1")
    with pytest.raises(RuntimeError):
        main(["check", "bouncing_ball"])


def test_debug_shows_the_traceback_of_bad_input(tmp_path, tumble_subprocess_env):
    """TUMBLE_DEBUG=1 turns the one-line error of a missing file into a traceback."""
    env = dict(tumble_subprocess_env, TUMBLE_DEBUG="1")
    result = subprocess.run(
        [sys.executable, "-m", "tumble", "check", str(tmp_path / "none.toml")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert result.returncode != 0 and "Traceback" in result.stderr


def test_out_of_memory_says_so_and_what_to_reduce(monkeypatch, capsys):
    """A MemoryError: one line saying out of memory and what to reduce, exit 2."""
    from tumble.commands import run

    def oom(args):
        raise MemoryError("Unable to allocate 7.45 GiB")

    monkeypatch.setattr(run, "main", oom)
    assert main(["run", "bouncing_ball"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "out of memory" in err and "reduce" in err and "7.45 GiB" in err


@pytest.mark.parametrize("command, module", [("plot", "matplotlib"), ("view", "PySide6"), ("render", "moderngl")])
def test_a_missing_optional_package_names_the_pip_command(command, module, tmp_path, tumble_subprocess_env):
    """Without matplotlib / PySide6 / moderngl: one line naming the package and the pip command, exit 2."""
    _recording(tmp_path / "r.npz")
    argv = {
        "plot": ["plot", str(tmp_path / "r.npz"), "-o", str(tmp_path / "p.png")],
        "view": ["view", "bouncing_ball"],
        "render": ["render", "bouncing_ball", "-o", str(tmp_path / "v.mp4")],
    }[command]
    # a fresh interpreter in which importing `module` fails as it does where it is not installed
    program = f"import sys; sys.modules[{module!r}] = None; from tumble.cli import main; sys.exit(main({argv!r}))"
    result = subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, env=tumble_subprocess_env, timeout=240
    )
    assert result.returncode == 2, result.stderr
    err = result.stderr.strip()
    assert err.count("\n") == 0 and repr(module) in err and 'pip install "tumble[viewer]"' in err, err
    assert tumble.cli.OPTIONAL[module] == 'pip install "tumble[viewer]"'


@pytest.mark.parametrize(
    "body, key",
    [
        ("[[sphere]]\nposition = [0, 0, 1]\nradius = 1e300\n", "radius"),
        ("[[sphere]]\nposition = [0, 0, 1]\nradius = 1e-300\n", "radius"),
        ("[[sphere]]\nposition = [0, 0, 1]\nradius = 1\nmass = 1e-320\n", "radius"),
        ("[[box]]\nposition = [0, 0, 1]\nhalf_extents = [1e-200, 1e-200, 1]\n", "half_extents"),
        ("[[emitter]]\nrate = 10\ncount = 10\nposition = [0, 0, 1]\nradius = [1e-200, 0.1]\n", "radius"),
    ],
)
def test_sizes_whose_mass_is_not_representable_are_refused(body, key):
    """A mass or inertia that overflows or vanishes in float64 is a SceneError naming the size key."""
    with pytest.raises(ValueError, match=f"{key}: a size of .* must be finite and > 0"):
        parse_scene(body)


EMITTER = "[[plane]]\n[[emitter]]\nrate = 10\ncount = 2\nposition = [0, 0, 1]\n"
TETRAHEDRON = "[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]"


@pytest.mark.parametrize(
    "body, message",
    [
        # each ran (a box's state went NaN at step 25, exit 2 only then; spheres never fitted) or crashed
        # (a convex one: OverflowError, exit 1): the emitter's scale multiplies every size
        ('shape = "convex"\npoints = ' + TETRAHEDRON + "\nscale = 1e100\n", "scale: a size of [0.5, 0.5, 0.5] m"),
        ('shape = "convex"\npoints = ' + TETRAHEDRON + "\nscale = 1e-200\n", "times scale 1e-200"),
        ("radius = 0.1\nscale = [0.1, 1e200]\n", "scale: a size of 0.1 m times scale 1e+200"),
        ('shape = "box"\nhalf_extents = 0.1\nscale = 1e200\n', "times scale 1e+200 gives a mass of inf kg"),
        ('shape = "capsule"\nradius = 0.1\nhalf_height = 0.1\nscale = 1e-200\n', "gives a mass of 0 kg"),
        (
            'shape = "convex"\npoints = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]\n',
            "points: the points span no volume",
        ),
    ],
)
def test_emitter_scales_whose_mass_is_not_representable_are_refused(body, message, write_scene, capsys):
    """An emitter's sizes times its `scale` (and a convex one's points) are held to the same rule as
    a body's size, by `tumble check` as by `run`: one line naming the key, exit 2."""
    path = write_scene(EMITTER + body)
    for command in ("check", "run"):
        assert main([command, str(path), "--duration", "0.3"][: 2 if command == "check" else 4]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err


def test_a_convex_emitter_scaled_beyond_float64_from_python_is_a_value_error():
    """World.add_emitter: a hull scaled by 1e100 (moments s^5 overflow) raised OverflowError."""
    world = tumble.World()
    with pytest.raises(ValueError, match="scale 1e\\+100 gives the hull a volume of .* must be finite and > 0"):
        world.add_emitter(shape="convex", points=np.eye(4, 3, -1), scale=1e100, rate=10, count=2, position=(0, 0, 1))
    assert not world.emitters


def test_thin_but_representable_boxes_are_accepted():
    """A box 1e-120 m thin (1e-30 m in float32, whose floats stop at 1.2e-38) still has a finite,
    positive mass and inertia, and inverses: accepted, built, and it steps."""
    thin = 1e-30 if is_float32() else 1e-120
    world = build_world(parse_scene(f"[[box]]\nposition = [0, 0, 1]\nhalf_extents = [{thin}, 1, 1]\n"))
    mass = 1000.0 * 8.0 * thin  # the default density times the volume 8 a b c
    # stored in the world's precision, the inertia inverted and back: a few ulps
    rel = resolution(1e-12, 1.0, 4)
    assert world.body_mass[0] == pytest.approx(mass, rel=rel)
    inertia = np.diag(world.body_inertia_world[0])
    assert inertia == pytest.approx([2.0 * mass / 3.0, mass / 3.0, mass / 3.0], rel=rel)  # m / 3 (b^2 + c^2), ...
    world.step()
    assert np.isfinite(world.body_position).all() and world.body_position[0, 2] < 1.0


def test_resume_of_a_file_that_is_not_a_snapshot_says_what_it_is(tmp_path, capsys):
    """`tumble run --resume scene.toml` said "not a Tumble snapshot file (ValueError: This file contains
    pickled (object) data. If you trust the file you can load it unsafely using the `allow_pickle=`
    keyword ...)", NumPy's advice to unpickle it; it now says what the file seems to be."""
    scene = tmp_path / "ball.toml"
    scene.write_text(BALL, encoding="utf-8")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(bytes(range(256)))
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    zeros = tmp_path / "zeros.npz"  # valid UTF-8, but not text (was called a text file)
    zeros.write_bytes(bytes(4096))
    cases = [(scene, "it is a text file (a scene?"), (junk, "unknown binary content"), (empty, "empty")]
    for path, what in cases + [(zeros, "unknown binary content")]:
        assert main(["run", "--resume", str(path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "pickle" not in err, err
        assert err.startswith(f"tumble run: error: {path}: not a Tumble snapshot file (") and what in err, err
