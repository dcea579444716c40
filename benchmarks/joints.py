"""Joint benchmarks: a 1,000-link chain and 100 ragdolls in Tumble, PyBullet, MuJoCo and Rapier.

Every engine builds the same bodies and ball joints (spherical joints, point-to-point
constraints, MuJoCo's `connect` equalities), steps at dt = 1/240 s on one core, and reports
steps/s and the joint drift: the largest distance between the two anchors of a joint, taken
every 0.1 s of simulated time (`max drift`) and at the end (`end drift`). Jointed pairs do not
collide in any engine; every other pair does.

Scenes (z up, SI units):
* `chain_1k`: 1,000 spheres (r 8 mm, 10 g) 2 cm apart in a horizontal line, joined by ball
  joints midway, the first one to the world: released, the 20 m chain swings down (violent).
* `chain_1k_rest`: the same chain hanging straight down, released at rest: its drift is the
  joints' stretch under the chain's weight (10 g x 1,000 on the top joint).
* `ragdoll_100`: 100 ragdolls of 10 bodies (a torso box, a head sphere, two-part arms and legs
  of boxes) joined by 9 ball joints each, on a 10 x 10 grid 1 m apart, dropped from 0.5 m onto
  a ground plane (friction 0.5).

Usage: `python benchmarks/run.py --scenes joints` (or `python benchmarks/joints.py`), with
`--duration S` (default 1 s of simulated time) and `--engines`.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parent))
    if (HERE.parent / "src" / "tumble").is_dir():
        sys.path.insert(0, str(HERE.parent / "src"))

DT = 1.0 / 240.0
GRAVITY = (0.0, 0.0, -9.81)
FRICTION = 0.5
SAMPLE_EVERY = 0.1  # [s] of simulated time between drift samples
DURATION = 1.0  # [s] simulated per scene and engine


@dataclass
class JointScene:
    """Bodies (boxes and spheres, identity orientation at the start) and ball joints (a = -1: the world)."""

    name: str
    shape: list = field(default_factory=list)  # "sphere" or "box"
    size: list = field(default_factory=list)  # radius, or half extents (3,)
    position: list = field(default_factory=list)
    mass: list = field(default_factory=list)
    joints: list = field(default_factory=list)  # (a, b, world anchor (3,))
    ground: bool = False

    def add(self, shape: str, size, position, mass: float) -> int:
        self.shape.append(shape)
        self.size.append(size)
        self.position.append(np.asarray(position, dtype=float))
        self.mass.append(float(mass))
        return len(self.shape) - 1

    def local_anchors(self) -> tuple[np.ndarray, np.ndarray]:
        """Anchors in each body's frame (the bodies start unrotated); the world's anchor is the world point."""
        x = np.vstack([np.array(self.position), np.zeros((1, 3))])
        a = np.array([j[0] for j in self.joints])
        b = np.array([j[1] for j in self.joints])
        p = np.array([j[2] for j in self.joints])
        return p - x[a], p - x[b]


def chain_scene(n: int = 1000) -> JointScene:
    s = JointScene("chain_1k")
    for i in range(n):
        s.add("sphere", 0.008, (0.02 * i, 0.0, 0.0), 0.01)
    s.joints.append((-1, 0, np.array([-0.01, 0.0, 0.0])))
    for i in range(1, n):
        s.joints.append((i - 1, i, np.array([0.02 * i - 0.01, 0.0, 0.0])))
    return s


def hanging_chain_scene(n: int = 1000) -> JointScene:
    """The chain of `chain_scene` hanging straight down from its world joint, released at rest."""
    s = JointScene("chain_1k_rest")
    for i in range(n):
        s.add("sphere", 0.008, (0.0, 0.0, -0.02 * i), 0.01)
    s.joints.append((-1, 0, np.array([0.0, 0.0, 0.01])))
    for i in range(1, n):
        s.joints.append((i - 1, i, np.array([0.0, 0.0, 0.01 - 0.02 * i])))
    return s


def ragdoll_scene(n: int = 100) -> JointScene:
    s = JointScene("ragdoll_100", ground=True)
    side = math.ceil(math.sqrt(n))
    for k in range(n):
        o = np.array([(k % side) * 1.0, (k // side) * 1.0, 0.5])
        torso = s.add("box", (0.1, 0.13, 0.25), o + (0, 0, 0.85), 30.0)
        head = s.add("sphere", 0.1, o + (0, 0, 1.21), 5.0)
        s.joints.append((torso, head, o + (0, 0, 1.105)))
        for side_y in (0.19, -0.19):
            upper = s.add("box", (0.045, 0.045, 0.14), o + (0, side_y, 0.91), 2.5)
            lower = s.add("box", (0.04, 0.04, 0.14), o + (0, side_y, 0.63), 1.5)
            s.joints.append((torso, upper, o + (0, side_y, 1.05)))
            s.joints.append((upper, lower, o + (0, side_y, 0.77)))
        for side_y in (0.075, -0.075):
            thigh = s.add("box", (0.065, 0.065, 0.2), o + (0, side_y, 0.4), 8.0)
            shin = s.add("box", (0.055, 0.055, 0.2), o + (0, side_y, 0.0), 4.0)
            s.joints.append((torso, thigh, o + (0, side_y, 0.6)))
            s.joints.append((thigh, shin, o + (0, side_y, 0.2)))
    # lift everything so that the shins' feet are 0.5 m up
    s.position = [p + (0, 0, 0.2) for p in s.position]
    s.joints = [(a, b, p + (0, 0, 0.2)) for a, b, p in s.joints]
    return s


SCENES = {"chain_1k": chain_scene, "chain_1k_rest": hanging_chain_scene, "ragdoll_100": ragdoll_scene}


def drift(scene: JointScene, x: np.ndarray, q: np.ndarray) -> float:
    """Largest anchor separation [m] of the scene's joints, for positions x (n, 3), quaternions q (n, 4) xyzw."""
    la, lb = scene.local_anchors()
    x = np.vstack([x, np.zeros((1, 3))])
    q = np.vstack([q / np.linalg.norm(q, axis=1, keepdims=True), [[0.0, 0.0, 0.0, 1.0]]])
    a = np.array([j[0] for j in scene.joints])
    b = np.array([j[1] for j in scene.joints])
    a_world = np.array([j[0] for j in scene.joints]) < 0
    pa = np.where(a_world[:, None], la, x[a] + _rotate(q[a], la))
    pb = x[b] + _rotate(q[b], lb)
    return float(np.linalg.norm(pb - pa, axis=1).max())


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    u, w = q[:, :3], q[:, 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


# ---------------------------------------------------------------------------- engines


class Tumble:
    name = "tumble"
    settings = "dt 1/240, 8 substeps (soft step, ball-joint chains exact)"

    def __init__(self, scene: JointScene):
        import tumble

        self.world = w = tumble.World(gravity=GRAVITY, dt=DT)
        if scene.ground:
            w.add_plane(friction=FRICTION)
        self.first = w.body_count
        for shape, size, x, m in zip(scene.shape, scene.size, scene.position, scene.mass):
            if shape == "sphere":
                w.add_sphere(position=x, radius=size, mass=m, friction=FRICTION)
            else:
                w.add_box(position=x, half_extents=size, mass=m, friction=FRICTION)
        for a, b, p in scene.joints:
            w.add_joint("ball", None if a < 0 else a + self.first, b + self.first, anchor=p)

    def step(self, k: int) -> None:
        for _ in range(k):
            self.world.step()

    def pose(self):
        return self.world.body_position[self.first :], self.world.body_orientation[self.first :]


class PyBullet:
    name = "pybullet"
    settings = "dt 1/240, 50 iterations (default)"

    def __init__(self, scene: JointScene):
        import pybullet as p

        self.p = p
        self.c = c = p.connect(p.DIRECT)
        p.setGravity(*GRAVITY, physicsClientId=c)
        p.setTimeStep(DT, physicsClientId=c)
        if scene.ground:
            plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=c)
            g = p.createMultiBody(0, plane, physicsClientId=c)
            p.changeDynamics(g, -1, lateralFriction=FRICTION, physicsClientId=c)
        self.ids = []
        shapes = {}
        for shape, size, x, m in zip(scene.shape, scene.size, scene.position, scene.mass):
            key = (shape, size if shape == "sphere" else tuple(size))
            if key not in shapes:
                shapes[key] = (
                    p.createCollisionShape(p.GEOM_SPHERE, radius=size, physicsClientId=c)
                    if shape == "sphere"
                    else p.createCollisionShape(p.GEOM_BOX, halfExtents=list(size), physicsClientId=c)
                )
            body = p.createMultiBody(m, shapes[key], basePosition=list(x), physicsClientId=c)
            p.changeDynamics(body, -1, lateralFriction=FRICTION, linearDamping=0, angularDamping=0, physicsClientId=c)
            self.ids.append(body)
        la, lb = scene.local_anchors()
        for (a, b, _), pa, pb in zip(scene.joints, la, lb):
            parent = -1 if a < 0 else self.ids[a]
            p.createConstraint(
                self.ids[b], -1, parent, -1, p.JOINT_POINT2POINT, [0, 0, 0], list(pb), list(pa), physicsClientId=c
            )
            if a >= 0:
                p.setCollisionFilterPair(self.ids[a], self.ids[b], -1, -1, 0, physicsClientId=c)

    def step(self, k: int) -> None:
        for _ in range(k):
            self.p.stepSimulation(physicsClientId=self.c)

    def pose(self):
        rows = [self.p.getBasePositionAndOrientation(i, physicsClientId=self.c) for i in self.ids]
        return np.array([r[0] for r in rows]), np.array([r[1] for r in rows])


class MuJoCo:
    name = "mujoco"
    settings = "dt 1/240, Newton solver, 100 iterations, connect equalities"

    def __init__(self, scene: JointScene):
        import mujoco

        self.mj = mujoco
        parts = [
            (
                f'<mujoco><option timestep="{DT}" gravity="{GRAVITY[0]} {GRAVITY[1]} {GRAVITY[2]}" '
                f'iterations="100"/><size memory="200M"/><worldbody>'
            )
        ]
        if scene.ground:
            parts.append(f'<geom type="plane" size="0 0 1" friction="{FRICTION} 0.005 0.0001"/>')
        for i, (shape, size, x, m) in enumerate(zip(scene.shape, scene.size, scene.position, scene.mass)):
            geom = (
                f'type="sphere" size="{size}"'
                if shape == "sphere"
                else f'type="box" size="{size[0]} {size[1]} {size[2]}"'
            )
            parts.append(
                f'<body name="b{i}" pos="{x[0]} {x[1]} {x[2]}"><freejoint/>'
                f'<geom {geom} mass="{m}" friction="{FRICTION} 0.005 0.0001"/></body>'
            )
        parts.append("</worldbody><contact>")
        parts += [f'<exclude body1="b{a}" body2="b{b}"/>' for a, b, _ in scene.joints if a >= 0]
        parts.append("</contact><equality>")
        la, lb = scene.local_anchors()
        for (a, b, _), pa, pb in zip(scene.joints, la, lb):
            # connect: the anchor, given in body1's frame, coincides with the same point of body2
            if a < 0:
                parts.append(f'<connect body1="b{b}" body2="world" anchor="{pb[0]} {pb[1]} {pb[2]}"/>')
            else:
                parts.append(f'<connect body1="b{a}" body2="b{b}" anchor="{pa[0]} {pa[1]} {pa[2]}"/>')
        parts.append("</equality></mujoco>")
        self.model = mujoco.MjModel.from_xml_string("".join(parts))
        self.data = mujoco.MjData(self.model)
        self.n = len(scene.shape)

    def step(self, k: int) -> None:
        for _ in range(k):
            self.mj.mj_step(self.model, self.data)

    def pose(self):
        q = self.data.qpos.reshape(self.n, 7)
        return q[:, :3].copy(), q[:, [4, 5, 6, 3]].copy()


class Rapier:
    name = "rapier"
    settings = "dt 1/240, 4 iterations (default), impulse joints, 1 thread"

    def __init__(self, scene: JointScene):
        import rapier3d as r

        self.r = r
        self.world = w = r.PhysicsWorld(gravity=r.Vec3(*GRAVITY))
        w.set_num_threads(1)
        w.integration_parameters.dt = DT
        fixed = w.add_body(r.RigidBody.fixed())
        if scene.ground:
            w.add_collider(r.Collider.halfspace(r.Vec3(0.0, 0.0, 1.0), friction=FRICTION), parent=fixed)
        self.handles = []
        for shape, size, x, m in zip(scene.shape, scene.size, scene.position, scene.mass):
            body = w.add_body(r.RigidBody.dynamic(translation=r.Vec3(*map(float, x)), can_sleep=False))
            collider = (
                r.Collider.ball(float(size), mass=m, friction=FRICTION)
                if shape == "sphere"
                else r.Collider.cuboid(*map(float, size), mass=m, friction=FRICTION)
            )
            w.add_collider(collider, parent=body)
            self.handles.append(body)
        la, lb = scene.local_anchors()
        for (a, b, _), pa, pb in zip(scene.joints, la, lb):
            joint = (
                r.SphericalJointBuilder()
                .local_anchor1(r.Vec3(*map(float, pa)))
                .local_anchor2(r.Vec3(*map(float, pb)))
                .contacts_enabled(False)
                .build()
            )
            w.impulse_joints.insert(fixed if a < 0 else self.handles[a], self.handles[b], joint, True)

    def step(self, k: int) -> None:
        for _ in range(k):
            self.world.step()

    def pose(self):
        rows = [self.world.rigid_bodies[h] for h in self.handles]
        x = np.array([(b.translation.x, b.translation.y, b.translation.z) for b in rows])
        q = np.array([(b.rotation.i, b.rotation.j, b.rotation.k, b.rotation.w) for b in rows])
        return x, q


ENGINES = {e.name: e for e in (Tumble, PyBullet, MuJoCo, Rapier)}


def run(scene_name: str, engine: str, duration: float, log=print) -> dict:
    """Build, warm up (one step, not timed) and run one engine on one scene; steps/s and drift."""
    scene = SCENES[scene_name]()
    t0 = time.perf_counter()
    sim = ENGINES[engine](scene)
    build = time.perf_counter() - t0
    sim.step(1)
    chunk = max(1, round(SAMPLE_EVERY / DT))
    steps = max(chunk, round(duration / DT) // chunk * chunk)
    stepping, worst = 0.0, drift(scene, *sim.pose())
    for _ in range(steps // chunk):
        t = time.perf_counter()
        sim.step(chunk)
        stepping += time.perf_counter() - t
        x, q = sim.pose()
        if not (np.isfinite(x).all() and np.isfinite(q).all()):
            worst = math.inf
            break
        worst = max(worst, drift(scene, x, q))
    end = drift(scene, *sim.pose())
    row = {
        "scene": scene_name,
        "engine": engine,
        "settings": sim.settings,
        "bodies": len(scene.shape),
        "joints": len(scene.joints),
        "steps": steps,
        "steps_per_s": steps / stepping,
        "build_s": build,
        "max_drift_mm": 1e3 * worst,
        "end_drift_mm": 1e3 * end,
    }
    log(
        f"  {engine:9s} {row['steps_per_s']:8.1f} steps/s   max drift {row['max_drift_mm']:9.3f} mm   "
        f"end drift {row['end_drift_mm']:9.3f} mm   ({sim.settings})"
    )
    return row


def write_csv(path: Path, rows: list[dict]) -> None:
    """The rows as CSV, written atomically (a temporary file beside the target, then renamed)."""
    import csv
    import os

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    with open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", default=",".join(SCENES))
    parser.add_argument("--engines", default="tumble,pybullet,mujoco,rapier")
    parser.add_argument("--duration", type=float, default=DURATION, help="simulated seconds per scene (default 1)")
    args = parser.parse_args(argv)
    rows = []
    for name in args.scenes.split(","):
        scene = SCENES[name]()
        print(
            f"{name}: {len(scene.shape):,} bodies, {len(scene.joints):,} ball joints, {args.duration:g} s", flush=True
        )
        for engine in args.engines.split(","):
            try:
                rows.append(run(name, engine, args.duration))
            except Exception as exc:  # noqa: BLE001 (an engine that cannot build the scene is reported, not fatal)
                print(f"  {engine:9s} failed: {type(exc).__name__}: {exc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
