"""cloth/grid.py: the grid builder (positions, springs, triangles), named pins and tethers, on plain inputs."""

from __future__ import annotations

import numpy as np
import pytest

from tumble.cloth import grid

FACING_X = (0.5, 0.5, 0.5, 0.5)  # i -> +y, j -> +z, normal +x


def test_grid_positions_row_major_in_xy_plane():
    """Particle j * nx + i sits at grid point (i, j) of an xy-plane grid centred on the position."""
    x = grid.grid_positions((2.0, 1.0), (5, 3), (1.0, 2.0, 3.0), np.array([0.0, 0.0, 0.0, 1.0]))
    assert x.shape == (15, 3)
    assert x[0] == pytest.approx([0.0, 1.5, 3.0])
    assert x[1] == pytest.approx([0.5, 1.5, 3.0])  # i fastest, along x
    assert x[5] == pytest.approx([0.0, 2.0, 3.0])  # next row, along y
    assert x.mean(axis=0) == pytest.approx([1.0, 2.0, 3.0])


def test_grid_orientation_rotates_the_grid():
    """The quaternion (0.5, 0.5, 0.5, 0.5) maps grid i to +y, j to +z, the normal to +x."""
    x = grid.grid_positions((1.0, 1.0), (2, 2), (0, 0, 0), np.array(FACING_X))
    assert x[1] - x[0] == pytest.approx([0.0, 1.0, 0.0])
    assert x[2] - x[0] == pytest.approx([0.0, 0.0, 1.0])


@pytest.mark.parametrize("nx, ny", [(2, 2), (4, 3), (7, 5)])
def test_spring_and_triangle_counts(nx, ny):
    """Structural, shear and bend springs and triangles number as the grid dictates."""
    s = grid.grid_springs(nx, ny)
    assert len(s["structural"]) == (nx - 1) * ny + nx * (ny - 1)
    assert len(s["shear"]) == 2 * (nx - 1) * (ny - 1)
    assert len(s["bend"]) == max(nx - 2, 0) * ny + nx * max(ny - 2, 0)
    assert len(grid.grid_triangles(nx, ny)) == 2 * (nx - 1) * (ny - 1)


def test_triangles_face_plus_z():
    """Every triangle of an unrotated cloth is counter-clockwise seen from +z."""
    x = grid.grid_positions((1.0, 1.0), (6, 4), (0, 0, 0), np.array([0.0, 0.0, 0.0, 1.0]))
    t = grid.grid_triangles(6, 4)
    normal = np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]])
    assert np.all(normal[:, 2] > 0.0)
    assert t.dtype == np.int32


def test_pin_names_and_lists():
    """Named pins pick the right grid points; explicit [i, j] lists are honoured."""
    nx, ny = 4, 3
    assert list(grid.pin_indices("corners", nx, ny)) == [0, 3, 8, 11]
    assert list(grid.pin_indices("top-corners", nx, ny)) == [8, 11]
    assert list(grid.pin_indices("top-edge", nx, ny)) == [8, 9, 10, 11]
    assert list(grid.pin_indices([[1, 0], [2, 2]], nx, ny)) == [1, 10]
    assert len(grid.pin_indices(None, nx, ny)) == 0


@pytest.mark.parametrize("pins", ["sides", [[4, 0]], [[0, -1]], [[1]], [[0.5, 1]]])
def test_bad_pins_raise(pins):
    """Unknown names and grid points outside the cloth raise ValueError."""
    with pytest.raises(ValueError):
        grid.pin_indices(pins, 4, 3)


def test_tethers_tie_free_particles_to_nearest_pins():
    """Tethers join every free particle to its nearest pins with limit (1 + s) x rest distance."""
    rest = grid.grid_positions((1.0, 1.0), (3, 3), (0, 0, 0), np.array([0.0, 0.0, 0.0, 1.0]))
    pinned = np.array([6, 8])
    particle, pin, limit = grid.tethers(rest, pinned, 0.1)
    assert set(particle) == set(range(9)) - {6, 8}
    assert len(particle) == 2 * 7
    k = np.nonzero((particle == 0) & (pin == 6))[0][0]
    assert limit[k] == pytest.approx(1.1 * 1.0)


@pytest.mark.parametrize("nx, ny", [(2, 2), (6, 4), (7, 5)])
def test_triangle_shares_give_each_particle_the_area_it_carries(nx, ny):
    """Each triangle starts at its right angle, and half of its area to that corner and a quarter to
    each other one gives every particle the area share its mass is given (a quarter of each quad)."""
    size = (1.2, 0.7)
    x = grid.grid_positions(size, (nx, ny), (0, 0, 0), np.array([0.0, 0.0, 0.0, 1.0]))
    t = grid.grid_triangles(nx, ny)
    e1, e2 = x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]]
    np.testing.assert_allclose(np.einsum("ij,ij->i", e1, e2), 0.0, atol=1e-12)  # right angle first
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    carried = np.zeros(nx * ny)
    for corner, share in enumerate(grid.TRIANGLE_LOAD_SHARES):
        np.add.at(carried, t[:, corner], share * area)
    np.testing.assert_allclose(carried / (size[0] * size[1]), grid.grid_area_shares(nx, ny), rtol=1e-12)


@pytest.mark.parametrize("nx, ny", [(2, 1), (6, 1), (5, 5), (7, 6)])
def test_no_particle_has_more_spring_stiffness_per_mass_than_an_inner_one(nx, ny):
    """Border springs at half strength against border particles of half the mass (corners a quarter):
    structural and shear springs give every particle the same stiffness per mass, and with the bend
    springs (which particles next to a border have fewer of) none has more than an inner particle,
    so the stable substep is an inner particle's, as with even masses and full-strength springs."""
    springs, shares, mass = grid.grid_springs(nx, ny), grid.grid_spring_shares(nx, ny), grid.grid_area_shares(nx, ny)
    for kind in ("structural", "shear", "bend"):
        assert len(shares[kind]) == len(springs[kind])

    def per_mass(kinds) -> np.ndarray:
        stiffness = np.zeros(nx * ny)
        for kind, k in kinds:
            for end in (0, 1):
                np.add.at(stiffness, springs[kind][:, end], k * shares[kind])
        return stiffness / mass

    lines = per_mass([("structural", 12.0), ("shear", 1.2)])
    np.testing.assert_allclose(lines, lines.max(), rtol=1e-12)
    full = per_mass([("structural", 12.0), ("shear", 1.2), ("bend", 0.3)])
    inner = full[(ny // 2) * nx + nx // 2]
    assert full.max() == pytest.approx(inner, rel=1e-12)
