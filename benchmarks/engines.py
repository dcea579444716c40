"""One adapter per engine: build a `Scene`, step it, read its state back as plain arrays.

Every adapter has the same small interface, so the runner treats engines alike:

* `Adapter(scene, device)` builds the scene from `scenes.initial_bodies` / `scenes.initial_cloth`;
* `step(k)` advances k steps of `scene.dt`; `sync()` waits for the device (GPU only);
* `bodies()` returns position (n, 3), orientation (n, 4) as (x, y, z, w), velocity (n, 3) and
  angular velocity (n, 3) of the moving bodies, in the order of `initial_bodies`;
* `cloth_position()` returns the cloth particles (n * n, 3) in the order of `initial_cloth`.

Material: restitution 0.5 and friction 0.5 everywhere. Tumble combines a pair as max(e) and
sqrt(mu mu), so every body gets 0.5. PyBullet multiplies the two bodies' coefficients, so every
body gets sqrt(0.5). MuJoCo has no restitution coefficient: its contacts are springs (solref
time constant and damping ratio), tuned below to bounce back about half the speed.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.scenes import (
    CLOTH_SIZE,
    FRICTION,
    NO_RAPIER_CLOTH,
    RESTITUTION,
    Scene,
    initial_bodies,
    initial_cloth,
)

GRAVITY = (0.0, 0.0, -9.81)

# MuJoCo contact softness for rigid contacts: time constant [s] (MuJoCo requires >= 2 dt) and
# damping ratio; a damping ratio below 1 makes the contact spring bounce (measured in
# benchmarks/README.md: a ball dropped from 1 m rebounds to ~0.25 m, i.e. e ~ 0.5)
MUJOCO_SOLREF = (0.02, 0.3)

# MuJoCo cloth: edge equality constraints made as stiff as MuJoCo allows at this time step
# and enough CG iterations to converge (the default 100 stops short on 64 x 64 and the cloth
# stretches by several hundred per cent)
MUJOCO_CLOTH_ITERATIONS = 1000
MUJOCO_CLOTH_EDGE = 'solref="0.0084 1" solimp="0.99 0.99 0.001"'


def _xyz(v) -> str:
    """Three numbers for an MJCF attribute, full precision."""
    return " ".join(repr(float(c)) for c in v)


def _pixel_index(position: np.ndarray, origin: np.ndarray, spacing: float, n: int) -> np.ndarray:
    """Grid row j * n + i of each particle, from its rest position on the cloth's grid."""
    ij = np.rint((position[:, :2] - origin[:2]) / spacing).astype(np.int64)
    if ij.min() < 0 or ij.max() >= n:
        raise RuntimeError("cloth particles are not on the expected grid")
    index = ij[:, 1] * n + ij[:, 0]
    if len(np.unique(index)) != n * n:
        raise RuntimeError("cloth particles do not map one to one onto the expected grid")
    return index


class TumbleAdapter:
    """Tumble on the CPU or a CUDA device (`World(device=...)`), default substeps.

    Cloth: `add_cloth` with its default springs and 10 % stretch limit, self-collision off.
    `quality=True`: the settings docs/performance.md recommends for quality (`QUALITY_SUBSTEPS`).
    """

    name = "tumble"
    #: the World's precision (None: Tumble's default, `tumble.precision.DEFAULT_PRECISION`)
    precision: str | None = None

    #: substeps for quality: past this count benchmarks/curve.py finds no gain worth the time
    QUALITY_SUBSTEPS = 16

    def settings(self) -> str:
        """The solver settings this adapter runs with, for the results table."""
        w = self.world
        return f"dt 1/{round(1 / w.dt)}, {w.substeps} substeps, {w.precision}"

    def __init__(self, scene: Scene, device: str = "cpu", *, quality: bool = False):
        import warp as wp

        import tumble

        self._wp = wp
        self.scene = scene
        options = {} if scene.substeps is None else {"substeps": scene.substeps}
        if self.precision is not None:  # (left out otherwise, so that overhead.py --compare can time older trees)
            options["precision"] = self.precision
        gravity = (0.0, 0.0, -scene.gravity)
        self.world = world = tumble.World(gravity=gravity, dt=scene.dt, device=device, **options)
        if quality:
            world.substeps = self.QUALITY_SUBSTEPS
        self.device = world.device
        if scene.kind == "cloth":
            self.cloth_init = cloth = initial_cloth(scene)
            world.add_cloth(
                size=(CLOTH_SIZE, CLOTH_SIZE),
                resolution=(cloth.n, cloth.n),
                position=(0.0, 0.0, float(cloth.position[0, 2])),
                mass=cloth.mass,
                pins=[[int(k) % cloth.n, int(k) // cloth.n] for k in cloth.pins],  # grid points (i, j)
            )
            # like the peers' cloths: no self-collision
            world.cloth.self_collision = False
            if world.cloth.particle_count != cloth.n * cloth.n:
                raise RuntimeError(f"Tumble made {world.cloth.particle_count} cloth particles, expected {cloth.n**2}")
            start = world.cloth.particle_position
            self._cloth_rows = np.argsort(_pixel_index(start, cloth.position[0], cloth.spacing, cloth.n))
            return
        self.init = init = initial_bodies(scene)
        material = {"restitution": init.restitution, "friction": init.friction}
        for normal, offset in init.planes:
            world.add_plane(normal=normal, offset=offset, **material)
        first = world.body_count
        # all bodies in one vectorised call (add_sphere one by one costs ~2 ms a body)
        add = world.add_spheres if init.shape == "sphere" else world.add_boxes
        size = {"radius": init.radius} if init.shape == "sphere" else {"half_extents": init.half_extents}
        add(position=init.position, mass=init.mass, **size, **material)
        self._rows = slice(first, world.body_count)

    def step(self, k: int) -> None:
        for _ in range(k):
            self.world.step()

    def sync(self) -> None:
        if self.device != "cpu":
            self._wp.synchronize_device(self.device)

    def bodies(self) -> dict[str, np.ndarray]:
        w, rows = self.world, self._rows
        return {
            "position": np.array(w.body_position[rows]),
            "orientation": np.array(w.body_orientation[rows]),
            "velocity": np.array(w.body_velocity[rows]),
            "angular_velocity": np.array(w.body_angular_velocity[rows]),
        }

    def cloth_position(self) -> np.ndarray:
        return np.array(self.world.cloth.particle_position)[self._cloth_rows]

    def close(self) -> None:
        self.world = None


class TumbleFloat64Adapter(TumbleAdapter):
    """Tumble in float64 (`World(precision="float64")`), beside the default's row: its "Tumble x" column
    is then the default precision's speed over float64's."""

    name = "tumble_f64"
    precision = "float64"


class TumbleFloat32Adapter(TumbleAdapter):
    """Tumble in float32 (`World(precision="float32")`), beside the default's row: its "Tumble x" column
    is then the default precision's speed over float32's."""

    name = "tumble_f32"
    precision = "float32"


class PyBulletAdapter:
    """PyBullet in DIRECT mode with its default solver; damping set to 0 (Tumble has none).

    `quality=True`: `numSubSteps` = `QUALITY_SUBSTEPS`, the knob its quickstart guide names for
    trading performance for accuracy (`setPhysicsEngineParameter`); iterations stay at its 50.

    Cloth is a soft body loaded from a generated OBJ grid into PyBullet's classic soft-body world
    (position-based links with PyBullet's built-in stiffness and 20 iterations; the mass-spring
    keywords of `loadSoftBody` only act in the deformable world, which diverged on this cloth at
    dt = 1/240 and ran at ~10 steps/s), its two corners anchored to the world.
    """

    name = "pybullet"

    QUALITY_SUBSTEPS = 4

    def settings(self) -> str:
        """The solver settings this adapter runs with, for the results table."""
        params = self.p.getPhysicsEngineParameters(physicsClientId=self.client)
        sub = params["numSubSteps"]
        return f"dt 1/{round(1 / params['fixedTimeStep'])}, {params['numSolverIterations']} iterations" + (
            f", {sub} substeps" if sub > 1 else ""
        )

    def __init__(self, scene: Scene, device: str = "cpu", *, quality: bool = False):
        import pybullet as p

        self.p = p
        self.scene = scene
        self.client = cid = p.connect(p.DIRECT)
        self.quality = quality
        if scene.kind == "cloth":
            self._build_cloth(scene)
            return
        p.setTimeStep(scene.dt, physicsClientId=cid)
        if quality:
            p.setPhysicsEngineParameter(numSubSteps=self.QUALITY_SUBSTEPS, physicsClientId=cid)
        p.setGravity(*GRAVITY, physicsClientId=cid)
        self.init = init = initial_bodies(scene)
        # pybullet multiplies the coefficients of the two bodies in contact
        e, mu = math.sqrt(RESTITUTION), math.sqrt(FRICTION)
        for normal, offset in init.planes:
            shape = p.createCollisionShape(p.GEOM_PLANE, planeNormal=list(normal), physicsClientId=cid)
            body = p.createMultiBody(0.0, shape, basePosition=list(normal * offset), physicsClientId=cid)
            p.changeDynamics(body, -1, restitution=e, lateralFriction=mu, physicsClientId=cid)
        if init.shape == "sphere":
            shape = p.createCollisionShape(p.GEOM_SPHERE, radius=init.radius, physicsClientId=cid)
        else:
            shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(init.half_extents), physicsClientId=cid)
        self.ids = []
        for x in init.position:
            body = p.createMultiBody(init.mass, shape, basePosition=list(x), physicsClientId=cid)
            p.changeDynamics(
                body,
                -1,
                restitution=e,
                lateralFriction=mu,
                linearDamping=0.0,
                angularDamping=0.0,
                physicsClientId=cid,
            )
            self.ids.append(body)

    def _build_cloth(self, scene: Scene) -> None:
        p, cid = self.p, self.client
        cloth = self.cloth_init = initial_cloth(scene)
        p.resetSimulation(physicsClientId=cid)
        p.setTimeStep(scene.dt, physicsClientId=cid)
        if self.quality:
            p.setPhysicsEngineParameter(numSubSteps=self.QUALITY_SUBSTEPS, physicsClientId=cid)
        p.setGravity(*GRAVITY, physicsClientId=cid)
        # a grid OBJ in the cloth's local frame (z = 0), placed at the cloth's height
        fd, path = tempfile.mkstemp(suffix=".obj", prefix="tumble_bench_cloth_")
        with os.fdopen(fd, "w") as f:
            for x, y, _ in cloth.position:
                f.write(f"v {x:.9g} {y:.9g} 0\n")
            for a, b, c in cloth.triangles + 1:
                f.write(f"f {a} {b} {c}\n")
        try:
            self.cloth_id = p.loadSoftBody(
                path,
                basePosition=[0.0, 0.0, float(cloth.position[0, 2])],
                mass=cloth.mass,
                useSelfCollision=0,
                collisionMargin=0.005,
                frictionCoeff=FRICTION,
                physicsClientId=cid,
            )
        finally:
            os.unlink(path)
        _, nodes = p.getMeshData(self.cloth_id, -1, flags=p.MESH_DATA_SIMULATION_MESH, physicsClientId=cid)
        start = np.array(nodes, dtype=np.float64)
        self._cloth_rows = np.argsort(_pixel_index(start, cloth.position[0], cloth.spacing, cloth.n))
        for pin in cloth.pins:
            p.createSoftBodyAnchor(self.cloth_id, int(self._cloth_rows[pin]), -1, -1, physicsClientId=cid)

    def step(self, k: int) -> None:
        p, cid = self.p, self.client
        for _ in range(k):
            p.stepSimulation(physicsClientId=cid)

    def sync(self) -> None:
        pass

    def bodies(self) -> dict[str, np.ndarray]:
        p, cid = self.p, self.client
        pose = [p.getBasePositionAndOrientation(i, physicsClientId=cid) for i in self.ids]
        vel = [p.getBaseVelocity(i, physicsClientId=cid) for i in self.ids]
        return {
            "position": np.array([x for x, _ in pose]),
            "orientation": np.array([q for _, q in pose]),  # already (x, y, z, w)
            "velocity": np.array([v for v, _ in vel]),
            "angular_velocity": np.array([w for _, w in vel]),
        }

    def cloth_position(self) -> np.ndarray:
        p = self.p
        _, nodes = p.getMeshData(self.cloth_id, -1, flags=p.MESH_DATA_SIMULATION_MESH, physicsClientId=self.client)
        return np.array(nodes, dtype=np.float64)[self._cloth_rows]

    def close(self) -> None:
        self.p.disconnect(physicsClientId=self.client)


class MuJoCoAdapter:
    """MuJoCo from a generated MJCF model: CG solver, default iterations and tolerance.

    `quality=True`: what MuJoCo's documentation recommends for accuracy: the Newton solver, the
    `implicitfast` integrator and elliptic friction cones (pyramidal cones approximate the
    friction cone; elliptic ones are exact), at the same time step.

    Rigid bodies are free-jointed bodies with one geom each; contacts use `MUJOCO_SOLREF`.
    Cloth is a 2D `flexcomp` grid with edge equality constraints, pinned at two corners.
    """

    name = "mujoco"

    def settings(self) -> str:
        """The solver settings this adapter runs with, for the results table."""
        o, m = self.model.opt, self.mujoco
        solver = m.mjtSolver(o.solver).name.removeprefix("mjSOL_").replace("NEWTON", "Newton")
        extra = ""
        if self.quality:
            extra = f", {m.mjtIntegrator(o.integrator).name.removeprefix('mjINT_').lower()}, "
            extra += f"{m.mjtCone(o.cone).name.removeprefix('mjCONE_').lower()} cones"
        return f"dt 1/{round(1 / o.timestep)}, {solver}, {o.iterations} iterations{extra}"

    def __init__(self, scene: Scene, device: str = "cpu", *, quality: bool = False):
        import mujoco

        self.mujoco = mujoco
        self.scene = scene
        self.quality = quality
        xml = self._cloth_xml(scene) if scene.kind == "cloth" else self._bodies_xml(scene)
        self.model = self._compile(xml)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        if scene.kind == "cloth":
            cloth = self.cloth_init
            start = np.array(self.data.flexvert_xpos)
            self._cloth_rows = np.argsort(_pixel_index(start, cloth.position[0], cloth.spacing, cloth.n))

    def _compile(self, xml: str):
        """Compile the MJCF, through a cache of compiled models: MuJoCo's compile time grows
        faster than linearly with the body count (about 4 minutes for 20,000 free bodies)."""
        mujoco = self.mujoco
        if xml.count("<body") < 2000:
            return mujoco.MjModel.from_xml_string(xml)
        key = hashlib.sha256((mujoco.__version__ + xml).encode()).hexdigest()[:24]
        root = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "tumble-bench"
        path = root / f"mujoco-{key}.mjb"
        if path.exists():
            return mujoco.MjModel.from_binary_path(str(path))
        model = mujoco.MjModel.from_xml_string(xml)
        try:
            root.mkdir(parents=True, exist_ok=True)
            mujoco.mj_saveModel(model, str(path), None)
        except OSError:
            pass  # no cache: compile again next time
        return model

    def _header(self, scene: Scene, memory: str, iterations: int = 100) -> str:
        return (
            f'<mujoco model="{scene.name}">\n'
            f'  <option timestep="{scene.dt!r}" gravity="{GRAVITY[0]} {GRAVITY[1]} {GRAVITY[2]}" '
            + ('solver="Newton" integrator="implicitfast" cone="elliptic" ' if self.quality else 'solver="CG" ')
            + f'iterations="{iterations}"/>\n'
            f'  <size memory="{memory}"/>\n'
        )

    def _bodies_xml(self, scene: Scene) -> str:
        self.init = init = initial_bodies(scene)
        n = len(init.position)
        solref = f"{MUJOCO_SOLREF[0]} {MUJOCO_SOLREF[1]}"
        friction = f"{FRICTION} 0.005 0.0001"
        lines = [
            self._header(scene, f"{max(64, n // 8)}M"),
            f'  <default><geom solref="{solref}" friction="{friction}"/></default>\n',
            "  <worldbody>\n",
        ]
        for normal, offset in init.planes:
            lines.append(
                f'    <geom type="plane" size="0 0 1" pos="{_xyz(normal * offset)}" zaxis="{_xyz(normal)}"/>\n'
            )
        if init.shape == "sphere":
            geom = f'<geom type="sphere" size="{init.radius!r}" mass="{init.mass!r}"/>'
        else:
            geom = f'<geom type="box" size="{_xyz(init.half_extents)}" mass="{init.mass!r}"/>'
        for x in init.position:
            lines.append(f'    <body pos="{_xyz(x)}"><freejoint/>{geom}</body>\n')
        lines.append("  </worldbody>\n</mujoco>\n")
        return "".join(lines)

    def _cloth_xml(self, scene: Scene) -> str:
        self.cloth_init = cloth = initial_cloth(scene)
        n = cloth.n
        # flexcomp grid vertex (i, j) is numbered i * n + j (x slowest); pins in that numbering
        pins = " ".join(str((k % n) * n + k // n) for k in cloth.pins)
        z = float(cloth.position[0, 2])
        return (
            self._header(scene, f"{max(64, n * n // 16)}M", MUJOCO_CLOTH_ITERATIONS) + "  <worldbody>\n"
            f'    <flexcomp name="cloth" type="grid" dim="2" count="{n} {n} 1" '
            f'spacing="{cloth.spacing!r} {cloth.spacing!r} {cloth.spacing!r}" pos="0 0 {z!r}" '
            f'radius="0.001" mass="{cloth.mass!r}">\n'
            '      <contact selfcollide="none" contype="0" conaffinity="0"/>\n'
            f'      <edge equality="true" {MUJOCO_CLOTH_EDGE}/>\n'
            f'      <pin id="{pins}"/>\n'
            "    </flexcomp>\n"
            "  </worldbody>\n</mujoco>\n"
        )

    def step(self, k: int) -> None:
        mj_step, model, data = self.mujoco.mj_step, self.model, self.data
        for _ in range(k):
            mj_step(model, data)

    def sync(self) -> None:
        pass

    def bodies(self) -> dict[str, np.ndarray]:
        qpos = np.array(self.data.qpos).reshape(-1, 7)
        qvel = np.array(self.data.qvel).reshape(-1, 6)
        return {
            "position": qpos[:, :3],
            "orientation": qpos[:, [4, 5, 6, 3]],  # MuJoCo stores (w, x, y, z)
            "velocity": qvel[:, :3],  # world frame
            "angular_velocity": qvel[:, 3:],  # body frame; |w| is all the quality figures use
        }

    def cloth_position(self) -> np.ndarray:
        return np.array(self.data.flexvert_xpos)[self._cloth_rows]

    def close(self) -> None:
        self.model = self.data = None


class RapierAdapter:
    """Rapier (`rapier3d`, Rust, f32) on one thread with its defaults (4 solver iterations).

    `quality=True`: `QUALITY_ITERATIONS` solver iterations, the "more accurate (but slower)"
    setting of the example in Rapier's `IntegrationParameters` documentation.

    Planes are half-spaces on one fixed body; each moving body is a dynamic body with one
    collider carrying the body's mass, restitution 0.5 and friction 0.5 (Rapier combines a pair
    by the average, so each pair gets 0.5). Sleeping is off, as in the other engines.
    """

    name = "rapier"

    #: Rapier's own default solver iterations per step, and its documented setting for accuracy
    ITERATIONS = 4
    QUALITY_ITERATIONS = 8

    def settings(self) -> str:
        """The solver settings this adapter runs with, for the results table."""
        p = self.world.integration_parameters
        return f"dt 1/{round(1 / p.dt)}, {p.num_solver_iterations} iterations, 1 thread"

    def __init__(self, scene: Scene, device: str = "cpu", *, iterations: int | None = None, quality: bool = False):
        import rapier3d as r

        if scene.kind == "cloth":
            raise NotImplementedError(NO_RAPIER_CLOTH)
        self.r = r
        self.scene = scene
        self.world = world = r.PhysicsWorld(gravity=r.Vec3(*GRAVITY))
        world.set_num_threads(1)
        world.integration_parameters.dt = scene.dt
        default = self.QUALITY_ITERATIONS if quality else self.ITERATIONS
        world.integration_parameters.num_solver_iterations = iterations or default
        self.init = init = initial_bodies(scene)
        ground = world.add_body(r.RigidBody.fixed())
        for normal, offset in init.planes:
            # the half-space's solid side is opposite its normal; the plane passes through normal * offset
            point = normal * offset
            world.add_collider(
                r.Collider.halfspace(
                    r.Vec3(*map(float, normal)),
                    translation=r.Vec3(*map(float, point)),
                    friction=FRICTION,
                    restitution=RESTITUTION,
                ),
                parent=ground,
            )
        self.handles = []
        for x in init.position:
            body = world.add_body(r.RigidBody.dynamic(translation=r.Vec3(*map(float, x)), can_sleep=False))
            if init.shape == "sphere":
                collider = r.Collider.ball(init.radius, mass=init.mass, friction=FRICTION, restitution=RESTITUTION)
            else:
                hx, hy, hz = map(float, init.half_extents)
                collider = r.Collider.cuboid(hx, hy, hz, mass=init.mass, friction=FRICTION, restitution=RESTITUTION)
            world.add_collider(collider, parent=body)
            self.handles.append(body)

    def step(self, k: int) -> None:
        world = self.world
        for _ in range(k):
            world.step()

    def sync(self) -> None:
        pass

    def bodies(self) -> dict[str, np.ndarray]:
        bodies = self.world.rigid_bodies
        rows = [bodies[h] for h in self.handles]

        def vec(v):
            return (v.x, v.y, v.z)

        return {
            "position": np.array([vec(b.translation) for b in rows], dtype=np.float64),
            "orientation": np.array(
                [(b.rotation.i, b.rotation.j, b.rotation.k, b.rotation.w) for b in rows], dtype=np.float64
            ),
            "velocity": np.array([vec(b.linvel) for b in rows], dtype=np.float64),
            "angular_velocity": np.array([vec(b.angvel) for b in rows], dtype=np.float64),
        }

    def close(self) -> None:
        self.world = None


ADAPTERS = {
    a.name: a
    for a in (TumbleAdapter, TumbleFloat64Adapter, TumbleFloat32Adapter, PyBulletAdapter, MuJoCoAdapter, RapierAdapter)
}
