"""USD export (tumble.io.usd): every stage is read back with pxr and compared with the recording."""

from __future__ import annotations

import os
import resource
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdPhysics

import tumble
from tumble.errors import TumbleError
from tumble.io import usd
from tumble.limits import LimitError
from tumble.npmath import quat_to_matrix

from . import open_stage, record_scene, validation_errors

FPS = 30.0
FRAMES = 16  # 0.5 s

# planes, a static pole, two spheres, a spinning box, an emitter releasing spheres and boxes
# after the start, a small pinned cloth, and a camera
SCENE = """
[world]
dt = 0.004166666666666667

[[plane]]
normal = [0, 0, 1]

[[plane]]
normal = [1, 0, 0]
offset = -1.5

[[box]]
position = [-0.8, 0, 0.6]
half_extents = [0.02, 0.02, 0.6]
static = true

[[sphere]]
position = [0.3, 0, 0.4]
radius = 0.1
mass = 1.0

[[sphere]]
position = [0.6, 0.1, 0.9]
radius = 0.07
mass = 0.5
restitution = 0.8

[[box]]
position = [-0.3, 0.3, 0.5]
half_extents = [0.1, 0.05, 0.08]
mass = 1.0
angular_velocity = [1, 3, 2]

[[emitter]]
shape = ["sphere", "box"]
rate = 20
count = 5
position = [0, -0.4, 1.2]
region = "box"
extent = [0.3, 0.1, 0.05]
radius = 0.04
half_extents = 0.03
mass = 0.1
seed = 2

[[cloth]]
size = [0.6, 0.4]
resolution = [6, 4]
position = [0, 0.5, 1.0]
mass = 0.1
pins = "top-corners"

[camera]
position = [2.0, -3.0, 1.5]
target = [0, 0, 0.4]
fov = 40
"""


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """The scene recorded for FRAMES frames at FPS, as load_recording returns it."""
    return record_scene(tmp_path_factory.mktemp("usd") / "scene.toml", SCENE, FRAMES, FPS)


@pytest.fixture(scope="module")
def stage_path(recording, tmp_path_factory):
    return usd.export(recording, tmp_path_factory.mktemp("out") / "take.usdc")


def _moving(rec):
    names = rec["shape_names"][rec["shape"]]
    return np.flatnonzero((names != "plane") & (rec["mass"] > 0))


def test_stage_metadata_and_time_codes(stage_path):
    """Write Z up, metres, the fps as time codes per second, frames 0..F-1, and /Root as default prim."""
    stage = open_stage(stage_path)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == FPS
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, FRAMES - 1)
    assert stage.GetDefaultPrim().GetPath() == "/Root"
    assert stage.GetDefaultPrim().IsA(UsdGeom.Xform)
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies"))
    assert inst.GetPositionsAttr().GetTimeSamples() == list(range(FRAMES))
    assert inst.GetOrientationsAttr().GetTimeSamples() == list(range(FRAMES))


def test_stage_opens_without_composition_errors(stage_path):
    """Open the stage with no composition errors, every prim valid and defined."""
    stage = open_stage(stage_path)
    assert list(stage.GetCompositionErrors()) == []
    prims = list(stage.Traverse())
    assert len(prims) > 5 and all(p.IsValid() and p.IsDefined() for p in prims)


def test_positions_and_orientations_equal_the_recording(recording, stage_path):
    """At every frame each released body's position is the recording's in float32, its orientation in half."""
    rec = recording
    moving = _moving(rec)
    inst = UsdGeom.PointInstancer(open_stage(stage_path).GetPrimAtPath("/Root/Bodies"))
    ids = np.array(inst.GetIdsAttr().Get())
    np.testing.assert_array_equal(ids, moving)
    for k in range(FRAMES):
        pos = np.array(inst.GetPositionsAttr().Get(k))
        quat = np.array([(*q.GetImaginary(), q.GetReal()) for q in inst.GetOrientationsAttr().Get(k)])
        want_p = rec["position"][k, moving]
        want_q = rec["orientation"][k, moving]
        seen = np.isfinite(want_p).all(axis=1)
        np.testing.assert_array_equal(pos[seen], want_p[seen].astype(np.float32))
        np.testing.assert_array_equal(quat[seen], want_q[seen].astype(np.float16).astype(np.float64))


def test_instance_transforms_match_the_bodies(recording, stage_path):
    """pxr's own instance transforms are the bodies' rotation matrices times their sizes, at their positions."""
    rec = recording
    moving = _moving(rec)
    inst = UsdGeom.PointInstancer(open_stage(stage_path).GetPrimAtPath("/Root/Bodies"))
    k = FRAMES - 1
    xforms = inst.ComputeInstanceTransformsAtTime(Usd.TimeCode(k), Usd.TimeCode(k))
    m = np.array([np.array(x) for x in xforms])  # row-vector convention: rows are the local axes
    names = rec["shape_names"][rec["shape"][moving]]
    size = np.where((names == "sphere")[:, None], rec["radius"][moving, None], rec["half_extents"][moving])
    rot = quat_to_matrix(rec["orientation"][k, moving])  # world.py's column-vector rotation
    # half-precision quaternions: entries of the rotation good to ~2 * 2^-11
    np.testing.assert_allclose(m[:, :3, :3], np.transpose(rot, (0, 2, 1)) * size[:, :, None], atol=2e-3 * 0.1)
    np.testing.assert_allclose(m[:, 3, :3], rec["position"][k, moving], atol=1e-6)


def test_emitted_bodies_appear_at_their_birth_frame(recording, stage_path):
    """A body not yet released is in invisibleIds (and scaled to zero) until the frame it first exists."""
    rec = recording
    moving = _moving(rec)
    exists = np.isfinite(rec["position"][:, moving, 0])
    birth = exists.argmax(axis=0)
    assert (birth > 0).sum() >= 3, "the scene should release bodies after the first frame"
    inst = UsdGeom.PointInstancer(open_stage(stage_path).GetPrimAtPath("/Root/Bodies"))
    for k in range(FRAMES):
        hidden = set(np.array(inst.GetInvisibleIdsAttr().Get(k), dtype=np.int64).tolist())
        assert hidden == set(moving[~exists[k]].tolist()), k
        scales = np.array(inst.GetScalesAttr().Get(k))
        np.testing.assert_array_equal(scales[~exists[k]], 0.0)
        assert np.all(scales[exists[k]] > 0)
    for body, b in zip(moving, birth):
        if b > 0:
            assert body in set(np.array(inst.GetInvisibleIdsAttr().Get(int(b) - 1)).tolist())
            assert body not in set(np.array(inst.GetInvisibleIdsAttr().Get(int(b))).tolist())


def test_cloth_points_and_topology(recording, stage_path):
    """The cloth is one double-sided mesh: the recorded triangles, points in float32 at every frame, unit normals."""
    rec = recording
    mesh = UsdGeom.Mesh(open_stage(stage_path).GetPrimAtPath("/Root/Cloth"))
    assert mesh.GetDoubleSidedAttr().Get() is True
    tri = rec["cloth_triangles"]
    np.testing.assert_array_equal(np.array(mesh.GetFaceVertexCountsAttr().Get()), np.full(len(tri), 3))
    np.testing.assert_array_equal(np.array(mesh.GetFaceVertexIndicesAttr().Get()), tri.reshape(-1))
    assert mesh.GetPointsAttr().GetTimeSamples() == list(range(FRAMES))
    moved = 0.0
    for k in range(FRAMES):
        pts = np.array(mesh.GetPointsAttr().Get(k))
        np.testing.assert_array_equal(pts, rec["cloth_position"][k].astype(np.float32))
        normals = np.array(mesh.GetNormalsAttr().Get(k))
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
        moved = max(moved, float(np.abs(pts - rec["cloth_position"][0]).max()))
    assert moved > 0.01, "the cloth should move in the take"


def test_static_geometry_colors_and_camera(recording, stage_path):
    """Planes become quads around the action, the static pole a box mesh, colours are the viewer's, the camera the scene's."""
    from tumble.render.colors import body_colors

    def linear(c):  # USD colours are linear; the palette is sRGB (IEC 61966-2-1)
        c = np.asarray(c, dtype=np.float64)
        return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)

    stage = open_stage(stage_path)
    rec = recording
    ground = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/Static/plane_0"))
    wall = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/Static/plane_1"))
    for plane, normal, offset in ((ground, (0, 0, 1), 0.0), (wall, (1, 0, 0), -1.5)):
        m = np.array(plane.ComputeLocalToWorldTransform(0))
        corners = np.c_[np.array(plane.GetPointsAttr().Get()), np.ones(4)] @ m
        np.testing.assert_allclose(corners[:, :3] @ np.array(normal, float), offset, atol=1e-6)
        assert np.ptp(corners[:, :3], axis=0).max() > 2.0  # wider than the action
    pole_index = int(np.flatnonzero((rec["shape_names"][rec["shape"]] == "box") & (rec["mass"] == 0))[0])
    pole = UsdGeom.Mesh(stage.GetPrimAtPath(f"/Root/Static/box_{pole_index}"))
    bound = pole.ComputeWorldBound(0, UsdGeom.Tokens.default_).ComputeAlignedRange()
    np.testing.assert_allclose(np.array(bound.GetMin()), (-0.82, -0.02, 0.0), atol=1e-6)
    np.testing.assert_allclose(np.array(bound.GetMax()), (-0.78, 0.02, 1.2), atol=1e-6)
    np.testing.assert_allclose(
        np.array(pole.GetDisplayColorAttr().Get()[0]), linear(body_colors([pole_index])[0]), rtol=1e-6
    )
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies"))
    colors = UsdGeom.PrimvarsAPI(inst.GetPrim()).GetPrimvar("displayColor")
    assert colors.GetInterpolation() == UsdGeom.Tokens.vertex
    np.testing.assert_allclose(np.array(colors.Get()), linear(body_colors(_moving(rec))), rtol=1e-6)

    cam = UsdGeom.Camera(stage.GetPrimAtPath("/Root/Camera")).GetCamera(0)
    m = np.array(cam.transform)
    np.testing.assert_allclose(m[3, :3], (2.0, -3.0, 1.5), atol=1e-9)
    look = -m[2, :3]  # the camera looks down its -z
    want = np.array([-2.0, 3.0, -1.1]) / np.linalg.norm([-2.0, 3.0, -1.1])
    np.testing.assert_allclose(look, want, atol=1e-9)
    assert cam.GetFieldOfView(Gf.Camera.FOVVertical) == pytest.approx(40.0, abs=1e-4)


def test_xforms_mode_animates_one_xform_per_body(recording, tmp_path):
    """--bodies xforms: each body's world transform sits at its recorded position and is invisible before release."""
    rec = recording
    path = usd.export(rec, tmp_path / "xf.usda", bodies="xforms")
    stage = open_stage(path)
    assert list(stage.GetCompositionErrors()) == []
    moving = _moving(rec)
    cache = UsdGeom.XformCache()
    for k in (0, FRAMES // 2, FRAMES - 1):
        cache.SetTime(k)
        for b in moving:
            prim = stage.GetPrimAtPath(f"/Root/Bodies/body_{b:06d}")
            visible = UsdGeom.Imageable(prim).ComputeVisibility(k) != UsdGeom.Tokens.invisible
            exists = bool(np.isfinite(rec["position"][k, b]).all())
            assert visible == exists
            if exists:
                m = np.array(cache.GetLocalToWorldTransform(prim))
                np.testing.assert_allclose(m[3, :3], rec["position"][k, b], atol=1e-12)
                rot = quat_to_matrix(rec["orientation"][k, b][None])[0]
                scale = np.linalg.norm(m[:3, :3], axis=1)
                np.testing.assert_allclose(m[:3, :3] / scale[:, None], rot.T, atol=1e-6)
        geom = UsdGeom.Mesh(stage.GetPrimAtPath(f"/Root/Bodies/body_{moving[0]:06d}/geom"))
        assert len(geom.GetPointsAttr().Get()) > 100  # the sphere prototype, through its reference


@pytest.mark.parametrize(
    "suffix, magic", [(".usd", b"PXR-USDC"), (".usdc", b"PXR-USDC"), (".usda", b"#usda"), (".usdz", b"PK")]
)
def test_every_extension_writes_its_format(recording, tmp_path, suffix, magic):
    """.usd/.usdc write binary crate, .usda text, .usdz a package (its layer named after it, not after a
    temporary file); each opens with all frames and no temp file left."""
    path = usd.export(recording, tmp_path / f"shot{suffix}")
    assert path.read_bytes()[: len(magic)] == magic
    if suffix == ".usdz":
        assert zipfile.ZipFile(path).namelist() == ["shot.usdc"]
    stage = open_stage(path)
    assert stage.GetEndTimeCode() == FRAMES - 1
    assert sorted(os.listdir(tmp_path)) == [path.name]


def test_physics_schemas(recording, tmp_path):
    """physics=True: a PhysicsScene with the gravity, static colliders, rigid prototypes with density and materials."""
    stage = open_stage(usd.export(recording, tmp_path / "phys.usda", physics=True))
    scene = UsdPhysics.Scene(stage.GetPrimAtPath("/Root/PhysicsScene"))
    assert scene.GetGravityMagnitudeAttr().Get() == pytest.approx(9.81)
    np.testing.assert_allclose(np.array(scene.GetGravityDirectionAttr().Get()), (0, 0, -1))
    ground = stage.GetPrimAtPath("/Root/Static/plane_0")
    assert ground.HasAPI(UsdPhysics.CollisionAPI) and not ground.HasAPI(UsdPhysics.RigidBodyAPI)
    sphere = stage.GetPrimAtPath("/Root/Bodies/Prototypes/sphere")
    assert sphere.HasAPI(UsdPhysics.RigidBodyAPI) and sphere.HasAPI(UsdPhysics.CollisionAPI)
    # one density per prototype: the median of m / (4/3 pi r^3) over the spheres
    spheres = np.flatnonzero((recording["shape_names"][recording["shape"]] == "sphere") & (recording["mass"] > 0))
    want = np.median(recording["mass"][spheres] / (4 / 3 * np.pi * recording["radius"][spheres] ** 3))
    assert UsdPhysics.MassAPI(sphere).GetDensityAttr().Get() == pytest.approx(want, rel=1e-6)
    restitutions = sorted(
        UsdPhysics.MaterialAPI(p).GetRestitutionAttr().Get()
        for p in stage.Traverse()
        if p.HasAPI(UsdPhysics.MaterialAPI)
    )
    assert restitutions == [0.5]  # the spheres' prototype binds the first sphere's; 0.8 is per body in xforms
    stage = open_stage(usd.export(recording, tmp_path / "phys_xf.usda", physics=True, bodies="xforms"))
    light = int(np.flatnonzero(recording["mass"] == 0.5)[0])
    body = stage.GetPrimAtPath(f"/Root/Bodies/body_{light:06d}")
    assert UsdPhysics.MassAPI(body).GetMassAttr().Get() == pytest.approx(0.5)
    restitutions = sorted(
        UsdPhysics.MaterialAPI(p).GetRestitutionAttr().Get()
        for p in stage.Traverse()
        if p.HasAPI(UsdPhysics.MaterialAPI)
    )
    assert restitutions == pytest.approx([0.5, 0.8])


@pytest.mark.parametrize("suffix", [".usdc", ".usdz"])
@pytest.mark.parametrize("bodies", ["instancer", "xforms"])
def test_usd_validators_find_nothing_wrong(recording, tmp_path, bodies, suffix):
    """Every validator USD registers passes the stage (bodies either way, with the physics schemas;
    the package rules too for .usdz): what Blender, Houdini and Omniverse read is well-formed USD."""
    path = usd.export(recording, tmp_path / f"take{suffix}", bodies=bodies, physics=True)
    assert validation_errors(path) == []


def test_lower_fps_takes_every_other_frame(recording, tmp_path):
    """fps 15 from a 30 fps recording writes frames 0, 2, 4, ... with 15 time codes per second."""
    stage = open_stage(usd.export(recording, tmp_path / "half.usdc", fps=15))
    assert stage.GetTimeCodesPerSecond() == 15
    assert stage.GetEndTimeCode() == (FRAMES - 1) // 2
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/Cloth"))
    np.testing.assert_array_equal(
        np.array(mesh.GetPointsAttr().Get(3)), recording["cloth_position"][6].astype(np.float32)
    )
    with pytest.raises(tumble.errors.TumbleError, match="more than the recording"):
        usd.export(recording, tmp_path / "fast.usdc", fps=60)
    with pytest.raises(tumble.errors.TumbleError, match="the recording holds"):
        usd.export(recording, tmp_path / "long.usdc", duration=5.0)
    assert not list(tmp_path.glob("fast*")) and not list(tmp_path.glob("long*"))


def test_version_1_recording_still_exports(recording, tmp_path):
    """A recording from format version 1 (no materials, no camera) exports all the same."""
    old = {k: v for k, v in recording.items() if k not in ("restitution", "friction") and not k.startswith("camera")}
    old["format_version"] = np.int32(1)
    np.savez_compressed(tmp_path / "old.npz", **old)
    stage = open_stage(usd.export(tmp_path / "old.npz", tmp_path / "old.usdc", physics=True))
    assert not stage.GetPrimAtPath("/Root/Camera")
    assert stage.GetEndTimeCode() == FRAMES - 1


def test_failed_write_leaves_the_old_file_and_no_temp(recording, tmp_path, monkeypatch):
    """An error at the last moment (the rename over the target, after the stage was written to its
    temporary file) leaves an existing target untouched and no temporary file beside it."""
    target = tmp_path / "keep.usda"
    target.write_text("old", encoding="utf-8")

    def broken(src, dst):
        assert Path(src).parent == tmp_path and Path(src).stat().st_size > 0  # the whole stage, beside it
        raise OSError("boom")

    monkeypatch.setattr(os, "replace", broken)
    with pytest.raises(OSError, match="boom"):
        usd.export(recording, target)
    assert target.read_text(encoding="utf-8") == "old"
    assert os.listdir(tmp_path) == ["keep.usda"]


@pytest.mark.parametrize("suffix", [".usdc", ".usdz"])
def test_a_full_disk_is_named_as_such(recording, tmp_path, monkeypatch, suffix):
    """pxr reports a write cut short by a full disk as a corrupt asset ("exception thrown unpacking
    a value", with a tab in it): the error says the device is full, the old file is kept, and no
    temporary file is left. (The write is cut short by a 4 kB file-size limit on this process,
    which Python turns into EFBIG, and the disk is made to report no free space.)"""
    target = tmp_path / f"keep{suffix}"
    target.write_bytes(b"old")
    free = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(usd.shutil, "disk_usage", lambda folder: free._replace(free=0))
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, hard))
    try:
        with pytest.raises(TumbleError) as error:
            usd.export(recording, target)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert str(error.value) == f"cannot write {str(target)!r}: no space left on the device"
    assert target.read_bytes() == b"old"
    assert os.listdir(tmp_path) == [target.name]


@pytest.mark.parametrize("suffix", [".usda", ".usdz"])
def test_an_export_over_a_file_keeps_its_permissions(recording, tmp_path, suffix):
    """Exporting over an existing file replaces it with the permissions it had (0o640 here), as every
    other output does (`tumble.io.atomic`); before, the new file always got 0o644 less the umask."""
    target = tmp_path / f"shot{suffix}"
    target.write_bytes(b"old")
    os.chmod(target, 0o640)
    usd.export(recording, target)
    assert open_stage(target).GetEndTimeCode() == FRAMES - 1
    assert target.stat().st_mode & 0o777 == 0o640
    assert os.listdir(tmp_path) == [target.name]


def test_world_export_simulates_the_frames(tmp_path):
    """Exporting a World steps it: frames = duration * fps + 1, the last at the world's end time."""
    world = tumble.World(dt=1 / 240)
    world.add_plane()
    world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    stage = open_stage(usd.export(world, tmp_path / "drop.usdc", duration=0.25, fps=20))
    assert stage.GetEndTimeCode() == 5
    assert world.time == pytest.approx(0.25, abs=0.5 / 240)
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies"))
    assert np.array(inst.GetPositionsAttr().Get(5))[0, 2] == np.float32(world.body_position[1, 2])


def test_world_export_defaults_to_a_frame_a_step_when_the_world_steps_slower_than_60_fps(tmp_path):
    """dt = 0.05 s (20 steps a second): the default export rate is 20 fps, not a refusal of the
    default 60; an explicit rate above the step rate is still refused."""
    world = tumble.World(dt=0.05)
    world.add_plane()
    world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    stage = open_stage(usd.export(world, tmp_path / "slow.usdc", duration=1.0))
    assert stage.GetTimeCodesPerSecond() == 20.0 and stage.GetEndTimeCode() == 20
    with pytest.raises(TumbleError, match="fps 60 is more than the world's 20 steps per second"):
        usd.export(tumble.World(dt=0.05), tmp_path / "fast.usdc", duration=1.0, fps=60)


def test_an_existing_directory_is_refused_as_the_output(recording, tmp_path):
    """-o shot.usda naming a folder was found only at the final rename, after simulating and
    authoring, and named the temporary file ('.shot.x1y2.usda: Is a directory'); check_output
    refuses it first now, naming the output, and the folder is left as it was."""
    folder = tmp_path / "shot.usda"
    folder.mkdir()
    with pytest.raises(TumbleError, match=r"cannot write '.*shot\.usda': is a directory, not a file"):
        usd.export(recording, folder)
    assert os.listdir(tmp_path) == ["shot.usda"] and os.listdir(folder) == []


def test_too_many_frames_are_refused_before_anything_runs(recording, tmp_path, monkeypatch):
    """A world export past 10^9 steps or the memory of its frames raises LimitError naming the option
    before a step is taken (--frames 99999999999 simulated until killed); a recording asked for far
    more frames than it holds is refused before the frame times are made (no 800 GB array)."""
    world = tumble.World(dt=1 / 240)
    world.add_sphere(position=(0, 0, 1), radius=0.1, mass=1.0)
    with pytest.raises(LimitError, match=r"frames 99,999,999,999 at 60 fps: .* steps; the limit is 1,000,000,000"):
        usd.export(world, tmp_path / "long.usda", frames=99_999_999_999)
    with pytest.raises(LimitError, match=r"^duration: 1e\+300 s"):
        usd.export(world, tmp_path / "long.usda", duration=1e300)
    monkeypatch.setenv("TUMBLE_MEMORY", "1G")
    with pytest.raises(LimitError, match=r"frames 100,000,000 at 240 fps: 100,000,000 frames need about 25\.6 GB"):
        usd.export(world, tmp_path / "long.usda", frames=10**8, fps=240)  # 4e5 s: 10^8 steps, within the limit
    assert world.step_count == 0 and list(tmp_path.iterdir()) == []
    with pytest.raises(TumbleError, match=r"the recording holds .*; 100,000,000,000 frames"):
        usd.export(recording, tmp_path / "long.usda", frames=10**11)


def test_a_kinematic_body_turning_in_place_is_animated(tmp_path):
    """A kinematic fan that turns about its own centre moves no point of its centre: it was written
    as static geometry, its turning lost (found by an outside audit). It is an animated instance
    whose orientation at the last frame is the world's."""
    world = tumble.World()
    world.add_plane()
    fan = world.add_box(
        position=(0, 0, 0.5), half_extents=(0.5, 0.05, 0.05), kinematic=True, angular_velocity=(0, 0, 2)
    )
    stage = open_stage(usd.export(world, tmp_path / "fan.usda", duration=1.0, fps=30))
    assert not stage.GetPrimAtPath("/Root/Static/box_1").IsValid()
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies"))
    xyzw = [
        [q.GetImaginary()[0], q.GetImaginary()[1], q.GetImaginary()[2], q.GetReal()]
        for q in inst.GetOrientationsAttr().Get(30)
    ]
    np.testing.assert_allclose(np.abs(np.dot(xyzw[0], world.body_orientation[fan])), 1.0, atol=1e-3)  # half floats
    assert abs(world.body_orientation[fan][2]) > 0.8  # it turned 2 rad about z


@pytest.mark.parametrize("with_mesh", [False, True])
def test_a_world_with_a_removed_body_exports_the_others(tmp_path, with_mesh):
    """A removed body's row (shape -1, no state) is left out: it was taken for the last shape name,
    "mesh", and the export refused the world as an old recording or failed inside NumPy."""
    world = tumble.World()
    world.add_plane()
    if with_mesh:
        world.add_mesh(vertices=[[3, 0, 0], [4, 0, 0], [3, 1, 0]], triangles=[[0, 1, 2]])
    gone = world.add_sphere(position=(0, 0, 1), radius=0.1)
    kept = world.add_sphere(position=(1, 0, 1), radius=0.1)
    world.remove_body(gone)
    stage = open_stage(usd.export(world, tmp_path / "r.usda", frames=3))
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies"))
    positions = np.array(inst.GetPositionsAttr().Get(2))
    assert len(positions) == 1
    np.testing.assert_allclose(positions[0], world.body_position[kept], atol=1e-6)


def test_a_dict_that_is_not_a_recording_is_refused_by_name(tmp_path):
    """A hand-made dict missing a recording's arrays gets a TumbleError naming them (a bare KeyError before)."""
    with pytest.raises(TumbleError, match="the recording given has no time, fps, orientation"):
        usd.export({"position": np.zeros((1, 1, 3))}, tmp_path / "x.usda")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("scale", [1.0, 1.0 + 1e-5])
def test_small_rotations_survive_the_orient_ops(recording, tmp_path, scale):
    """A body or static prim turned by a few mrad keeps that turn in pxr's (and Blender's) transform.
    The orient ops were float quaternions, and pxr takes an orient op's angle from acos of the real
    part: 1e-4 rad came out as no turn, 2e-3 rad as 1.95e-3; a quaternion 1e-5 too long (as a pebble
    of the pebbles sample had just after release) lost 2e-3 rad altogether, in any precision."""
    rec = dict(recording)
    moving = _moving(rec)
    pole = int(np.flatnonzero((rec["shape_names"][rec["shape"]] == "box") & (rec["mass"] == 0))[0])
    body = int(moving[0])
    angles = {body: 2e-3, pole: 1e-4}
    orientation = rec["orientation"].copy()
    for b, a in angles.items():
        orientation[:, b] = scale * np.array([np.sin(a / 2), 0.0, 0.0, np.cos(a / 2)])
    rec["orientation"] = orientation
    stage = open_stage(usd.export(rec, tmp_path / "turn.usda", bodies="xforms"))
    cache = UsdGeom.XformCache(Usd.TimeCode(FRAMES - 1))
    for b, path in ((body, f"/Root/Bodies/body_{body:06d}"), (pole, f"/Root/Static/box_{pole}")):
        m = np.array(cache.GetLocalToWorldTransform(stage.GetPrimAtPath(path)))
        m = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=1)[:, None]  # rows: the rotated axes
        assert np.arctan2(m[1, 2], m[1, 1]) == pytest.approx(angles[b], rel=1e-6), path


def test_xforms_mode_scales_bodies_to_nothing_before_release(recording, tmp_path):
    """--bodies xforms: a body not released yet is drawn nowhere, also by a tool that ignores
    `visibility`. Blender 5.0.1 imports neither an Xform's nor a Mesh's animated visibility, so
    it drew every emitted pebble of the pebbles sample at its release point from frame 0; the
    geom's scale is 0 until the release now, as the instancer's scales are, and the body's size after."""
    rec = recording
    moving = _moving(rec)
    exists = np.isfinite(rec["position"][:, moving, 0])
    stage = open_stage(usd.export(rec, tmp_path / "xf.usdc", bodies="xforms"))
    cache = UsdGeom.XformCache()
    later = 0
    for k in range(FRAMES):
        cache.SetTime(k)
        for b, there in zip(moving, exists[k]):
            geom = stage.GetPrimAtPath(f"/Root/Bodies/body_{b:06d}/geom")
            size = np.linalg.norm(np.array(cache.GetLocalToWorldTransform(geom))[:3, :3], axis=1)
            if there:
                want = rec["radius"][b] if rec["shape_names"][rec["shape"][b]] == "sphere" else rec["half_extents"][b]
                np.testing.assert_allclose(size, np.broadcast_to(want, 3), rtol=1e-6)
            else:
                np.testing.assert_array_equal(size, 0.0)
                later += 1
    assert later >= 3
