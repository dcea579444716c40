"""Issue 16: a cloth folding over the edge of an open mesh (a two-triangle plate) was thrown up to 2.7 m.

Cause (cloth/collide.py, `_mesh_distance`): a particle behind a face's interior and less than one
thickness deep counted as inside the mesh and was pushed out to the front, up to two thicknesses
in one substep. An open mesh has no inside: a skirt that swung under the plate was pushed up
through the zero-thickness sheet, and the position-based velocity update turned the 2 cm push
into 2 cm / h = 38 m/s (h = 1/1920 s). Measured before the fix, a 1 m cloth dropped from 0.6 m
on a 0.6 m plate at 0.4 m: thrown to z = 2.5-3.0 m, particles at up to 40 m/s. Fixed: on an
open mesh a particle is kept on the side it began the substep on.

Bounds from the physics: the cloth falls from rest and meets only static bodies, so no particle
rises above its start by more than one thickness (what a contact may lift it by), and the
cloth's energy (kinetic + gravity) never rises above its start by more than lifting it all by
one thickness. A bound on particle speeds is not used: a cloth folding over an edge whips its
free end faster than free fall (7 m/s here, the fall's 3.4 m/s; a folding chain does the same).
"""

import numpy as np
import pytest

import tumble

G = 9.81
THICKNESS = 0.01
PLATE = np.array([[-0.3, -0.3, 0.0], [0.3, -0.3, 0.0], [0.3, 0.3, 0.0], [-0.3, 0.3, 0.0]])


@pytest.mark.parametrize("winding", ["up", "down"])
def test_cloth_folding_over_an_open_plate_is_not_thrown(winding):
    """A cloth dropped over a two-triangle plate, facing up or down, folds over its edges and stays put."""
    world = tumble.World(gravity=(0, 0, -G), dt=1.0 / 240.0)
    world.add_plane()
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    if winding == "down":
        triangles = triangles[:, ::-1]  # the cloth lands on the plate's back
    world.add_mesh(vertices=PLATE, triangles=triangles, position=(0, 0, 0.4))
    world.add_cloth(size=(1.0, 1.0), resolution=(24, 24), position=(0, 0, 0.6), mass=0.2, thickness=THICKNESS)
    cloth = world.cloth
    z0 = cloth.particle_position_numpy()[:, 2].max()
    e0 = cloth.kinetic_energy() + cloth.potential_energy()
    lift = cloth.particle_mass.sum() * G * THICKNESS
    top, gain = -np.inf, -np.inf
    for _ in range(int(1.5 * 240)):
        world.step()
        top = max(top, cloth.particle_position_numpy()[:, 2].max())
        gain = max(gain, cloth.kinetic_energy() + cloth.potential_energy() - e0)
    assert top <= z0 + THICKNESS
    assert gain <= lift
    # it lies on the plate: its middle one thickness above it (the skirt may fold under), and
    # nothing is caught in the sheet's layer
    x = cloth.particle_position_numpy()
    middle = [cloth.cloths[0].particle(i, j) for i in range(8, 16) for j in range(8, 16)]
    np.testing.assert_allclose(x[middle, 2], 0.4 + THICKNESS, atol=2e-3)
    over = (np.abs(x[:, 0]) < 0.3) & (np.abs(x[:, 1]) < 0.3)
    assert not (over & (np.abs(x[:, 2] - 0.4) < THICKNESS - 2e-3)).any()
