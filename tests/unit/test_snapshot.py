"""Snapshots (tumble/snapshot.py): restore in place, into a new world, and from a file in a new process,
each giving the trajectory of the uninterrupted run bit for bit."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tumble
from tumble import snapshot
from tumble.snapshot import SnapshotError

ROOT = Path(__file__).resolve().parents[2]
# a pile with an emitter, the box tower, the rain (emitter, random sizes), the hammock (cloth + bodies), and two
# scenes with triangle meshes: the pebble bowl (convex bodies in a mesh) and the cloth statue (cloth over a mesh),
# whose BVH ids are pointers of the process that made them (a resume in a new process crashed on the saved ones)
SCENES = ["sphere_pile", "box_tower", "rain", "hammock", "pebble_bowl", "cloth_statue"]


def _steps(world, seconds: float) -> None:
    for _ in range(round(seconds / world.dt)):
        world.step()


@pytest.mark.parametrize("name", SCENES)
def test_saved_run_resumes_in_a_new_process_bit_for_bit(name, tmp_path):
    """Run 2 s in one process against 1 s, save, load in a new process and run 1 s: same state hash."""
    world = tumble.load_scene(name)
    _steps(world, 1.0)
    path = tumble.save_snapshot(world.snapshot(), tmp_path / "state.npz")
    _steps(world, 1.0)
    code = (
        "import sys, tumble; w = tumble.load_snapshot(sys.argv[1]); "
        "[w.step() for _ in range(round(1.0 / w.dt))]; print(w.state_hash(), w.step_count, w.time)"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    out = subprocess.run(
        [sys.executable, "-c", code, str(path)], capture_output=True, text=True, env=env, timeout=600, check=True
    ).stdout.split()
    assert out[0] == world.state_hash()
    assert int(out[1]) == world.step_count
    assert float(out[2]) == world.time


def test_restore_in_place_repeats_the_run():
    """Restoring into the world the snapshot came from (after it ran on, emitting more bodies) repeats it."""
    world = tumble.load_scene("rain")
    _steps(world, 0.25)
    state = world.snapshot()
    bodies_then = world.body_count
    _steps(world, 0.5)
    first = world.state_hash(), world.body_count, world.time
    assert world.body_count > bodies_then  # the emitter kept going: rows, ids and rng all moved on
    world.restore(state)
    assert world.body_count == bodies_then and world.step_count == state.step_count
    assert world.snapshot() == state
    _steps(world, 0.5)
    assert (world.state_hash(), world.body_count, world.time) == first


def test_snapshot_is_a_copy():
    """Stepping after a snapshot does not change it; a restored world does not share arrays with it."""
    world = tumble.load_scene("bouncing_ball")
    state = world.snapshot()
    kept = state.copy()
    _steps(world, 0.1)
    assert state == kept
    world.restore(state)
    _steps(world, 0.1)
    assert state == kept


def test_world_built_in_python_restores(tmp_path):
    """A world built with the API (no scene) restores into a world built the same way; `load` says it can't."""

    def build():
        w = tumble.World(seed=3)
        w.add_plane()
        for k in range(4):
            w.add_box(position=(0.01 * k, 0, 0.3 + 0.25 * k), half_extents=(0.1, 0.1, 0.1), mass=1.0)
        return w

    a = build()
    _steps(a, 0.2)
    path = snapshot.save(a.snapshot(), tmp_path / "api.npz")
    _steps(a, 0.2)
    b = build()
    b.restore(snapshot.read(path))
    _steps(b, 0.2)
    assert a.state_hash() == b.state_hash()
    with pytest.raises(SnapshotError, match="built in Python"):
        tumble.load_snapshot(path)


def test_a_cloth_restored_while_its_substeps_rise_repeats_the_run(tmp_path):
    """A cloth's substeps rise to the world's by doubling a step as a body approaches (1, 2, 4, 8 for this
    hammock): restored from a file into a new world in the middle of that rise, it repeats the run bit for
    bit (the last step's count is cloth state, `substeps_last`; a new world would otherwise start at 8)."""

    def build():
        w = tumble.World(gravity=(0, 0, -9.81), dt=1.0 / 240.0)
        w.add_cloth(size=(1.2, 1.2), resolution=(12, 12), position=(0, 0, 1.0), mass=0.3, pins="corners")
        w.add_sphere(position=(0.01, 0.02, 1.3), radius=0.025, mass=0.05)
        return w

    a = build()
    rise = []
    while len(rise) < 2 or rise[-2:] != [1, 2]:
        a.step()
        rise.append(a.cloth.state.substeps_last)
        assert len(rise) < 240, rise  # the ball reaches the cloth within 1 s
    path = snapshot.save(a.snapshot(), tmp_path / "rising.npz")
    for _ in range(10):
        a.step()
        rise.append(a.cloth.state.substeps_last)
    assert rise[-10:-7] == [4, 8, 8], rise
    b = build()
    b.restore(snapshot.read(path))
    for _ in range(10):
        b.step()
    assert b.state_hash() == a.state_hash()


def test_a_body_moved_by_its_cloth_pin_restores_and_repeats_the_run(tmp_path):
    """A light box hung from one cloth pin, which the stretch limit moves with its pin (its pending shift and
    turn, a cache): restored in place, and into a new world from a file, it repeats the run bit for bit."""

    def build():
        w = tumble.World(gravity=(0, 0, -9.81), dt=1.0 / 240.0)
        facing_y = (0.7071067811865476, 0.0, 0.0, 0.7071067811865476)
        index = w.add_cloth(
            size=(1, 1), resolution=(6, 6), position=(0, 0, 1.5), orientation=facing_y, mass=0.2, pins="top-corners"
        )
        k = w.cloth.cloths[index].particle(0, 0)
        box = w.add_box(position=w.cloth.particle_position[k] - (0, 0, 0.6), half_extents=(0.02,) * 3, mass=0.05)
        w.pin_cloth_to_body([k], box)
        return w

    a = build()
    _steps(a, 0.5)
    state = a.snapshot()
    path = snapshot.save(state, tmp_path / "pinned.npz")
    _steps(a, 0.5)
    first = a.state_hash()
    uninterrupted = build()
    _steps(uninterrupted, 1.0)
    assert uninterrupted.state_hash() == first
    a.restore(state)
    _steps(a, 0.5)
    assert a.state_hash() == first
    b = build()
    b.restore(snapshot.read(path))
    _steps(b, 0.5)
    assert b.state_hash() == first


def test_snapshot_of_another_world_is_refused_and_changes_nothing():
    pile = tumble.load_scene("sphere_pile")
    hammock = tumble.load_scene("hammock")
    before = hammock.snapshot()
    with pytest.raises(SnapshotError, match="does not match this world"):
        hammock.restore(pile.snapshot())
    assert hammock.snapshot() == before
    with pytest.raises(TypeError, match="Snapshot"):
        hammock.restore({"bodies": 1})


def test_a_restored_world_keeps_its_own_handles(tmp_path):
    """A snapshot of one world restored into another (or loaded from a file) leaves the other's emitters and
    cloth its own: they took the first world's key, and refused the restored world's handles (HandleError)."""
    rain = tumble.load_scene("rain")
    _steps(rain, 0.1)
    other = tumble.load_scene("rain")
    emitter = other.emitters[0]
    other.restore(rain.snapshot())
    other.remove_emitter(emitter)
    assert other.emitters == []

    hammock = _cloth_and_joints_world()
    _steps(hammock, 0.05)
    path = snapshot.save(hammock.snapshot(), tmp_path / "s.npz")
    world = _cloth_and_joints_world()
    world.restore(snapshot.read(path))
    assert world.snapshot() == snapshot.read(path)
    assert world.cloth.cloth(tumble.ClothId(0, 0, world.key)).nx == 8
    world.cloth.pin_to_body([1], world.body(1))


def test_a_handle_made_after_a_snapshot_never_names_a_body_added_after_the_restore():
    """A restore takes the world back to fewer bodies, and the ids it frees are handed out again; the handles
    made between the snapshot and the restore must not name the bodies that take those ids (they would act
    on another body), while the handles made before the snapshot keep naming theirs."""
    from tumble import HandleError

    w = tumble.World()
    w.add_plane()
    ball = w.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    doomed = w.add_sphere(position=(0, 1, 1), radius=0.1, mass=1.0)
    snap = w.snapshot()
    later = w.add_sphere(position=(1, 0, 1), radius=0.1, mass=1.0)  # a new id
    w.remove_body(doomed)
    again = w.add_box(position=(0, 2, 1), half_extents=(0.1,) * 3, mass=1.0)  # doomed's id, reused
    assert int(again) == int(doomed)

    for _ in range(2):  # restore twice: the second time the ids were handed out after the first restore too
        w.restore(snap)
        assert w.has_body(ball) and w.has_body(doomed)  # made before the snapshot: theirs again
        assert not w.has_body(later) and not w.has_body(again)
        box = w.add_box(position=(2, 0, 1), half_extents=(0.1,) * 3, mass=1.0)
        assert int(box) == int(later) and box != later
        for stale in (later, again):
            with pytest.raises(HandleError, match="removed"):
                w.set_body_state(stale, velocity=(0, 0, 5))
        np.testing.assert_array_equal(w.body_velocity[box], (0, 0, 0))
        w.remove_body(doomed)
        fresh = w.add_sphere(position=(0, 3, 1), radius=0.1, mass=1.0)
        assert int(fresh) == int(doomed) and fresh not in (doomed, again)
        later, again = box, fresh


def test_values_come_back_with_their_types(tmp_path):
    """Floats exactly (hex), infinities, tuples and generator states survive the file."""
    world = tumble.load_scene("rain")
    _steps(world, 0.1)
    state = world.snapshot()
    back = snapshot.read(snapshot.save(state, tmp_path / "s.npz"))
    assert back == state and back.time == state.time and back.step_count == state.step_count
    assert back.scene == state.scene and back.overrides == state.overrides


def _cloth_and_joints_world() -> tumble.World:
    """A flag in the wind on a hinged pole beside a ball on a rope: cloth, wind, joints and body pins."""
    w = tumble.World(dt=1 / 240, substeps=4, seed=1)
    w.add_plane()
    pole = w.add_box(position=(0, 0, 1.0), half_extents=(0.02, 0.02, 0.5), mass=1.0)
    w.add_joint("hinge", None, pole, anchor=(0, 0, 0.5), axis=(0, 0, 1))
    ball = w.add_sphere(position=(0.5, 0.5, 1.0), radius=0.05, mass=0.2)
    w.add_joint("rope", None, ball, anchor=(0.5, 0.5, 1.6), anchor_b=(0.5, 0.5, 1.05), break_force=1e9)
    flag = w.add_cloth(
        size=(0.4, 0.3), resolution=(8, 6), position=(0.22, 0, 1.3), orientation=(0.7071068, 0, 0, 0.7071068)
    )
    w.pin_cloth_to_body([flag.particle(0, j) for j in range(6)], pole)
    w.set_wind(velocity=(0.0, 3.0, 0.0), turbulence=1.0, scale=0.5, seed=2)
    return w


def test_state_with_cloth_and_joints_round_trips_and_compares(tmp_path):
    """A snapshot holds the cloth's and the joints' parts: it survives a file, restores bit for bit, and a
    changed particle makes it compare unequal, naming the cloth state's particle positions."""
    world = _cloth_and_joints_world()
    _steps(world, 0.25)
    assert world.state.cloth is world.cloth.state and world.model.cloth is world.cloth.model
    assert world.state.joints is world.joints.impulses and world.control.wind is world.cloth.wind
    assert np.abs(world.state.joints.numpy("joint_impulse_linear")).max() > 0.0  # warm start to keep
    state = world.snapshot()
    back = snapshot.read(snapshot.save(state, tmp_path / "s.npz"))
    assert back == state and not back.differences(state)
    _steps(world, 0.25)
    ahead = world.state_hash(), world.snapshot()
    other = _cloth_and_joints_world()  # a new world built the same way
    other.restore(back)
    assert other.snapshot() == state
    _steps(other, 0.25)
    assert other.state_hash() == ahead[0]
    world.restore(back)  # in place: every array and value as in the uninterrupted run
    _steps(world, 0.25)
    # (ContactSet.SNAPSHOT_CACHES: the contact solver's key of array identities is not compared)
    assert world.snapshot().differences(ahead[1]) == []

    x = world.cloth.particle_position.copy()
    x[3, 2] = np.nextafter(x[3, 2], np.inf)  # one ulp, in the world's precision
    world.cloth.set_state(position=x)
    changed = world.snapshot().differences(ahead[1])
    assert "state/cloth/particles/particle_position" in changed and all("cloth" in path for path in changed)


@pytest.mark.parametrize(
    "content, message",
    [
        (b"", "not a Tumble snapshot file"),
        (b"PK\x03\x04 broken zip", "not a Tumble snapshot file"),
        (None, "no such snapshot file"),
    ],
)
def test_broken_files_get_one_line(tmp_path, content, message):
    path = tmp_path / "bad.npz"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(SnapshotError, match=message) as info:
        snapshot.read(path)
    assert "\n" not in str(info.value) and "bad.npz" in str(info.value)


def test_an_npz_without_a_manifest_is_refused(tmp_path):
    path = tmp_path / "other.npz"
    np.savez(path, x=np.zeros(3))
    with pytest.raises(SnapshotError, match="not a Tumble snapshot file"):
        snapshot.read(path)


def test_a_recording_given_as_a_snapshot_is_named_for_what_it_is(tmp_path, capsys):
    """`tumble run --resume REC.npz` with a recording (`--record`) said "not a Tumble snapshot file
    (KeyError: 'manifest is not a file in the archive')"; it now says it is a recording and which file
    --resume takes, in one line, exit status 2."""
    from tumble.cli import main

    recording = tmp_path / "ball.npz"
    assert main(["run", "bouncing_ball", "--duration", "0.1", "--record", str(recording)]) == 0
    capsys.readouterr()
    assert main(["run", "--resume", str(recording)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "KeyError" not in err, err
    assert f"{recording}: a recording (tumble run --record), not a saved state" in err and "--save-state" in err


def test_cli_save_state_and_resume(tmp_path):
    """`tumble run SCENE --duration 1 --save-state F` then `tumble run --resume F --duration 1` equals a 2 s run."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}

    def run(*args):
        done = subprocess.run(
            [sys.executable, "-m", "tumble", "run", *args], capture_output=True, text=True, env=env, timeout=600
        )
        return done.returncode, done.stdout, done.stderr

    def state_hash(stdout: str) -> str:
        return next(line.split()[-1] for line in stdout.splitlines() if line.startswith("state hash"))

    state = tmp_path / "half.npz"
    rc, whole, _ = run("bouncing_ball", "--duration", "2")
    assert rc == 0
    rc, out, _ = run("bouncing_ball", "--duration", "1", "--save-state", str(state))
    assert rc == 0 and state.exists() and "--resume" in out
    rc, resumed, _ = run("--resume", str(state), "--duration", "1")
    assert rc == 0
    assert state_hash(resumed) == state_hash(whole)

    for args, needle in [
        ((), "give a SCENE"),
        (("bouncing_ball", "--resume", str(state)), "not both"),
        (("--resume", str(tmp_path / "none.npz")), "no such snapshot file"),
        (("--resume", str(state), "--seed", "3"), "--seed cannot"),
        (("bouncing_ball", "--save-state", str(tmp_path / "x.txt")), "--save-state"),
    ]:
        rc, _, err = run(*args)
        assert rc == 2, args
        assert needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err


#: samples/box_tower.toml saved at 0.5 s by Tumble at git 817fe29: snapshot format 6, whose contacts
#: still held the solver's per-step quantities as arrays (format 7 keeps them in scratch rows)
FORMAT_6 = ROOT / "tests" / "data" / "box_tower.format6.npz"


def test_a_format_6_file_is_read_at_its_saved_moment_and_resumes(tmp_path):
    """A format 6 file loads: the bodies are where the file has them, and the world it makes steps on as
    the same state saved again in format 7 and loaded anew does, bit for bit."""
    old = snapshot.read(FORMAT_6)
    world = tumble.load_snapshot(FORMAT_6)
    assert world.step_count == old.step_count and world.precision == "float64"
    position = old.arrays["state/bodies/body_position"][: world.body_count]
    np.testing.assert_array_equal(world.body_position, position)
    path = tumble.save_snapshot(world.snapshot(), tmp_path / "again.npz")
    again = tumble.load_snapshot(path)
    _steps(world, 0.5)
    _steps(again, 0.5)
    assert np.isfinite(world.body_position).all()
    assert world.state_hash() == again.state_hash()


def test_an_edited_or_damaged_file_is_refused(tmp_path):
    """A file whose arrays were changed after saving (one cut short and saved again with NumPy), or
    whose compressed bytes were damaged, is refused with a SnapshotError naming it, not resumed."""
    world = tumble.load_scene("bouncing_ball")
    world.step()
    path = tumble.save_snapshot(world.snapshot(), tmp_path / "state.npz")
    assert snapshot.read(path).step_count == 1
    data = dict(np.load(path))
    data["a0"] = data["a0"][:1]
    np.savez(tmp_path / "edited.npz", **data)
    with pytest.raises(SnapshotError, match=r"edited\.npz: the snapshot is damaged or was edited"):
        snapshot.read(tmp_path / "edited.npz")
    saved = snapshot.read(path)
    raw = bytearray(path.read_bytes())
    damaged = 0
    for offset in range(0, len(raw), 97):  # a flipped byte: refused, or (outside the data) read unchanged
        flipped = bytearray(raw)
        flipped[offset] ^= 0xFF
        (tmp_path / "flipped.npz").write_bytes(flipped)
        try:
            again = snapshot.read(tmp_path / "flipped.npz")
        except SnapshotError:
            damaged += 1
        else:
            assert again == saved, offset
    assert damaged > 0
