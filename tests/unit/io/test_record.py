"""io/record.py: a recording holds, frame by frame, the state the world had at each sample time,
and save + load_recording round-trips every field (dtype, shape and value)."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tolerances import stored
from tumble.cli import main
from tumble.cloth.system import PARTICLE_FIELDS
from tumble.errors import TumbleError
from tumble.io.atomic import OutputError
from tumble.io.record import FORMAT_VERSION, Recorder, RecordingError, load_recording, recorded_name
from tumble.model import BODY_FIELDS, Role

DT = 1.0 / 64.0
FPS = 16.0  # a frame every 4 steps


def small_world() -> tumble.World:
    world = tumble.World(dt=DT, substeps=2)
    world.add_plane(friction=0.3)
    world.add_sphere(position=(0.0, 0.0, 1.0), radius=0.1, mass=1.0, velocity=(0.5, 0.0, 0.0), restitution=0.2)
    world.add_box(
        position=(1.0, 0.0, 0.3), half_extents=(0.1, 0.2, 0.3), mass=2.0, angular_velocity=(0.0, 0.0, 3.0), friction=0.9
    )
    return world


def test_frames_hold_the_state_at_each_sample_time():
    """Frame k is the world at t = k / fps: positions, velocities, orientations, energy, momentum, contacts."""
    world = small_world()
    seen = [(world.time, world.body_position.copy(), world.kinetic_energy(), world.contact_count)]
    recorder = Recorder(world, fps=FPS)

    def watch(w):
        recorder(w)
        if len(recorder.frames) > len(seen):  # a frame was just taken: keep our own copy
            seen.append((w.time, w.body_position.copy(), w.kinetic_energy(), w.contact_count))

    world.run(1.0, callback=watch)
    rec = recorder.arrays()
    f = round(1.0 * FPS) + 1
    assert recorder.frame_count == f == len(seen)
    np.testing.assert_allclose(rec["time"], np.arange(f) / FPS, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rec["position"], np.array([s[1] for s in seen]))
    np.testing.assert_array_equal(rec["kinetic_energy"], [s[2] for s in seen])
    np.testing.assert_array_equal(rec["contact_count"], [s[3] for s in seen])
    # the last frame is the world now
    np.testing.assert_array_equal(rec["velocity"][-1], world.body_velocity)
    np.testing.assert_array_equal(rec["orientation"][-1], world.body_orientation)
    np.testing.assert_array_equal(rec["angular_velocity"][-1], world.body_angular_velocity)
    np.testing.assert_allclose(rec["momentum"][-1], world.momentum(), rtol=0, atol=1e-12)
    assert rec["momentum"].shape == (f, 3)


def test_bodies_and_world_settings_are_recorded_once():
    """Shapes, sizes, masses, materials, gravity, dt and fps, as the world has them."""
    world = small_world()
    rec = Recorder(world, fps=FPS).arrays()
    assert int(rec["format_version"]) == FORMAT_VERSION
    assert [str(rec["shape_names"][s]) for s in rec["shape"]] == ["plane", "sphere", "box"]
    np.testing.assert_array_equal(rec["radius"], world.body_radius)
    np.testing.assert_array_equal(rec["half_extents"][2], stored([0.1, 0.2, 0.3]))  # as the world holds them
    np.testing.assert_array_equal(rec["mass"], world.body_mass)
    np.testing.assert_array_equal(rec["restitution"], world.body_restitution)
    np.testing.assert_array_equal(rec["friction"], world.body_friction)
    np.testing.assert_array_equal(rec["gravity"], world.gravity)
    assert float(rec["dt"]) == DT and float(rec["fps"]) == FPS
    assert "cloth_position" not in rec and "joint_force" not in rec and "hull_points" not in rec
    np.testing.assert_array_equal(rec["geometry"], 0)  # no hulls or meshes: every body's row 0


def test_every_declared_state_array_is_recorded_per_frame_and_every_model_array_once():
    """The recording's body and particle arrays are the declarations' state (F, rows, ...) and model (rows, ...) ones."""
    world = tumble.World(dt=DT, substeps=2)
    world.add_plane()
    world.add_sphere(position=(0.0, 0.0, 1.0), radius=0.1)
    world.add_cloth(size=(0.5, 0.5), resolution=(4, 3), position=(0.0, 0.0, 2.0), pins="top-corners")
    recorder = Recorder(world, fps=FPS)
    world.run(0.25, callback=recorder)
    rec, f = recorder.arrays(), recorder.frame_count
    declared = {
        "body": (BODY_FIELDS, world.body_count, world.body_values),
        "cloth": (PARTICLE_FIELDS, world.cloth.particle_count, world.cloth.particle_values),
    }
    for fields, rows, values in declared.values():
        for field in fields:
            name = recorded_name(field)
            if field.role is Role.STATE:
                assert rec[name].shape == (f, rows, *field.shape), name
                np.testing.assert_array_equal(rec[name][-1], values(field.name), err_msg=name)
            elif field.role is Role.MODEL:
                np.testing.assert_array_equal(rec[name], values(field.name), err_msg=name)
            else:  # scratch and control arrays are not recorded
                assert name not in rec, name
    assert {"position", "velocity", "mass", "cloth_position", "cloth_velocity", "cloth_mass"} <= set(rec)
    assert recorded_name(BODY_FIELDS[0]) == BODY_FIELDS[0].name.removeprefix("body_")


def test_bodies_added_later_are_nan_before_they_exist():
    """Rows of a body created after a frame are NaN in that frame; later frames have its state."""
    world = small_world()
    recorder = Recorder(world, fps=FPS)
    world.run(0.25, callback=recorder)
    late = world.add_sphere(position=(3.0, 0.0, 0.5), radius=0.1, mass=1.0)
    world.run(0.25, callback=recorder)
    rec = recorder.arrays()
    born = int(np.argmax(~np.isnan(rec["position"][:, late.index, 0])))
    assert born == 5  # frames 0..4 cover the first 0.25 s
    assert np.isnan(rec["position"][:born, late.index]).all()
    assert np.isnan(rec["orientation"][:born, late.index]).all()
    assert not np.isnan(rec["position"][:, : late.index]).any()
    np.testing.assert_array_equal(rec["position"][-1, late.index], late.position)


def test_save_and_load_round_trip_every_field(tmp_path):
    """load_recording(save(path)) gives back each array with its dtype, shape and values (NaN too)."""
    world = small_world()
    recorder = Recorder(world, fps=FPS)
    world.run(0.25, callback=recorder)
    world.add_sphere(position=(3.0, 0.0, 0.5), radius=0.1, mass=1.0)
    world.run(0.25, callback=recorder)
    path = recorder.save(tmp_path / "run.npz")
    assert path == tmp_path / "run.npz" and [p.name for p in tmp_path.iterdir()] == ["run.npz"]
    loaded, written = load_recording(path), recorder.arrays()
    assert set(loaded) == set(written)
    for name, value in written.items():
        assert loaded[name].dtype == np.asarray(value).dtype, name
        np.testing.assert_array_equal(loaded[name], value, err_msg=name)


def test_cloth_and_hulls_are_recorded(tmp_path):
    """With a cloth: its particles per frame, triangles, masses, strain; with a hull: its points and triangles."""
    world = tumble.World(dt=DT, substeps=2)
    world.add_plane()
    world.add_cloth(size=(0.5, 0.5), resolution=(4, 3), position=(0.0, 0.0, 1.0), mass=0.3, pins="top-corners")
    cube = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.1, 0.1) for z in (-0.1, 0.1)])
    world.add_convex(points=cube, position=(1.0, 0.0, 0.5), mass=1.0)
    recorder = Recorder(world, fps=FPS)
    world.run(0.25, callback=recorder)
    rec = load_recording(recorder.save(tmp_path / "cloth.npz"))
    f, p = recorder.frame_count, 12
    assert rec["cloth_position"].shape == (f, p, 3)
    np.testing.assert_array_equal(rec["cloth_position"][-1], world.cloth.particle_position)
    np.testing.assert_array_equal(rec["cloth_triangles"], world.cloth.triangles)
    assert rec["cloth_mass"].sum() == pytest.approx(0.3)
    assert rec["cloth_max_strain"].shape == (f,) and rec["cloth_max_strain"][0] == 0.0
    # the cube's hull row: 8 points about its centre, 12 triangles (6 faces fanned), rows [start[g], start[g + 1])
    g = int(rec["geometry"][-1])
    start, tri_start = rec["hull_point_start"], rec["hull_triangle_start"]
    assert len(start) == len(tri_start) == len(world.hulls.prototypes) + 1
    points = rec["hull_points"][start[g] : start[g + 1]]
    triangles = rec["hull_triangles"][tri_start[g] : tri_start[g + 1]]
    assert points.shape == (8, 3) and triangles.shape == (12, 3)
    np.testing.assert_allclose(np.abs(points), 0.1, atol=1e-12)
    assert triangles.min() == 0 and triangles.max() == 7  # indices within the hull's own points


def test_bad_fps_and_bad_output_paths_are_refused(tmp_path):
    """fps <= 0 or NaN raises ValueError; a path that is not .npz or has no folder raises OutputError."""
    world = small_world()
    for fps in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="fps"):
            Recorder(world, fps=fps)
    recorder = Recorder(world, fps=FPS)
    with pytest.raises(OutputError):
        recorder.save(tmp_path / "run.txt")
    with pytest.raises(OutputError):
        recorder.save(tmp_path / "missing" / "run.npz")
    assert list(tmp_path.iterdir()) == []


def test_fps_above_the_step_rate_is_refused():
    """A recording takes at most one frame a step: fps above 1 / dt raises ValueError naming both
    (it recorded one frame a step and stored the higher fps, so an export timed them wrongly)."""
    world = small_world()
    steps_per_second = 1.0 / world.dt
    with pytest.raises(ValueError, match=f"fps 1000 is more than the world's {steps_per_second:g} steps"):
        Recorder(world, fps=1000.0)
    assert Recorder(world, fps=steps_per_second).fps == steps_per_second


def test_load_refuses_files_without_time_and_newer_versions(tmp_path):
    """No 'time' array: RecordingError; a format version above FORMAT_VERSION: TumbleError naming both."""
    no_time = tmp_path / "no_time.npz"
    np.savez(no_time, position=np.zeros((2, 1, 3)))
    with pytest.raises(RecordingError, match="'time'"):
        load_recording(no_time)
    newer = tmp_path / "newer.npz"
    np.savez(newer, time=np.zeros(1), format_version=np.int32(FORMAT_VERSION + 1))
    with pytest.raises(TumbleError, match=f"version {FORMAT_VERSION + 1} is newer"):
        load_recording(newer)
    with pytest.raises(RecordingError, match="no such recording"):
        load_recording(tmp_path / "absent.npz")


def test_a_saved_state_is_named_as_one_where_a_recording_is_expected(tmp_path):
    """A --save-state file given to plot or export is refused as a saved state, pointing at run --resume
    (it said "a recording needs a non-empty 1-D 'time' array")."""
    from tumble import snapshot

    world = tumble.World()
    world.add_sphere(position=(0, 0, 1), radius=0.1)
    path = tmp_path / "state.npz"
    snapshot.save(world.snapshot(), path)
    with pytest.raises(
        RecordingError, match=r"state.npz: a saved state \(run --save-state\), not a recording; .*--resume"
    ):
        load_recording(path)


def test_recorder_samples_at_the_nearest_step(write_scene):
    """Record one frame per 1/fps of simulated time, at the step nearest to it, when dt does not divide it."""
    from .scene import BALL

    world = tumble.load_scene(write_scene("[world]\ndt = 0.01\n" + BALL))
    recorder = Recorder(world, fps=30)
    world.run(1.0, callback=recorder)
    time = recorder.arrays()["time"]
    assert len(time) == 31  # t = 0, 1/30, ..., 1
    assert np.all(np.abs(time - np.arange(31) / 30) <= 0.5 * world.dt + 1e-12)
    with pytest.raises(ValueError, match="fps"):
        Recorder(world, fps=0)


def test_arrays_that_disagree_or_name_no_shape_are_refused(tmp_path):
    """A recording edited after it was written (one body's rows cut from the positions, or a shape
    index past the shape table) is refused on reading, before export or plot index one array by another."""
    world = tumble.load_scene("bouncing_ball")
    recorder = Recorder(world, fps=60)
    world.run(0.05, callback=recorder)
    path = recorder.save(tmp_path / "rec.npz")
    assert load_recording(path)["position"].shape[1] == world.body_count
    cut = dict(np.load(path))
    cut["position"] = cut["position"][:, :1]
    np.savez(tmp_path / "cut.npz", **cut)
    with pytest.raises(
        RecordingError, match=r"array 'orientation' has shape .* as 'position' has\): the file is damaged"
    ):
        load_recording(tmp_path / "cut.npz")
    odd = dict(np.load(path))
    odd["shape"] = np.full_like(odd["shape"], 57)
    np.savez(tmp_path / "odd.npz", **odd)
    with pytest.raises(RecordingError, match="'shape' holds 57, which names no shape"):
        load_recording(tmp_path / "odd.npz")


@pytest.mark.parametrize("removed", [1, 2], ids=["a middle id", "the highest id"])
def test_a_body_removed_during_a_recording_keeps_its_shape_and_frames(tmp_path, removed):
    """A body removed during a run is recorded as it was until then: its shape and sizes (the views
    give -1 and NaN for its id now) and its frames before, NaN after; the recording reads, plots and
    exports it. (The middle id's shape was -1, refused when read; the highest id shortens the views,
    and the recorder failed on frames longer than the last: ValueError, could not broadcast.)"""
    world = small_world()
    shapes, half = world.body_shape.copy(), world.body_half_extents.copy()
    recorder = Recorder(world, fps=FPS)
    world.run(0.25, callback=recorder)
    before = recorder.frame_count
    world.remove_body(removed)
    world.run(0.25, callback=recorder)
    path = recorder.save(tmp_path / "removed.npz")
    rec = load_recording(path)
    np.testing.assert_array_equal(rec["shape"], shapes)
    np.testing.assert_array_equal(rec["half_extents"], half)
    position = rec["position"][:, removed]
    assert np.isfinite(position[:before]).all() and np.isnan(position[before:]).all()
    assert main(["plot", str(path), "-o", str(tmp_path / "removed.png")]) == 0
    assert main(["export", str(path), "-o", str(tmp_path / "removed.usda")]) == 0


def test_a_recording_whose_removed_body_has_shape_minus_one_reads(tmp_path):
    """Recordings written before removed bodies kept their shape hold -1 there: they still read."""
    world = small_world()
    path = Recorder(world, fps=FPS).save(tmp_path / "old.npz")
    arrays = dict(np.load(path))
    arrays["shape"] = np.array([0, -1, 2], dtype=arrays["shape"].dtype)
    np.savez(path, **arrays)
    assert list(load_recording(path)["shape"]) == [0, -1, 2]


def _everything(tmp_path):
    """A recording with every optional table: cloth, a hull, a mesh, a joint and a camera."""
    world = tumble.World(dt=DT, substeps=2)
    world.add_plane()
    world.add_cloth(size=(0.5, 0.5), resolution=(3, 3), position=(0.0, 0.0, 1.0), pins="top-corners")
    cube = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.1, 0.1) for z in (-0.1, 0.1)])
    hull = world.add_convex(points=cube, position=(1.0, 0.0, 0.5), mass=1.0)
    world.add_mesh(vertices=[(0, 0, 0), (1, 0, 0), (0, 1, 0)], triangles=[(0, 1, 2)], position=(3, 0, 0))
    world.add_joint("ball", None, hull, anchor=(1.0, 0.0, 1.0))
    world.metadata["camera"] = {"position": [3.0, -3.0, 2.0], "target": [0.0, 0.0, 0.5], "fov": 30.0}
    recorder = Recorder(world, fps=FPS)
    world.run(0.125, callback=recorder)
    return recorder.save(tmp_path / "all.npz")


#: an edit -> a fragment of the message: each made `tumble export` (and some `tumble plot`) fail
#: with an internal error (exit 1: IndexError, KeyError, TypeError) instead of refusing the file
EDITS = {
    "hull_triangles": (lambda r: r["hull_triangles"] + 99, "names points outside hull row 0"),
    "mesh_point_start": (lambda r: r["mesh_point_start"][:1], "does not run from 0 up to 3"),
    "geometry": (lambda r: np.full_like(r["geometry"], 7), "names hull row 7 of 2"),
    "cloth_triangles": (lambda r: np.full_like(r["cloth_triangles"], 1000), "names particles outside the 9"),
    "joint_bodies": (lambda r: np.full_like(r["joint_bodies"], 50), "names bodies outside"),
    "joint_kind": (lambda r: np.full_like(r["joint_kind"], 9), "holds 9, which names no joint"),
    "joint_lower": (lambda r: None, "'joint_lower' is missing"),
    "camera_up": (lambda r: None, "'camera_up' is missing"),
    "camera_fov": (lambda r: np.zeros(2), "has shape (2,), expected ()"),
    "fps": (lambda r: np.zeros(0), "has shape (0,), expected ()"),
    "gravity": (lambda r: np.float64(9.81), "has shape (), expected (3,)"),
    "shape": (lambda r: r["shape"].astype(np.float64), "has type float64, expected integers"),
    "shape_names": (lambda r: np.array(["plane"]), "past the 1 shape names"),
    "camera_position": (lambda r: np.array(["x", "y", "z"]), "expected numbers"),
    "format_version": (lambda r: np.zeros(1, np.int32), "'format_version' is not an integer"),
}


@pytest.mark.parametrize("name", list(EDITS))
def test_edited_tables_are_refused_before_export_reads_them(name, tmp_path):
    """An edited or damaged recording whose joints, hulls, meshes, cloth triangles, camera or scalars
    are of the wrong type or shape, missing from their group or indexing past their table: one
    RecordingError naming the array, and `tumble export` and `plot` exit 2 (export crashed, exit 1)."""
    path = _everything(tmp_path)
    rec = dict(np.load(path))
    assert load_recording(path)  # the unedited file reads
    edit, fragment = EDITS[name]
    changed = edit(rec)
    if changed is None:
        del rec[name]
    else:
        rec[name] = changed
    np.savez(tmp_path / "edited.npz", **rec)
    with pytest.raises(RecordingError, match="the file is damaged or was edited") as info:
        load_recording(tmp_path / "edited.npz")
    assert fragment in str(info.value)
    assert main(["export", str(tmp_path / "edited.npz"), "-o", str(tmp_path / "x.usda"), "--physics"]) == 2
    assert main(["plot", str(tmp_path / "edited.npz"), "-o", str(tmp_path / "x.png")]) == 2
    assert not (tmp_path / "x.usda").exists() and not (tmp_path / "x.png").exists()
