"""`tumble run` (tumble.commands.run): the summary, the stage profile, recordings, exit codes on bad options."""

from __future__ import annotations

import importlib.util
import os
import signal
import time

import numpy as np
import pytest

import tumble
from tolerances import is_float32, resolution, stored, ulps
from tumble.cli import main

from ..io.scene import BALL

# a ground plane, one sphere and an emitter releasing 4 spheres at 40 per second from t = 0
EMITTING = (
    BALL
    + """
[[emitter]]
rate = 40
count = 4
position = [0, 0, 2]
region = "box"
extent = [0.5, 0.5, 0.1]
radius = 0.05
mass = 0.1
seed = 3
"""
)


def test_run_prints_a_summary(write_scene, capsys):
    """Run a scene headless, exit 0 and print bodies, steps, speed, energy and contacts."""
    assert main(["run", str(write_scene(BALL)), "--duration", "0.25"]) == 0
    out = capsys.readouterr().out
    for label in ("bodies", "steps", "steps/s", "kinetic energy", "contacts"):
        assert label in out
    assert "2 (1 plane, 1 sphere, 0 boxes)" in out
    assert "60 (0.250 s simulated" in out  # 0.25 s at dt = 1/240


def test_run_summary_counts_capsules_convex_bodies_and_meshes(capsys, tmp_path):
    """Count every shape in the summary: capsules, convex bodies and meshes were left out."""
    (tmp_path / "tri.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n")
    scene = BALL + (
        "[[capsule]]\nposition = [1, 0, 1]\nradius = 0.1\nhalf_height = 0.2\n"
        "[[convex]]\nposition = [-1, 0, 1]\npoints = [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]]\n"
        '[[mesh]]\nfile = "tri.obj"\nposition = [5, 5, 0]\n[[mesh]]\nfile = "tri.obj"\nposition = [-5, 5, 0]\n'
    )
    path = tmp_path / "shapes.toml"
    path.write_text(scene)
    assert main(["run", str(path), "--duration", "0.01"]) == 0
    assert "6 (1 plane, 1 sphere, 0 boxes, 1 capsule, 1 convex, 2 meshes)" in capsys.readouterr().out


def test_run_summary_counts_the_emitted_bodies_and_names_an_emitter_that_finds_no_room(capsys, tmp_path):
    """An emitter whose region lies inside a closed mesh never releases a body, and said nothing: the
    summary counts the emitted bodies and names the emitter that has found no free spot, and for how long."""
    v = [(x, y, z) for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)]
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3]]
    faces = [t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])]
    (tmp_path / "cube.obj").write_text(
        "".join(f"v {x} {y} {z}\n" for x, y, z in v) + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
    )
    inside = EMITTING.replace("position = [0, 0, 2]", "position = [5, 0, 1]").replace(
        "extent = [0.5, 0.5, 0.1]", "extent = [0.2, 0.2, 0.1]"
    )
    scene = EMITTING + inside + '[[mesh]]\nfile = "cube.obj"\nposition = [5, 0, 1]\n'
    path = tmp_path / "inside.toml"
    path.write_text(scene)
    assert main(["run", str(path), "--duration", "0.5"]) == 0
    line = next(row for row in capsys.readouterr().out.splitlines() if row.startswith("emitted"))
    # the first emitter releases its 4 (at 40 a second, the first at 25 ms); the second tries from 25 ms on
    assert line.split(None, 1)[1].startswith("4 of 8 bodies; emitter 2 has found no free spot in its region")
    blocked = float(line.split("for the last ")[1].split(" s")[0])
    assert 0.5 - 0.025 - 2 / 240 <= blocked <= 0.5 - 0.025 + 1 / 240  # tried each step since it first owed one


def test_run_profile_lists_the_stages(write_scene, capsys):
    """Print the time per stage with --profile."""
    assert main(["run", str(write_scene(BALL)), "--duration", "0.05", "--profile"]) == 0
    out = capsys.readouterr().out
    assert "stage" in out and "ms/step" in out and "total" in out


def test_record_writes_the_documented_arrays(write_scene, tmp_path, capsys):
    """Write every documented array with its shape, and NaN rows for bodies not yet emitted."""
    out = tmp_path / "rec.npz"
    assert main(["run", str(write_scene(EMITTING)), "--duration", "0.5", "--record", str(out), "--fps", "30"]) == 0
    rec = np.load(out)
    f = 16  # frames at t = 0, 1/30, ..., 15/30 = 0.5 s
    n = 2 + 4  # plane, sphere, 4 emitted spheres
    expected = {
        "time": (f,),
        "position": (f, n, 3),
        "velocity": (f, n, 3),
        "orientation": (f, n, 4),
        "angular_velocity": (f, n, 3),
        "shape": (n,),
        "shape_names": (len(tumble.ShapeType),),
        "radius": (n,),
        "half_extents": (n, 3),
        "mass": (n,),
        "gravity": (3,),
        "dt": (),
        "contact_count": (f,),
        "kinetic_energy": (f,),
    }
    for name, shape in expected.items():
        assert rec[name].shape == shape, name
    np.testing.assert_allclose(rec["time"], np.arange(f) / 30.0, atol=0.5 / 240)
    assert rec["shape"].dtype == np.int32
    assert list(rec["shape_names"][rec["shape"]]) == ["plane", "sphere"] + ["sphere"] * 4
    np.testing.assert_array_equal(rec["radius"], stored([0.0, 0.1] + [0.05] * 4))  # as the world holds them
    # at t = 0 only the plane and the ball exist; at the end every body does
    assert np.isfinite(rec["position"][0, :2]).all()
    assert np.isnan(rec["position"][0, 2:]).all() and np.isnan(rec["orientation"][0, 2:]).all()
    assert np.isfinite(rec["position"][-1]).all()
    # once a body appears it stays: its NaN frames come first
    present = np.isfinite(rec["position"][:, :, 0])
    assert (np.diff(present.astype(int), axis=0) >= 0).all()
    # the free ball falls as z0 - g t^2 / 2 until it reaches the ground (z0 = 1 m, it lands after ~0.43 s)
    t = rec["time"][:6]
    np.testing.assert_allclose(rec["position"][:6, 1, 2], 1.0 - 0.5 * 9.81 * t**2, atol=9.81 * t.max() / 240 + 1e-9)
    assert "recorded" in capsys.readouterr().out


def test_record_and_save_state_to_one_file_is_refused(write_scene, tmp_path, capsys):
    """--record X --save-state X wrote the state over the recording and exited 0; now exit 2 with
    one line naming both options, and the file already there is kept."""
    out = tmp_path / "both.npz"
    out.write_bytes(b"kept")
    argv = ["run", str(write_scene(BALL)), "--duration", "0.05", "--record", str(out)]
    assert main([*argv, "--save-state", str(tmp_path / "." / "both.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--record and --save-state name the same file" in err
    assert out.read_bytes() == b"kept"


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["run", "missing.toml"], "no such scene file"),
        (["run", "SCENE", "--duration", "-1"], "--duration"),
        (["run", "SCENE", "--fps", "0"], "--fps"),
        (["run", "SCENE", "--record", "out.csv"], ".npz"),
        (["run", "SCENE", "--record", "no/such/dir/out.npz"], "no such directory"),
    ],
)
def test_bad_arguments_exit_2(write_scene, capsys, argv, fragment):
    """Reject a missing file or a bad option with exit status 2 and one line on stderr."""
    path = str(write_scene(BALL))
    assert main([path if a == "SCENE" else a for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and fragment in err


CLOTH_READY = importlib.util.find_spec("tumble.cloth") is not None


@pytest.mark.skipif(not CLOTH_READY, reason="the cloth engine (tumble.cloth) is not merged yet")
def test_record_writes_cloth_arrays(write_scene, tmp_path):
    """Add cloth_position, cloth_triangles, cloth_rest_position, cloth_mass and strain to cloth recordings."""
    out = tmp_path / "cloth.npz"
    scene = write_scene(
        "[[plane]]\n[[cloth]]\nsize = [1, 0.5]\nresolution = [6, 4]\nposition = [0, 0, 1]\npins = 'top-edge'\n"
    )
    assert main(["run", str(scene), "--duration", "0.25", "--record", str(out)]) == 0
    rec = np.load(out)
    f, p = 16, 6 * 4
    assert rec["cloth_position"].shape == (f, p, 3)
    assert rec["cloth_triangles"].shape == (2 * 5 * 3, 3) and rec["cloth_triangles"].dtype == np.int32
    np.testing.assert_allclose(rec["cloth_rest_position"], rec["cloth_position"][0])
    # row-major, i fastest: particle j * nx + i sits at x = -0.5 + i * 0.2, y = -0.25 + j * 0.5 / 3 at rest
    rest = [-0.3, -0.25 + 0.5 / 3]
    np.testing.assert_allclose(rec["cloth_rest_position"][7, :2], rest, atol=resolution(1e-12, 0.5, 4))
    # the pinned top edge (j = 3) stays; the rest falls
    np.testing.assert_allclose(rec["cloth_position"][-1, 18:, 2], 1.0, atol=1e-9)
    assert rec["cloth_position"][-1, :6, 2].max() < 1.0
    # masses add up to the cloth's; strain starts at zero and stays within the 10 % limit
    assert rec["cloth_mass"].shape == (p,) and rec["cloth_mass"].sum() > 0
    assert rec["cloth_max_strain"].shape == (f,)
    # at rest |d| / l0 - 1, l0 measured in float64 and stored: 0 in float64, an ulp of 1 or so in float32
    assert abs(rec["cloth_max_strain"][0]) <= (ulps(1.0, 4) if is_float32() else 0.0)
    assert 0.0 < rec["cloth_max_strain"].max() <= 0.1 + 1e-6


def test_a_first_ctrl_c_waits_for_the_step_to_end_and_a_second_stops_at_once():
    """run's SIGINT handler only asks the loop to stop between steps; a second Ctrl-C raises at once."""
    from tumble.commands.run import interrupt_between_steps

    before = signal.getsignal(signal.SIGINT)
    with interrupt_between_steps() as interrupted:
        assert not interrupted.is_set()
        os.kill(os.getpid(), signal.SIGINT)  # handled in the main thread before the next bytecode
        time.sleep(0.01)
        assert interrupted.is_set()  # the request is recorded, nothing was raised mid-step
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)
    assert signal.getsignal(signal.SIGINT) is before  # the caller's handler is back


def test_a_sigterm_also_waits_for_the_step_to_end(tumble_subprocess_env, tmp_path):
    """`kill` during `tumble run --save-state` raised Terminated mid-step, and the state saved could be
    a step half taken; and it said "interrupted", status 130. Now SIGTERM, as Ctrl-C, stops between
    steps: "terminated", status 143, and the saved state resumes as the run would have gone on."""
    import subprocess
    import sys

    from tumble.cli import Terminated
    from tumble.commands.run import interrupt_between_steps

    leaked: list[int] = []  # (this process's own SIGTERM handler, lest a SIGTERM not caught end pytest)
    guard = signal.signal(signal.SIGTERM, lambda signum, frame: leaked.append(signum))
    try:
        with interrupt_between_steps() as request:  # in this process: the request is recorded, not raised
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.01)
        assert not leaked and request.is_set() and isinstance(request.exception(), Terminated)
    finally:
        signal.signal(signal.SIGTERM, guard)
    state = tmp_path / "state.npz"
    proc = subprocess.Popen(
        [sys.executable, "-m", "tumble", "run", "sphere_pile", "--duration", "600", "--save-state", str(state)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=tumble_subprocess_env,
    )
    assert proc.stderr is not None
    for line in proc.stderr:  # stepping once the first step is done
        if line.startswith("first step done"):
            break
    time.sleep(0.5)
    proc.terminate()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("tumble run: terminated at t = ") and last.endswith(f"saved the state to {state}")
    steps = int(last.split("(step ")[1].split(")")[0].replace(",", ""))
    resumed = tumble.load_snapshot(state)
    assert resumed.step_count == steps > 1
    fresh = tumble.load_scene("sphere_pile", precision=resumed.precision)  # (the command's, float64)
    for _ in range(steps + 12):
        fresh.step()
    for _ in range(12):
        resumed.step()
    assert resumed.state_hash() == fresh.state_hash()


def test_record_takes_a_frame_a_step_at_most_by_default(write_scene, tmp_path, capsys):
    """A world of dt = 0.05 s steps 20 times a second: --record without --fps records 20 frames a
    second of them (the default 60 was refused once the recorder refused rates above the step
    rate); asking for 60 is refused with one line and exit 2."""
    path = write_scene("[world]\ndt = 0.05\n" + BALL)
    out = tmp_path / "slow.npz"
    assert main(["run", str(path), "--duration", "1", "--record", str(out)]) == 0
    rec = tumble.io.record.load_recording(out)
    assert float(rec["fps"]) == 20.0 and len(rec["time"]) == 21
    np.testing.assert_allclose(np.diff(rec["time"]), 0.05)
    capsys.readouterr()
    assert main(["run", str(path), "--duration", "1", "--record", str(tmp_path / "fast.npz"), "--fps", "60"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "fps 60 is more than the world's 20 steps per second" in err
