"""USD export of capsules, convex hulls, static meshes and joints, read back with pxr."""

from __future__ import annotations

import math

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
pytest.importorskip("scipy")
from pxr import Usd, UsdGeom, UsdPhysics  # noqa: E402

import tumble  # noqa: E402
from tumble.io import usd  # noqa: E402
from tumble.io.record import Recorder, load_recording  # noqa: E402

from . import validation_errors  # noqa: E402

FRAMES = 6
ROCK = np.array([[0, 0, 0], [0.2, 0, 0], [0, 0.15, 0], [0, 0, 0.1], [0.12, 0.1, 0.08]], dtype=float)
_OPEN: list = []


def _open(path):
    stage = Usd.Stage.Open(str(path))
    assert stage is not None and list(stage.GetCompositionErrors()) == []
    _OPEN.append(stage)
    return stage


def _bowl():
    n = 7
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    v = np.stack([x.ravel(), y.ravel(), 0.2 * (x.ravel() ** 2 + y.ravel() ** 2)], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def build():
    """Capsules of two sizes, two rocks (hulls), a static bowl mesh, a static post, and joints of four kinds."""
    world = tumble.World(dt=1 / 240)
    world.add_plane()  # 0
    v, t = _bowl()
    world.add_mesh(
        vertices=v, triangles=t, position=(0, 0, 0.05), orientation=(0, 0, math.sin(0.3), math.cos(0.3))
    )  # 1
    post = world.add_box(position=(-1.0, 0, 0.5), half_extents=(0.05, 0.05, 0.5), static=True)  # 2
    q = (0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4))
    c1 = world.add_capsule(position=(-0.6, 0, 1.0), radius=0.05, half_height=0.2, orientation=q)  # 3
    c2 = world.add_capsule(position=(-0.1, 0, 1.0), radius=0.05, half_height=0.2, orientation=q)  # 4
    world.add_capsule(position=(0.5, 0.5, 0.6), radius=0.08, half_height=0.1)  # 5
    rock = world.add_convex(points=ROCK, position=(0.3, -0.3, 0.5))  # 6
    world.add_convex(points=ROCK * 0.7, position=(0.6, -0.3, 0.5))  # 7
    ball = world.add_sphere(position=(0.3, -0.3, 1.2), radius=0.05)  # 8
    world.add_joint(
        "hinge", post, c1, anchor=(-0.85, 0, 1.0), axis=(0, 1, 0), lower=-0.5, upper=1.0
    )  # to a static body
    world.add_joint("ball", c1, c2, anchor=(-0.35, 0, 1.0))
    world.add_joint("rope", None, ball, anchor_a=(0.3, -0.3, 1.6), break_force=500.0)  # to the world
    world.add_joint("distance", rock, ball, min_length=0.3, max_length=0.8)
    return world


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    world = build()
    recorder = Recorder(world, fps=30)
    while recorder.frame_count < FRAMES:
        world.step()
        recorder(world)
    path = tmp_path_factory.mktemp("shapes") / "take.npz"
    recorder.save(path)
    return load_recording(path)


@pytest.fixture(scope="module")
def world_after():
    """The world itself, for its hulls and meshes (recorded geometry is compared with these)."""
    return build()


def test_recording_holds_the_geometry_and_the_joint_model(rec, world_after):
    """The .npz keeps every hull's and mesh's points and triangles, the bodies' rows, and the joints' anchors."""
    protos = world_after.hulls.prototypes
    starts = rec["hull_point_start"]
    assert len(starts) == len(protos) + 1
    for row, proto in enumerate(protos):
        np.testing.assert_allclose(rec["hull_points"][starts[row] : starts[row + 1]], proto.vertex)
    np.testing.assert_array_equal(rec["mesh_triangles"], world_after.meshes.triangles[0])
    np.testing.assert_array_equal(rec["geometry"], world_after.body_geometry)
    assert rec["joint_kind"].tolist() == [1, 0, 4, 4]
    np.testing.assert_allclose(rec["joint_local"][2, 0], (0.3, -0.3, 1.6))  # the world's end: a world point


def test_capsules_are_capsule_prims_along_z(rec, tmp_path):
    """One UsdGeom.Capsule per distinct size (axis Z, radius, spine 2 a); instances point at the right one."""
    stage = _open(usd.export(rec, tmp_path / "c.usda"))
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies"))
    targets = [str(p) for p in inst.GetPrototypesRel().GetTargets()]
    ids = np.array(inst.GetIdsAttr().Get())
    index = np.array(inst.GetProtoIndicesAttr().Get())
    capsules = {}
    for b in (3, 4, 5):
        prim = stage.GetPrimAtPath(targets[index[list(ids).index(b)]])
        capsule = UsdGeom.Capsule(prim)
        assert prim.IsA(UsdGeom.Capsule) and capsule.GetAxisAttr().Get() == "Z"
        capsules[b] = (capsule.GetRadiusAttr().Get(), capsule.GetHeightAttr().Get(), str(prim.GetPath()))
    assert capsules[3] == capsules[4]  # same size: one prototype
    assert capsules[3][:2] == pytest.approx((0.05, 0.4)) and capsules[5][:2] == pytest.approx((0.08, 0.2))
    assert capsules[5][2] != capsules[3][2]
    # an instance's transform is the body's pose at scale 1
    k = FRAMES - 1
    m = np.array(inst.ComputeInstanceTransformsAtTime(Usd.TimeCode(k), Usd.TimeCode(k))[list(ids).index(3)])
    np.testing.assert_allclose(m[3, :3], rec["position"][k, 3], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(m[:3, :3], axis=1), 1.0, atol=2e-3)


def _world_points(stage, prim_path, time, points_local):
    cache = UsdGeom.XformCache(time)
    m = np.array(cache.GetLocalToWorldTransform(stage.GetPrimAtPath(prim_path)))
    return np.c_[points_local, np.ones(len(points_local))] @ m


def test_hulls_are_meshes_of_their_triangles_placed_at_the_bodies(rec, tmp_path):
    """Each distinct hull is a Mesh prototype of triangles; placed by its body at frame 0 its corners are the
    user's points (the hull of ROCK is all five of them), and its faces wind outward."""
    stage = _open(usd.export(rec, tmp_path / "h.usda", bodies="xforms"))
    for body, points in ((6, ROCK + (0.3, -0.3, 0.5)), (7, ROCK * 0.7 + (0.6, -0.3, 0.5))):
        geom = UsdGeom.Mesh(stage.GetPrimAtPath(f"/Root/Bodies/body_{body:06d}/geom"))
        local = np.array(geom.GetPointsAttr().Get(), dtype=np.float64)
        counts = np.array(geom.GetFaceVertexCountsAttr().Get())
        assert set(counts.tolist()) == {3}
        assert geom.GetNormalsInterpolation() == UsdGeom.Tokens.faceVarying
        world_pts = _world_points(stage, f"/Root/Bodies/body_{body:06d}/geom", 0, local)[:, :3]
        gap = np.linalg.norm(world_pts[:, None] - points[None], axis=2).min(axis=1)
        assert gap.max() < 1e-6 and len(local) == 5
        tri = local[np.array(geom.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)]
        outward = np.einsum("ij,ij->i", np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), tri.mean(axis=1))
        assert np.all(outward > 0)  # the body frame's origin is the centre of mass, inside
    # two hulls, two prototypes (one per distinct hull)
    assert stage.GetPrimAtPath("/Root/Prototypes/hull_1") and stage.GetPrimAtPath("/Root/Prototypes/hull_2")


def test_static_mesh_is_a_static_mesh_with_its_triangles(rec, tmp_path):
    """The bowl is a constant Mesh under /Root/Static with the mesh's triangles, placed by its pose; a collider with --physics."""
    stage = _open(usd.export(rec, tmp_path / "m.usda", physics=True))
    prim = stage.GetPrimAtPath("/Root/Static/mesh_0_1")
    mesh = UsdGeom.Mesh(prim)
    v, t = _bowl()
    np.testing.assert_array_equal(np.array(mesh.GetFaceVertexIndicesAttr().Get()), t.reshape(-1))
    world_pts = _world_points(stage, "/Root/Static/mesh_0_1", 0, np.array(mesh.GetPointsAttr().Get(), float))[:, :3]
    c, s = math.cos(0.6), math.sin(0.6)  # the quaternion (0, 0, sin 0.3, cos 0.3) turns 0.6 rad about z
    want = v @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + (0, 0, 0.05)
    np.testing.assert_allclose(world_pts, want, atol=1e-6)
    assert not mesh.GetPointsAttr().GetTimeSamples()
    assert prim.HasAPI(UsdPhysics.CollisionAPI) and not prim.HasAPI(UsdPhysics.RigidBodyAPI)
    assert UsdPhysics.MeshCollisionAPI(prim).GetApproximationAttr().Get() == "none"


def _joint_point(stage, joint, side, time=0):
    """World position of a joint's frame on one side (body0 / body1, or the world when it names none)."""
    rel = joint.GetBody0Rel() if side == 0 else joint.GetBody1Rel()
    local = np.array((joint.GetLocalPos0Attr() if side == 0 else joint.GetLocalPos1Attr()).Get(), dtype=float)
    targets = rel.GetTargets()
    if not targets:
        return local
    return _world_points(stage, targets[0], time, local[None])[0, :3]


@pytest.mark.parametrize("bodies", ["instancer", "xforms"])
def test_joints_are_usdphysics_joints_between_rigid_bodies(rec, tmp_path, bodies):
    """--physics: each joint is its UsdPhysics type; its two frames meet at the anchor; limits and rels are right."""
    stage = _open(usd.export(rec, tmp_path / f"j_{bodies}.usda", physics=True, bodies=bodies))
    root = "/Root/JointedBodies" if bodies == "instancer" else "/Root/Bodies"
    joints = [stage.GetPrimAtPath(f"/Root/Joints/joint_{j:04d}") for j in range(4)]
    assert joints[0].IsA(UsdPhysics.RevoluteJoint) and joints[1].IsA(UsdPhysics.SphericalJoint)
    assert joints[2].IsA(UsdPhysics.DistanceJoint) and joints[3].IsA(UsdPhysics.DistanceJoint)
    anchors = [(-0.85, 0, 1.0), (-0.35, 0, 1.0), (0.3, -0.3, 1.6), None]
    for j, prim in enumerate(joints):
        joint = UsdPhysics.Joint(prim)
        a, b = _joint_point(stage, joint, 0), _joint_point(stage, joint, 1)
        if anchors[j] is not None:
            np.testing.assert_allclose(a, anchors[j], atol=1e-5)
            if j < 2:
                np.testing.assert_allclose(b, anchors[j], atol=1e-5)  # point joints: both frames at the anchor
        for rel in (joint.GetBody0Rel(), joint.GetBody1Rel()):
            for target in rel.GetTargets():
                assert str(target).startswith(root) and stage.GetPrimAtPath(target).HasAPI(UsdPhysics.RigidBodyAPI)
    hinge = UsdPhysics.RevoluteJoint(joints[0])
    assert hinge.GetBody0Rel().GetTargets() == []  # the static post: attached to the world at the anchor
    assert [str(p) for p in hinge.GetBody1Rel().GetTargets()] == [f"{root}/body_000003"]
    assert hinge.GetAxisAttr().Get() == "X"
    assert (hinge.GetLowerLimitAttr().Get(), hinge.GetUpperLimitAttr().Get()) == pytest.approx(
        (math.degrees(-0.5), math.degrees(1.0))
    )
    # the hinge axis (the joint frame's x) is world y, seen from body1's frame at frame 0
    q = hinge.GetLocalRot1Attr().Get()
    cache = UsdGeom.XformCache(0)
    m = np.array(cache.GetLocalToWorldTransform(stage.GetPrimAtPath(f"{root}/body_000003")))[:3, :3]
    x_local = np.array(pxr.Gf.Rotation(q).TransformDir(pxr.Gf.Vec3d(1, 0, 0)))
    np.testing.assert_allclose(x_local @ m, (0, 1, 0), atol=1e-5)
    rope = UsdPhysics.DistanceJoint(joints[2])
    assert rope.GetBody0Rel().GetTargets() == [] and rope.GetBreakForceAttr().Get() == pytest.approx(500.0)
    assert rope.GetMaxDistanceAttr().Get() == pytest.approx(0.4) and not rope.GetMinDistanceAttr().HasAuthoredValue()
    limits = UsdPhysics.DistanceJoint(joints[3])
    assert (limits.GetMinDistanceAttr().Get(), limits.GetMaxDistanceAttr().Get()) == pytest.approx((0.3, 0.8))
    assert not UsdPhysics.Joint(joints[1]).GetCollisionEnabledAttr().Get()
    if bodies == "instancer":
        # the jointed bodies left the instancer; the others (capsule 5, rock 7) are still instances
        ids = set(UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies")).GetIdsAttr().Get())
        assert ids == {5, 7}


def test_without_physics_no_joints_and_every_body_is_an_instance(rec, tmp_path):
    """Joints are written only with --physics; then every moving body stays in the instancer."""
    stage = _open(usd.export(rec, tmp_path / "plain.usda"))
    assert not stage.GetPrimAtPath("/Root/Joints") and not stage.GetPrimAtPath("/Root/JointedBodies")
    ids = set(UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies")).GetIdsAttr().Get())
    assert ids == {3, 4, 5, 6, 7, 8}


def test_physics_densities_of_capsule_and_hull_prototypes(rec, tmp_path):
    """--physics: a capsule's and a hull's prototype density is mass / volume, the default 1000 kg/m^3 here."""
    stage = _open(usd.export(rec, tmp_path / "d.usda", physics=True))
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Bodies"))
    targets = inst.GetPrototypesRel().GetTargets()
    ids = list(inst.GetIdsAttr().Get())
    index = inst.GetProtoIndicesAttr().Get()
    for body in (5, 7):  # the capsule and the rock no joint names
        prim = stage.GetPrimAtPath(targets[index[ids.index(body)]])
        assert prim.HasAPI(UsdPhysics.RigidBodyAPI) and prim.HasAPI(UsdPhysics.CollisionAPI)
        assert UsdPhysics.MassAPI(prim).GetDensityAttr().Get() == pytest.approx(1000.0, rel=1e-6)


@pytest.mark.parametrize("bodies", ["instancer", "xforms"])
def test_usd_validators_pass_the_shapes_and_joints(rec, tmp_path, bodies):
    """USD's own validators (UsdPhysics' joint, collider and rigid-body rules among them) pass the
    capsules, hulls, mesh and joints; and they are live: a joint pointed at no prim is reported."""
    path = usd.export(rec, tmp_path / "shapes.usda", bodies=bodies, physics=True)
    assert validation_errors(path) == []
    stage = Usd.Stage.Open(str(path))
    joint = next(p for p in stage.Traverse() if p.IsA(UsdPhysics.Joint))
    UsdPhysics.Joint(joint).GetBody0Rel().SetTargets(["/Root/Nowhere"])
    stage.GetRootLayer().Export(str(tmp_path / "broken.usda"))
    assert [e.split(":")[0] for e in validation_errors(tmp_path / "broken.usda")] == ["JointInvalidPrimRel"]
