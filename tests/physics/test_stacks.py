"""Stacks at rest: the sag of a tower is the soft contacts' compliance, and Box3D's pyramid stands.

A soft contact (Catto's soft step, `tumble.solver.contacts.softness`) carrying a load F settles
where its bias makes up what the impulse scale relaxes each pass: at the overlap
slop + F / (m_n omega^2), omega = 2 pi f, f = CONTACT_HERTZ_PER_SUBSTEP_RATE / h (twice that
against a static body). So the overlap grows with the load over the contact's own effective
mass m_n, and a stack's sag with the square of its height: Box3D's 4,095-cube pyramid
(`benchmarks/scenes.py`, `large_pyramid`) sinks 0.54 m at dt = 1/60 s with 4 substeps
(f = 30 Hz), and 8 mm at 32 substeps (h = 1/1920 s, the default substep), Tumble's
recommended setting for tall stacks at dt = 1/60 s (docs/performance.md).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

import tumble
from tolerances import in_float32, ulps
from tumble.solver import contacts

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import quality, scenes  # noqa: E402

G = 10.0  # [m/s^2], Box3D's
DT = 1.0 / 60.0
RECOMMENDED_SUBSTEPS = scenes.LARGE_PYRAMID_SUBSTEPS  # at dt = 1/60 s: h = 1/1920 s


def cube_world(position: np.ndarray, substeps: int) -> tumble.World:
    """Cubes of 1 m and 1 kg at `position` on the ground plane, friction 0.6, no restitution (Box3D's)."""
    world = tumble.World(gravity=(0.0, 0.0, -G), dt=DT, substeps=substeps)
    world.add_plane(friction=scenes.LARGE_PYRAMID_FRICTION, restitution=0.0)
    world.add_boxes(
        position=position,
        half_extents=(0.5, 0.5, 0.5),
        mass=1.0,
        friction=scenes.LARGE_PYRAMID_FRICTION,
        restitution=0.0,
    )
    return world


def test_tower_sags_by_the_contact_compliance():
    """A tower of ten cubes rests with each joint overlapping F / (4 m_n omega^2), F the weight on it, and stays upright."""
    n, substeps = 10, 4
    start = np.stack([np.zeros(n), np.zeros(n), 0.5 + np.arange(n)], axis=1)
    world = cube_world(start, substeps)
    world.run(4.0)
    z = world.body_position[1:, 2]
    h = DT / substeps
    omega = 2.0 * math.pi * contacts.CONTACT_HERTZ_PER_SUBSTEP_RATE / h  # 30 Hz here; twice that on the ground
    # a face's four corners share its load; a corner row's effective mass (I = m a^2 / 6, |r x n|^2 = a^2 / 2
    # at a corner) is 1 / (1/m + 6/m * 1/2) = m / 4 against the ground and m / 8 between two cubes
    load = G * np.arange(n, 0, -1)  # on the ground joint, then on the joint below each cube
    m_n = np.r_[1.0 / 4.0, np.full(n - 1, 1.0 / 8.0)]
    stiffness = np.r_[4.0, np.ones(n - 1)] * omega**2  # (2 omega)^2 against the static ground
    expected = load / (4.0 * m_n * stiffness)  # a manifold's rows have no slop
    overlap = np.r_[0.5 - z[0], 1.0 - np.diff(z)]
    # the soft row's fixed point, v_n + bias + (isc / ms) j / m_n = 0 at rest, is exact; in float32 the
    # cubes' heights (to 10 m) rest within a few ulps of it (measured 8 ulps of 9.5 m at the ninth
    # joint, 0.7 % of its 1.1 mm), so each overlap, a difference of two heights, gets 16 ulps of 10 m
    np.testing.assert_allclose(overlap, expected, rtol=2e-3, atol=in_float32(0.0, ulps(float(n), 16)))
    # the whole sag (2.6 cm here) goes as the load times h^2; the tower does not lean
    assert start[-1, 2] - z[-1] == pytest.approx(np.sum(expected), rel=2e-3)
    assert np.hypot(*world.body_position[-1, :2]) < 1e-3
    assert world.kinetic_energy() < 1e-6  # at rest


def test_pyramid_stands_at_dt_1_60_with_the_recommended_substeps():
    """Box3D's pyramid with 20 cubes at the base keeps its top cube within 2 cm at dt = 1/60 s.

    At 4 substeps (Box3D's setting) the same pyramid sags 27 mm and its top sways a further 15 mm
    (the compliance above, 16 times larger).
    """
    start = scenes.large_pyramid_positions(20)
    world = cube_world(start, RECOMMENDED_SUBSTEPS)
    world.run(3.0)
    top = world.body_position[-1]
    # the sag of the compliance: 27 mm at 4 substeps / (32 / 4)^2, about 0.4 mm
    assert np.linalg.norm(top - start[-1]) < 0.02
    assert start[-1, 2] - top[2] < 27e-3 / (RECOMMENDED_SUBSTEPS / 4) ** 2 + 0.5e-3
    q = world.body_orientation[1:]
    assert quality.box_max_overlap(world.body_position[1:], q, np.full(3, 0.5)) < 1e-3
    assert world.kinetic_energy() < 1e-2


@pytest.mark.slow
def test_box3d_large_pyramid_stands_ten_seconds():
    """Box3D's large pyramid (4,095 cubes, 90 at the base) keeps its top cube within 2 cm for 10 s at dt = 1/60 s."""
    scene = scenes.SCENES["large_pyramid"]
    start = scenes.initial_bodies(scene).position
    world = cube_world(start, RECOMMENDED_SUBSTEPS)
    world.run(10.0)
    top = world.body_position[-1]
    assert np.linalg.norm(top - start[-1]) < scenes.LARGE_PYRAMID_TOP_TOLERANCE
