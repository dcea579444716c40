"""Cloth triangles against the sharp features of static meshes: a tip or a ridge between particles.

References are geometric: a cloth sheet is the surface of its triangles, and a feature held off it
by the contacts stays on its side of that surface, half the cloth's thickness away (the distance
the triangles keep, as from small spheres); and energy: the contacts are position corrections
against a static body, so the cloth's energy (kinetic + gravity) never rises above its start by
more than the lift of the whole cloth by that distance.
"""

import numpy as np
import pytest

import tumble

G = 9.81
DT = 1.0 / 240.0
THICKNESS = 0.01
GAP = THICKNESS / 2  # what a triangle keeps from a mesh feature


def _surface_height(x, triangles, point):
    """Lowest height of the cloth's triangles over point's (x, y), or None where none covers it."""
    a, b, c = x[triangles[:, 0]], x[triangles[:, 1]], x[triangles[:, 2]]
    e1, e2, r = b[:, :2] - a[:, :2], c[:, :2] - a[:, :2], point[None, :2] - a[:, :2]
    det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
    ok = np.abs(det) > 1e-14
    det = np.where(ok, det, 1.0)
    u = (r[:, 0] * e2[:, 1] - e2[:, 0] * r[:, 1]) / det
    v = (e1[:, 0] * r[:, 1] - r[:, 0] * e1[:, 1]) / det
    inside = ok & (u >= 0) & (v >= 0) & (u + v <= 1)
    if not inside.any():
        return None
    z = a[:, 2] + u * (b[:, 2] - a[:, 2]) + v * (c[:, 2] - a[:, 2])
    return z[inside].min()


def _spike(world):
    trimesh = pytest.importorskip("trimesh")
    cone = trimesh.creation.cone(radius=0.08, height=0.3, sections=16)
    world.add_mesh(vertices=cone.vertices, triangles=cone.faces)
    return [np.array([0.0, 0.0, 0.3])]


def _ridge(world):
    # a wedge along y, 10 cm wide at the base, its ridge 0.3 m up, 0.8 m long (outward winding);
    # the points checked lie under the cloth (y from -0.243 to 0.357)
    v = np.array([[-0.05, -0.4, 0], [0.05, -0.4, 0], [0, -0.4, 0.3], [-0.05, 0.4, 0], [0.05, 0.4, 0], [0, 0.4, 0.3]])
    t = np.array([[1, 2, 0], [5, 4, 3], [4, 1, 0], [3, 4, 0], [5, 2, 1], [4, 5, 1], [3, 0, 2], [5, 3, 2]])
    world.add_mesh(vertices=v, triangles=t)
    return [np.array([0.0, y, 0.3]) for y in np.linspace(-0.2, 0.3, 11)]


@pytest.mark.parametrize("feature", [_spike, _ridge], ids=["cone tip", "wedge ridge"])
def test_a_sharp_mesh_feature_between_particles_stays_under_the_cloth(feature):
    """A coarse cloth (10 cm cells) dropped on a cone's tip or a wedge's ridge that falls inside a cell:
    the feature stays under the cloth's surface, and the cloth gains no energy.

    Before, the particles met only the mesh's faces: the tip and the ridge went through between
    them and the cloth fell to the ground (the tip ended 25 cm above the cloth's surface).
    """
    world = tumble.World(gravity=(0, 0, -G), dt=DT)
    world.add_plane()
    points = feature(world)
    # 7 x 7 particles 0.1 m apart; the feature lies off every particle and grid line
    world.add_cloth(
        size=(0.6, 0.6), resolution=(7, 7), position=(0.063, 0.057, 0.4), mass=0.1, thickness=THICKNESS, friction=0.5
    )
    cloth = world.cloth
    triangles = cloth.triangles
    mass = cloth.particle_mass.sum()
    e0 = cloth.kinetic_energy() + cloth.potential_energy()
    least, gain = np.inf, -np.inf
    for _ in range(int(1.5 / DT)):
        world.step()
        x = cloth.particle_position_numpy()
        for p in points:
            z = _surface_height(x, triangles, p)
            assert z is not None  # the cloth still covers the feature
            least = min(least, z - p[2])
        gain = max(gain, cloth.kinetic_energy() + cloth.potential_energy() - e0)
    # on its side of the surface: the contacts keep GAP; the tolerance is that GAP again
    assert least >= GAP - GAP
    # resting on it, not floating: the last surface height is within the thickness of the feature
    assert z - p[2] < THICKNESS
    assert gain <= mass * G * GAP
