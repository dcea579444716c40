"""The benchmark scenes start every engine from the same, non-overlapping state (no timing here)."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import quality, scenes  # noqa: E402


@pytest.mark.parametrize("name", ["pile_1k", "pile_20k", "pile_100k", "boxes_1k"])
def test_initial_bodies_are_seeded_and_do_not_overlap(name):
    """Build the same positions twice, inside the box, with no two bodies touching."""
    scene = scenes.SCENES[name]
    a, b = scenes.initial_bodies(scene), scenes.initial_bodies(scene)
    np.testing.assert_array_equal(a.position, b.position)
    assert a.position.shape == (scene.count, 3)
    if a.shape == "sphere":
        assert quality.sphere_max_overlap(a.position, a.radius) <= 0.0
        depth = quality.plane_penetration(a.position, a.planes, radius=a.radius)
    else:
        q = np.tile([0.0, 0.0, 0.0, 1.0], (scene.count, 1))
        assert quality.box_max_overlap(a.position, q, a.half_extents) <= 0.0
        depth = quality.plane_penetration(a.position, a.planes, orientation=q, half_extents=a.half_extents)
    assert np.all(depth <= 0.0)


def test_pile_box_widths():
    """Keep the 1k-20k piles in a 1 m box and the 100k pile in a 5 m box."""
    assert scenes.SCENES["pile_5k"].box_width == 1.0
    assert scenes.SCENES["pile_100k"].box_width == 5.0
    walls = scenes.box_planes(1.0)
    assert len(walls) == 5 and walls[1][1] == -0.5


def test_cloth_grid_and_pins():
    """Lay the cloth particles row by row with the two pins at the corners of the far edge."""
    cloth = scenes.initial_cloth(scenes.SCENES["cloth_64"])
    n = 64
    assert cloth.position.shape == (n * n, 3)
    np.testing.assert_allclose(cloth.position[1] - cloth.position[0], [cloth.spacing, 0, 0])
    np.testing.assert_allclose(cloth.position[n] - cloth.position[0], [0, cloth.spacing, 0])
    np.testing.assert_allclose(cloth.position[list(cloth.pins), 1], 0.5)
    np.testing.assert_allclose(cloth.position[list(cloth.pins), 0], [-0.5, 0.5])
    edges = scenes.cloth_edges(n)
    assert len(edges) == 2 * n * (n - 1)
    assert quality.cloth_max_strain(cloth.position, edges, cloth.spacing) == pytest.approx(0.0, abs=1e-12)


def test_quality_figures_find_known_overlaps():
    """Report the overlap of two spheres and of two boxes, and a box corner below the ground."""
    spheres = np.array([[0.0, 0.0, 0.0], [0.09, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert quality.sphere_max_overlap(spheres, 0.05) == pytest.approx(0.01)
    half = np.full(3, 0.05)
    s, c = np.sin(np.pi / 8), np.cos(np.pi / 8)
    q = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, s, c]])  # second box turned 45 deg about z
    boxes = np.array([[0.0, 0.0, 0.0], [0.11, 0.0, 0.0]])
    # the turned box reaches 0.05 sqrt(2) towards the first: overlap 0.05 + 0.0707 - 0.11
    assert quality.box_max_overlap(boxes, q, half) == pytest.approx(0.05 + 0.05 * np.sqrt(2) - 0.11)
    tilted = np.array([[s, 0.0, 0.0, c]])  # 45 deg about x: lowest edge 0.05 sqrt(2) below the centre
    ground = [(np.array([0.0, 0.0, 1.0]), 0.0)]
    depth = quality.plane_penetration(np.array([[0.0, 0.0, 0.06]]), ground, orientation=tilted, half_extents=half)
    assert depth[0] == pytest.approx(0.05 * np.sqrt(2) - 0.06)


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_peer_engines_start_from_the_scene_positions(engine):
    """Build a small pile and a small cloth in a peer and read back the same initial state."""
    pytest.importorskip(engine)
    from benchmarks import engines

    pile = scenes.Scene("pile_test", "pile", 50)
    adapter = engines.ADAPTERS[engine](pile)
    state = adapter.bodies()
    np.testing.assert_allclose(state["position"], scenes.initial_bodies(pile).position, atol=1e-9)
    np.testing.assert_allclose(np.abs(state["orientation"][:, 3]), 1.0)
    adapter.close()
    cloth = scenes.Scene("cloth_test", "cloth", 8)
    adapter = engines.ADAPTERS[engine](cloth)
    np.testing.assert_allclose(adapter.cloth_position(), scenes.initial_cloth(cloth).position, atol=1e-6)
    adapter.close()


def test_rapier_starts_from_the_scene_positions_and_keeps_spheres_above_the_ground():
    """Build a small pile in Rapier, read back the initial state, and step it onto the ground."""
    pytest.importorskip("rapier3d")
    from benchmarks import engines

    pile = scenes.Scene("pile_test", "pile", 50)
    adapter = engines.ADAPTERS["rapier"](pile)
    start = adapter.bodies()
    # Rapier stores f32: positions round to ~1e-7 relative
    np.testing.assert_allclose(start["position"], scenes.initial_bodies(pile).position, atol=1e-6)
    np.testing.assert_allclose(np.abs(start["orientation"][:, 3]), 1.0)
    assert "4 iterations" in adapter.settings()
    adapter.step(240)  # 1 s: the pile falls ~0.2-0.7 m and lands
    z = adapter.bodies()["position"][:, 2]
    assert np.all(z < start["position"][:, 2])  # everything fell
    assert z.min() > 0.5 * scenes.SPHERE_RADIUS  # nothing fell through the ground (half-space side right)
    adapter.close()
    with pytest.raises(NotImplementedError):
        engines.ADAPTERS["rapier"](scenes.Scene("cloth_test", "cloth", 8))


def test_mesh_benchmark_ground_is_100k_flat_triangles_and_the_same_pour():
    """The mesh row's ground: >= 100k upward triangles at z = 0 covering where the plane holds the spheres."""
    from benchmarks import meshes

    v, t = meshes.ground_mesh()
    assert len(t) >= 100_000 and np.all(v[:, 2] == 0.0)
    e1, e2 = v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]
    assert np.all(np.cross(e1, e2)[:, 2] > 0)  # wound counter-clockwise seen from above
    x = scenes.pile_positions(meshes.SPHERES, meshes.WIDTH, seed=1)
    assert np.abs(x[:, :2]).max() < meshes.MESH_HALF - 1.0  # a metre of mesh left around the pour


@pytest.mark.parametrize("engine", ["tumble", "pybullet", "mujoco", "rapier"])
def test_quality_settings_reach_the_engine(engine):
    """`run.py --quality` builds every engine with the settings its docs recommend for accuracy:
    read each back from the engine itself, not from the adapter's own record."""
    pytest.importorskip({"tumble": "tumble", "pybullet": "pybullet", "mujoco": "mujoco", "rapier": "rapier3d"}[engine])
    from benchmarks import engines

    pile = scenes.Scene("pile_test", "pile", 20)
    default, best = engines.ADAPTERS[engine](pile), engines.ADAPTERS[engine](pile, quality=True)
    if engine == "tumble":
        assert (default.world.substeps, best.world.substeps) == (8, engines.TumbleAdapter.QUALITY_SUBSTEPS)
    elif engine == "pybullet":
        read = [a.p.getPhysicsEngineParameters(physicsClientId=a.client)["numSubSteps"] for a in (default, best)]
        assert read == [0, engines.PyBulletAdapter.QUALITY_SUBSTEPS]
    elif engine == "mujoco":
        import mujoco

        o = best.model.opt
        assert (o.solver, o.integrator, o.cone) == (
            mujoco.mjtSolver.mjSOL_NEWTON,
            mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
            mujoco.mjtCone.mjCONE_ELLIPTIC,
        )
        assert default.model.opt.solver == mujoco.mjtSolver.mjSOL_CG
    else:
        read = [a.world.integration_parameters.num_solver_iterations for a in (default, best)]
        assert read == [engines.RapierAdapter.ITERATIONS, engines.RapierAdapter.QUALITY_ITERATIONS]
    assert default.settings() != best.settings()  # the table tells the two comparisons apart
    default.close()
    best.close()


def test_curve_bounce_row_measures_the_analytic_rebound():
    """benchmarks/curve.py's bounce row: a 1 m drop with e = 0.5 rebounds to e^2 H = 0.25 m, to
    within a few substeps' gravity kicks g h^2 (the apex is sampled once a step)."""
    from benchmarks import curve

    substeps = 2
    h = curve.DT / substeps
    figures = curve.bounce(substeps)
    bound = 100.0 * 4 * 9.81 * h * h / 0.25  # [%]: 0.07 %
    assert abs(figures["rebound error %"]) < bound
    assert figures["ground mm"] < 1e3 * 9.81 * h * h  # never more than one kick below the plane
