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
