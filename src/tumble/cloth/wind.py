"""Wind: a mean velocity plus seeded, smooth, time-varying turbulence, and the air force on cloth.

The turbulence is a sum of K random Fourier modes carried along by the mean wind (so gusts
travel downwind), each with its own slow oscillation::

    u(x, t) = U + s sqrt(6 / K) sum_k d_k sin(kappa_k . (x - U t) + omega_k t + phi_k)

with unit directions d_k, wave vectors |kappa_k| in [0.5, 2] 2 pi / scale, frequencies
omega_k in [0.5, 1.5] 2 pi max(s, 0.1 |U|) / scale and phases phi_k all drawn from `seed`.
Each component then has an RMS of s (the turbulence strength [m/s]) and the field varies
over distances of about `scale` [m]; it is smooth in space and time, not white noise.

Stages:
- `sample_wind` evaluates u at every particle once per world step (cost O(P K)).
- `accumulate_air_forces` adds, per triangle, the air force of its relative velocity
  u_rel = u - v (averaged over its three particles) to its particles (cost O(T) per substep),
  half to the triangle's right-angle corner (its first) and a quarter to each other corner, so
  each particle takes the air force on the area it carries the mass of (`grid.grid_area_shares`):
  a flat cloth in a steady face-on flow accelerates evenly and stays flat.
  With n the unit normal, A the area, u_n = u_rel . n and rho the air density:

      drag  F_d = 1/2 rho C_d A |u_n| u_n n                 (pressure on the face)
      lift  F_l = 1/2 rho C_l A |u_rel| u_n (n - u_n u_rel / |u_rel|^2)

  Both vanish when the cloth is edge-on to the wind (u_n = 0) and are largest face-on (drag)
  or at 45 degrees (lift); both are even in n, so the triangle winding does not matter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from .. import validate
from ..launch import LaunchCache, each_end, launch_each, vector
from ..real import float_t, vec3
from ..structs import array_struct
from .arrays import Particles, corners

# no adjoint code: nothing differentiates through Tumble's kernels, and it doubles the compile time
wp.set_module_options({"enable_backward": False})

#: classes without kernels that the float32 copy of this module shares (tumble.precision)
__shared__ = ("Wind",)

AIR_DENSITY = 1.2  # [kg/m^3] at sea level, 20 C

#: the turbulence's Fourier modes on the device (`Wind.mode_arrays`), one row per mode
MODE_FIELDS = {
    "mode_wave": vec3,  # wave vector kappa_k [1/m]
    "mode_amplitude": vec3,  # amplitude a_k [m/s]
    "mode_omega": float_t,  # frequency omega_k [rad/s]
    "mode_phase": float_t,  # phase phi_k [rad]
}
#: the modes as the kernels take them: `mode_wave` is `modes.wave`
Modes = array_struct("Modes", MODE_FIELDS, "mode_", __name__)


@dataclass
class Wind:
    """Wind acting on cloth.

    Args:
        velocity: mean wind velocity U [m/s], shape (3,).
        turbulence: RMS strength s of the turbulent part per component [m/s] (0 = steady wind).
        scale: length scale of the turbulent eddies [m], > 0.
        seed: seed of the turbulence field.
        drag: drag coefficient C_d of a cloth face (flat plate about 1.2).
        lift: lift coefficient C_l.
        air_density: rho [kg/m^3].
        modes: number K of Fourier modes of the turbulence.
    """

    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    turbulence: float = 0.0
    scale: float = 1.0
    seed: int = 0
    drag: float = 1.2
    lift: float = 0.3
    air_density: float = AIR_DENSITY
    modes: int = 8

    def __post_init__(self):
        self.velocity = validate.vector(self.velocity, "wind velocity")
        for name in ("turbulence", "drag", "lift", "air_density"):
            setattr(self, name, validate.number(getattr(self, name), f"wind {name}", low=0.0))
        self.scale = validate.positive(self.scale, "wind scale")
        self.modes = validate.integer(self.modes, "wind modes", low=1)
        self.seed = validate.seed(self.seed, "wind seed")

    def mode_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The seeded modes: wave vectors (K, 3) [1/m], amplitude vectors (K, 3) [m/s],
        frequencies (K,) [rad/s], phases (K,) [rad]."""
        rng = np.random.default_rng(self.seed)
        k = self.modes

        def unit(n):
            a = rng.normal(size=(n, 3))
            return a / np.linalg.norm(a, axis=1, keepdims=True)

        wave = unit(k) * (rng.uniform(0.5, 2.0, size=(k, 1)) * 2.0 * np.pi / self.scale)
        amplitude = unit(k) * (self.turbulence * np.sqrt(6.0 / k))
        speed = max(self.turbulence, 0.1 * float(np.linalg.norm(self.velocity)), 1e-3)
        omega = rng.uniform(0.5, 1.5, size=k) * 2.0 * np.pi * speed / self.scale
        phase = rng.uniform(0.0, 2.0 * np.pi, size=k)
        return wave, amplitude, omega, phase

    def sample(self, points: np.ndarray, t: float) -> np.ndarray:
        """Wind velocity [m/s] at `points` (n, 3) and time `t` [s], on the host (for tests and plots)."""
        wave, amplitude, omega, phase = self.mode_arrays()
        arg = (np.asarray(points) - self.velocity * t) @ wave.T + omega * t + phase
        return self.velocity + np.sin(arg) @ amplitude


@wp.kernel
def _sample_wind(particles: Particles, mean: vec3, modes: Modes, t: float_t, serial: int):
    x = particles.position
    for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        # u = U + sum_k a_k sin(kappa_k . (x - U t) + omega_k t + phi_k)
        xt = x[p] - mean * t
        acc = mean
        k = int(0)
        while k < modes.wave.shape[0]:
            acc = acc + modes.amplitude[k] * wp.sin(wp.dot(modes.wave[k], xt) + modes.omega[k] * t + modes.phase[k])
            k += 1
        particles.wind[p] = acc


@wp.kernel
def _air_forces(
    particles: Particles, tris: wp.array2d(dtype=wp.int32), half_rho_cd: float_t, half_rho_cl: float_t, serial: int
):
    x = particles.position
    v = particles.velocity
    u = particles.wind
    for t in range(wp.tid(), each_end(wp.tid(), serial, tris.shape[0])):
        a, b, c = corners(tris, t)
        cross = wp.cross(x[b] - x[a], x[c] - x[a])
        twice_area = wp.length(cross)
        if twice_area <= float_t(1.0e-15):
            continue
        n = cross / twice_area
        area = float_t(0.5) * twice_area
        third = float_t(1.0) / float_t(3.0)
        rel = (u[a] + u[b] + u[c] - v[a] - v[b] - v[c]) * third
        un = wp.dot(rel, n)
        speed2 = wp.dot(rel, rel)
        # drag 1/2 rho Cd A |u_n| u_n n, lift 1/2 rho Cl A |u| u_n (n - u_n u / |u|^2)
        force = n * (half_rho_cd * area * wp.abs(un) * un)
        if speed2 > float_t(1.0e-20):
            speed = wp.sqrt(speed2)
            force = force + (n - rel * (un / speed2)) * (half_rho_cl * area * speed * un)
        # the right-angle corner (first) takes half, the others a quarter each: the quad's
        # quarters, as the particles' masses (grid.TRIANGLE_LOAD_SHARES, grid.grid_area_shares)
        quarter = force * float_t(0.25)
        wp.atomic_add(particles.force, a, quarter + quarter)
        wp.atomic_add(particles.force, b, quarter)
        wp.atomic_add(particles.force, c, quarter)


def sample_wind(particles: Particles, mean, modes: Modes, t, *, cache: LaunchCache | None = None):
    """Evaluate the wind field at every particle, into `particles.wind` [m/s].

    Args:
        particles: the particle arrays (reads `position`, writes `wind`).
        mean: mean wind U [m/s], shape (3,).
        modes: the turbulence's modes (`Modes`, over the arrays of `Wind.mode_arrays`).
        t: time [s].
    """
    x = particles.position
    launch_each(_sample_wind, x.shape[0], [particles, vector(mean), modes, float(t)], x.device, cache)


def accumulate_air_forces(
    particles: Particles, triangles, drag, lift, air_density, *, cache: LaunchCache | None = None
):
    """Add the drag and lift of every triangle into `particles.force` [N]: half to its first (right-angle)
    corner, a quarter to each other one.

    Args:
        particles: the particle arrays (reads `position`, `velocity` and the `wind` at each particle).
        triangles: particle indices, shape (T, 3) int32.
        drag, lift: coefficients C_d, C_l.
        air_density: rho [kg/m^3].
    """
    count = triangles.shape[0]
    if count:
        inputs = [particles, triangles, 0.5 * air_density * drag, 0.5 * air_density * lift]
        launch_each(_air_forces, count, inputs, triangles.device, cache)
