"""Analytic checks of the particle engine: free fall, bounces, sliding, collisions, piles, tunnelling.

Time steps are powers of two or 1/240 s; tolerances are derived from the substep h = dt / substeps
where the scheme's error is known (semi-implicit Euler is first order: O(v h) per bounce).
"""

from __future__ import annotations

import numpy as np
import pytest

import tumble
from tolerances import in_float32, ulps

G = 9.81


def test_free_fall_matches_parabola():
    """Free fall follows z0 - g t^2 / 2 to within the integrator's first-order error g h t / 2."""
    dt, substeps = 2.0**-8, 4
    h = dt / substeps
    w = tumble.World(dt=dt, substeps=substeps)
    w.add_sphere(position=(0, 0, 10.0), radius=0.1, mass=1.0)
    steps = w.run(1.0)
    t = steps * dt
    n = steps * substeps
    z = w.body_position[0, 2]
    # semi-implicit Euler: z_n = z0 - g h^2 n (n + 1) / 2 exactly (up to rounding: an ulp of z0 per substep
    # for x += v h, n in all)
    fall = in_float32(1e-12, ulps(10.0, n))
    assert z == pytest.approx(10.0 - G * h * h * n * (n + 1) / 2, abs=fall)
    # analytic parabola z0 - g t^2 / 2, within g h t / 2
    assert abs(z - (10.0 - G * t * t / 2)) <= G * h * t / 2 + fall
    # v += g h in each substep: an ulp of |v| (<= g t) each
    assert w.body_velocity[0, 2] == pytest.approx(-G * t, rel=1e-12, abs=in_float32(0.0, ulps(G * t, n)))


def test_bounce_apexes_scale_with_e_squared():
    """A ball dropped from 1 m with e = 0.5 rises to 0.25, 0.0625, 0.0156 m (within 2 %)."""
    dt, substeps = 1.0 / 240.0, 16
    h = dt / substeps
    r = 0.1
    w = tumble.World(dt=dt, substeps=substeps)
    w.add_plane(restitution=0.5)
    w.add_sphere(position=(0, 0, 1.0 + r), radius=r, mass=1.0, restitution=0.5)
    heights = []
    w.run(3.0, callback=lambda world: heights.append(world.body_position[1, 2] - r))
    z = np.array(heights)
    apex = [z[i] for i in range(1, len(z) - 1) if z[i - 1] < z[i] >= z[i + 1] and z[i] > 1e-3]
    for k, measured in enumerate(apex[:3], start=1):
        expected = 0.5 ** (2 * k)  # h_k = e^(2k) h0
        # first-order error of the bounce: about (v_in + v_out) h per bounce, v = sqrt(2 g h)
        v = np.sqrt(2 * G * expected)
        assert abs(measured - expected) <= min(0.02 * expected, 3 * v * h), (k, measured, expected)
    assert len(apex) >= 3


def test_box_slides_v2_over_2_mu_g():
    """A box sliding at 2 m/s with mu = 0.5 stops after v^2 / (2 mu g) = 0.408 m (within 2 %)."""
    w = tumble.World()
    w.add_plane(friction=0.5, restitution=0.0)
    w.add_box(
        position=(0, 0, 0.1),
        half_extents=(0.1, 0.1, 0.1),
        mass=1.0,
        velocity=(2.0, 0, 0),
        friction=0.5,
        restitution=0.0,
    )
    w.run(1.0)  # stops after v / (mu g) = 0.41 s
    expected = 2.0**2 / (2 * 0.5 * G)
    assert w.body_position[1, 0] == pytest.approx(expected, rel=0.02)
    assert np.linalg.norm(w.body_velocity[1]) < 1e-6
    assert abs(w.body_position[1, 1]) < 1e-3


def test_equal_spheres_swap_velocities_head_on():
    """An elastic head-on collision of equal spheres swaps their velocities."""
    w = tumble.World(gravity=(0, 0, 0), restitution_threshold=0.0)
    w.add_sphere(position=(-0.5, 0, 0), radius=0.1, mass=1.0, velocity=(1.0, 0, 0), restitution=1.0, friction=0)
    w.add_sphere(position=(0.5, 0, 0), radius=0.1, mass=1.0, velocity=(-1.0, 0, 0), restitution=1.0, friction=0)
    w.run(1.0)
    np.testing.assert_allclose(w.body_velocity[0], [-1.0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(w.body_velocity[1], [1.0, 0, 0], atol=1e-9)


def _cloud(seed: int, count: int = 40, restitution: float = 1.0):
    """Spheres of mixed masses flying about with no gravity and no walls."""
    rng = np.random.default_rng(seed)
    w = tumble.World(gravity=(0, 0, 0), seed=seed)
    side = int(np.ceil(count ** (1 / 3)))
    for i in range(count):
        p = 0.3 * np.array([i % side, (i // side) % side, i // side**2]) + rng.uniform(-0.03, 0.03, 3)
        w.add_sphere(
            position=p,
            radius=0.1,
            mass=rng.uniform(0.5, 2.0),
            velocity=rng.normal(0, 1.0, 3),
            angular_velocity=rng.normal(0, 3.0, 3),
            restitution=restitution,
            friction=0.5,
        )
    return w


def test_momentum_is_conserved_in_collisions():
    """Total linear momentum of colliding spheres is conserved to 1e-9 relative."""
    w = _cloud(seed=1)
    p0 = w.momentum()
    contacts = 0
    for _ in range(240):
        w.step()
        contacts += w.contact_count
    assert contacts > 0
    scale = np.sum(w.body_mass * np.linalg.norm(w.body_velocity, axis=1))
    # float32: each contact's impulse reaches its two bodies in each substep, rounding each one's velocity
    # by up to an ulp: 2 ulps of the largest body's momentum per contact and substep (measured: 3.9e-6, 5e-8
    # of the scale, against 2.4e-3 allowed)
    largest = np.max(w.body_mass * np.linalg.norm(w.body_velocity, axis=1))
    assert np.linalg.norm(w.momentum() - p0) <= in_float32(1e-9 * scale, ulps(largest, 2 * contacts * w.substeps))


@pytest.mark.parametrize("restitution", [0.0, 0.5, 1.0])
def test_collisions_never_add_kinetic_energy(restitution):
    """No step of free collisions raises the kinetic energy (no gravity, so none is supplied)."""
    w = _cloud(seed=2, restitution=restitution)
    energy = w.kinetic_energy()
    # float32: a colliding body's velocity is rounded by up to an ulp in each substep, its energy by 2 ulps
    # (measured: 1.2e-9 of the energy at most, in a step, against 1.9e-6 allowed)
    gain = in_float32(1e-9, ulps(1.0, 2 * w.substeps))
    for _ in range(240):
        w.step()
        e = w.kinetic_energy()
        assert e <= energy * (1 + gain)
        energy = e


def sphere_pile(count: int, *, seed: int = 0, half_width: float = 0.5, radius: float = 0.05):
    """Spheres on a jittered grid above a box of 5 planes (ground and 4 walls)."""
    w = tumble.World(seed=seed)
    w.add_plane(restitution=0.5, friction=0.5)
    for normal in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)):
        w.add_plane(normal=normal, offset=-half_width, restitution=0.5, friction=0.5)
    rng = np.random.default_rng(seed)
    pitch = 2 * radius + 0.01
    side = int((2 * half_width - 0.02) // pitch)
    for i in range(count):
        ix, iy, iz = i % side, (i // side) % side, i // side**2
        p = np.array(
            [
                -half_width + 0.01 + radius + ix * pitch,
                -half_width + 0.01 + radius + iy * pitch,
                radius + 0.05 + iz * pitch,
            ]
        ) + rng.uniform(-0.004, 0.004, 3) * [1, 1, 0]
        w.add_sphere(position=p, radius=radius, mass=0.1, restitution=0.5, friction=0.5)
    return w


def test_sphere_pile_comes_to_rest():
    """1,000 spheres in a 1 m box settle: KE < 0.02 J at 3 s, overlaps < 1 mm, all inside."""
    r = 0.05
    w = sphere_pile(1000, radius=r)
    w.run(3.0)
    x = w.body_position[5:]
    assert w.kinetic_energy() < 0.02
    # largest overlap between spheres, via the contacts the engine itself found
    w.collide()
    pairs = w.contact_pair
    both = (pairs[:, 0] >= 5) & (pairs[:, 1] >= 5)
    d = np.linalg.norm(w.body_position[pairs[both, 0]] - w.body_position[pairs[both, 1]], axis=1)
    assert np.max(2 * r - d) < 1e-3
    # ground and walls: no sphere through them by 1 mm or more
    assert np.min(x[:, 2]) - r > -1e-3
    assert np.max(np.abs(x[:, :2])) + r < 0.5 + 1e-3


def test_fast_sphere_does_not_tunnel_through_ground():
    """A sphere thrown at the ground at 50 m/s stops on it (speculative contacts)."""
    w = tumble.World()
    w.add_plane(restitution=0.0)
    w.add_sphere(position=(0, 0, 0.5), radius=0.05, mass=1.0, velocity=(0, 0, -50.0), restitution=0.0)
    lowest = []
    w.run(0.5, callback=lambda world: lowest.append(world.body_position[1, 2]))
    assert min(lowest) > 0.05 - 1e-3
    assert w.body_position[1, 2] == pytest.approx(0.05, abs=1e-3)


def test_rest_has_no_jitter():
    """A resting ball stays exactly still: no bounce counter needed, no creeping."""
    w = tumble.World()
    w.add_plane(restitution=0.9)
    w.add_sphere(position=(0, 0, 0.1), radius=0.1, mass=1.0, restitution=0.9)
    w.run(1.0)
    z1 = w.body_position[1, 2]
    w.run(2.0)
    assert abs(w.body_position[1, 2] - z1) < 1e-7
    assert np.linalg.norm(w.body_velocity[1]) < 1e-6
