"""Spring forces, semi-implicit Euler integration and Provot's stretch limit for cloth particles.

Stage functions over the particle and spring arrays, as the structs of `arrays` (`Particles`,
`Springs`, ...):

- `accumulate_spring_forces` reads positions and velocities, adds every spring's force into
  `particle_force` (one thread per spring, scattered with atomics; on the CPU one thread loops
  over the springs in order, so the sum order and the result are deterministic). Cost O(springs).
- `integrate` turns forces into velocities and positions (semi-implicit Euler), moves pins.
- `limit_stretch` pulls over-stretched structural springs back to (1 + max_stretch) l0,
  Gauss-Seidel style, over-relaxed after two sweeps. Cost O(structural springs x iterations).
- `update_velocities` sets v = (x - x_prev) / h so position corrections show in velocities.

Explicit springs are stable only while h^2 k / m is small; `stable_substep` gives the largest
stable step for given stiffness and mass, from which `ClothSystem` picks its internal substeps.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..launch import LaunchCache, each_end, launch_each, vector
from ..real import float_t, vec3
from .arrays import Particles, Springs, Stretch, Structural, Tethers
from .attach import Carried, carried_inverse_mass, carried_pin, carried_position, carry

# no adjoint code: nothing differentiates through Tumble's kernels, and it doubles the compile time
wp.set_module_options({"enable_backward": False})


@wp.kernel
def _spring_forces(particles: Particles, springs: Springs, serial: int):
    x = particles.position
    v = particles.velocity
    for s in range(wp.tid(), each_end(wp.tid(), serial, springs.ids.shape[0])):
        i = springs.ids[s, 0]
        j = springs.ids[s, 1]
        d = x[j] - x[i]
        length = wp.length(d)
        if length > float_t(1.0e-12):
            n = d / length
            # f_i = n [ks (|xj - xi| - l0) + kd (vj - vi) . n],  f_j = -f_i
            fs = n * (
                springs.stiffness[s] * (length - springs.rest_length[s]) + springs.damping[s] * wp.dot(v[j] - v[i], n)
            )
            wp.atomic_add(particles.force, i, fs)
            wp.atomic_sub(particles.force, j, fs)


@wp.kernel
def _integrate(particles: Particles, gravity: vec3, h: float_t, pin_alpha: float_t, serial: int):
    x = particles.position
    v = particles.velocity
    f = particles.force
    for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        xp = x[p]
        particles.position_prev[p] = xp
        w = particles.inv_mass[p]
        if w > float_t(0.0):
            # semi-implicit Euler: v += h (g + w f); x += h v
            vp = v[p] + h * (gravity + w * (f[p] + particles.external_force[p]))
            v[p] = vp
            x[p] = xp + h * vp
        else:
            # pinned: move a fraction of the way to the target, reaching it at the end of the step
            x[p] = xp + pin_alpha * (particles.pin_target[p] - xp)
        f[p] = vec3(float_t(0.0))


@wp.func
def _carried_end(carried: Carried, p: int, x: vec3, w: float_t):
    """Particle p (at x, inverse mass w) as a spring end: its position and its pin row on a dynamic body
    (-1: none); a carried pin is where the corrections so far have moved its body. (Called only where a
    body carries pins: the sweeps of a cloth without any read nothing more than before.)"""
    k = carried_pin(carried, p, w)
    if k >= 0:
        return carried_position(carried, k, x), k
    return x, k


def _make_limit_stretch(carrying: bool):
    """`_limit_stretch`, with pins on bodies (`carrying`: they give way with their bodies) or without (a
    cloth without body pins, whose sweeps then compile as they did before there were any: the test for
    them in every spring cost its stretch limit 9 %)."""

    @wp.kernel(name="_limit_stretch_carrying" if carrying else "_limit_stretch")
    def limit(
        particles: Particles,
        stretch: Stretch,
        carried: Carried,
        margin: float_t,
        relax: float_t,
        reverse: int,
        serial: int,
    ):
        x = particles.position
        inv_m = particles.inv_mass
        pin_load = particles.pin_load
        count = stretch.ids.shape[0]
        for k in range(wp.tid(), each_end(wp.tid(), serial, count)):
            s = k
            if reverse != 0:
                s = count - 1 - k
            i = stretch.ids[s, 0]
            j = stretch.ids[s, 1]
            wi = inv_m[i]
            wj = inv_m[j]
            xi = x[i]
            xj = x[j]
            ki = int(-1)
            kj = int(-1)
            if wp.static(carrying):
                xi, ki = _carried_end(carried, i, xi, wi)
                xj, kj = _carried_end(carried, j, xj, wj)
            if wi + wj <= float_t(0.0) and ki < 0 and kj < 0:
                continue
            d = xj - xi
            length = wp.length(d)
            # Provot: a spring longer than its limit is shortened to margin * limit (slightly inside, so
            # that the sweeps converge to "no spring over the limit"), both ends moving along the spring
            # in proportion to their inverse masses; a pin on a dynamic body gives way by its body's
            # inverse mass at the pin along the spring
            target = stretch.limit[s] * margin
            excess = length - target
            if excess > float_t(0.0):
                w = wi + wj
                if wp.static(carrying):
                    if ki >= 0:
                        w += carried_inverse_mass(carried, ki, d / length)
                    if kj >= 0:
                        w += carried_inverse_mass(carried, kj, d / length)
                c = d * (excess * relax / (length * w))
                wp.atomic_add(x, i, c * wi)
                wp.atomic_sub(x, j, c * wj)
                # a pinned end feels the free end's pull, its momentum change times h: m_j (c w_j) = c [kg m];
                # a dynamic body carrying it moves by its response to that impulse
                if wi == float_t(0.0):
                    wp.atomic_add(pin_load, i, c)
                    if wp.static(carrying):
                        if ki >= 0:
                            carry(carried, ki, c)
                if wj == float_t(0.0):
                    wp.atomic_sub(pin_load, j, c)
                    if wp.static(carrying):
                        if kj >= 0:
                            carry(carried, kj, -c)

    return limit


#: the stretch limit's sweep, by whether a body carries pins
_LIMIT_STRETCH = {carrying: _make_limit_stretch(carrying) for carrying in (False, True)}


def _make_over_limit(carrying: bool):
    """`_over_limit`, with pins on bodies or without (as `_make_limit_stretch`)."""

    @wp.kernel(name="_over_limit_carrying" if carrying else "_over_limit")
    def over(particles: Particles, stretch: Stretch, carried: Carried, violated: wp.array(dtype=wp.int32), serial: int):
        x = particles.position
        ids = stretch.ids
        for s in range(wp.tid(), each_end(wp.tid(), serial, ids.shape[0])):
            # one spring over its limit settles the answer: on the CPU, where the springs are checked
            # in order, the rest of the check is then skipped
            if violated[0] != 0:
                return
            i = ids[s, 0]
            j = ids[s, 1]
            xi = x[i]
            xj = x[j]
            if wp.static(carrying):
                xi, ki = _carried_end(carried, i, xi, particles.inv_mass[i])
                xj, kj = _carried_end(carried, j, xj, particles.inv_mass[j])
            if wp.length(xj - xi) > stretch.limit[s]:
                violated[0] = 1

    return over


_OVER_LIMIT = {carrying: _make_over_limit(carrying) for carrying in (False, True)}


@wp.kernel
def _update_velocities(particles: Particles, inv_h: float_t, serial: int):
    x = particles.position
    for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
        particles.velocity[p] = (x[p] - particles.position_prev[p]) * inv_h


@wp.kernel
def _strain(particles: Particles, structural: Structural, strain: wp.array(dtype=float_t), serial: int):
    x = particles.position
    ids = structural.ids
    for s in range(wp.tid(), each_end(wp.tid(), serial, ids.shape[0])):
        strain[s] = wp.length(x[ids[s, 1]] - x[ids[s, 0]]) / structural.rest_length[s] - float_t(1.0)


def accumulate_spring_forces(particles: Particles, springs: Springs, *, cache: LaunchCache | None = None):
    """Add every spring's force into `particles.force` [N], from the positions and velocities.

    Args:
        particles: the particle arrays (reads `position`, `velocity`; adds to `force`).
        springs: the springs (`ids`, `rest_length`, `stiffness`, `damping`).
    """
    m = springs.ids.shape[0]
    if m:
        launch_each(_spring_forces, m, [particles, springs], particles.position.device, cache)


def integrate(particles: Particles, gravity, h, pin_alpha, *, cache: LaunchCache | None = None):
    """Semi-implicit Euler for free particles; pinned ones (inverse mass 0) move towards their target.

    Stores the start positions in `position_prev` and clears `force` for the next substep.

    Args:
        particles: the particle arrays (reads `force`, `external_force`, `inv_mass`, `pin_target`;
            moves `position`, `velocity`).
        gravity: [m/s^2], shape (3,).
        h: substep [s].
        pin_alpha: fraction of the remaining way to the pin target covered by this substep.
    """
    x = particles.position
    launch_each(_integrate, x.shape[0], [particles, vector(gravity), float(h), float(pin_alpha)], x.device, cache)


def limit_stretch(
    particles: Particles,
    stretch: Stretch,
    violated,
    carried: Carried,
    *,
    min_iterations: int = 2,
    max_iterations: int = 32,
    margin: float = 0.99,
    relax: float = 1.0,
    plain: int = 2,
    cache: LaunchCache | None = None,
) -> int:
    """Provot's deformation constraint: springs longer than their limit are shortened to it.

    Gauss-Seidel sweeps over the springs (plain ones alternate direction, over-relaxed ones keep
    one order: alternating made them cycle above the limit on a hard swing): `min_iterations`
    sweeps, then a check, then two more sweeps while some spring is still over its limit, at most
    `max_iterations` sweeps. (A flag raised inside a sweep would not do: every sweep briefly
    over-stretches springs it corrects later in the same sweep.)

    Args:
        particles: the particle arrays: `position` is corrected in place (weighted by `inv_mass`),
            and `pin_load` adds, on pinned particles, the corrections' pull on them lambda u [kg m]
            (divided by the substep it is the impulse the pins take).
        stretch: the limited (structural) springs and their largest lengths (1 + max_stretch) l0.
        violated: scratch flag, shape (1,) int32.
        carried: the pins on dynamic bodies (`BodyPins.carried`): they give way by their body's
            inverse mass at the pin, and the corrections move the body (its pending shift and turn).
        min_iterations, max_iterations: bounds on the number of sweeps (0: check first, sweep only
            if some spring is over its limit).
        margin: over-long springs are shortened to margin * limit, so that the sweeps end
            inside the limit rather than creeping up to it.
        relax: successive over-relaxation factor of the corrections (1 = exact projection) from
            sweep `plain` on.
        cache: recorded launches to replay.

    Returns:
        The number of sweeps taken.
    """
    count = stretch.ids.shape[0]
    if count == 0 or max_iterations <= 0:
        return 0
    device = particles.position.device
    flag = violated.numpy() if violated.device.is_cpu else None
    it = 0
    target = max(0, min_iterations)
    while True:
        while it < min(target, max_iterations):
            # plain projections first (enough for cloth that is barely over its limit), then
            # over-relaxed ones, which converge much faster where the whole cloth is taut
            sweep = [particles, stretch, carried, margin, 1.0 if it < plain else relax, it % 2 if relax == 1.0 else 0]
            launch_each(_LIMIT_STRETCH[carried.count > 0], count, sweep, device, cache)
            it += 1
        if it >= max_iterations:
            return it
        violated.zero_()
        launch_each(_OVER_LIMIT[carried.count > 0], count, [particles, stretch, carried, violated], device, cache)
        if int((flag if flag is not None else violated.numpy())[0]) == 0:
            return it
        target = it + 2


def update_velocities(particles: Particles, h, *, cache: LaunchCache | None = None):
    """Velocities from the corrected positions: v = (x - x_prev) / h."""
    x = particles.position
    launch_each(_update_velocities, x.shape[0], [particles, 1.0 / h], x.device, cache)


def strain(particles: Particles, structural: Structural, out) -> np.ndarray:
    """Strain (|xj - xi| - l0) / l0 of each structural spring, shape (s,), written into `out` and returned."""
    count = structural.ids.shape[0]
    if count:
        launch_each(_strain, count, [particles, structural, out], out.device)
    return out.numpy()[:count]


def stable_substep(particle_stiffness: np.ndarray, particle_damping: np.ndarray, inv_mass: np.ndarray) -> float:
    """Largest substep [s] for which explicit springs stay stable, with a 0.9 safety factor.

    By Gershgorin, the largest eigenvalues of the stiffness and damping terms of particle p are
    bounded by a = 2 K_p w_p and b = 2 D_p w_p, with K_p, D_p the sums of its springs' ks and kd.
    Symplectic Euler is stable for h^2 a <= 4 (undamped) and h b <= 2 (pure damping); we ask
    h^2 a / 4 + h b / 2 <= 1, whose positive root is h = (-b/2 + sqrt(b^2/4 + a)) / (a/2).

    Args:
        particle_stiffness: K_p [N/m], shape (P,).
        particle_damping: D_p [N s/m], shape (P,).
        inv_mass: w_p [1/kg], shape (P,).
    """
    with np.errstate(over="ignore"):  # an overflow (inf) gives a stable substep of 0 below
        a = 2.0 * particle_stiffness * inv_mass
        b = 2.0 * particle_damping * inv_mass
    active = (a > 0.0) | (b > 0.0)
    if not np.any(active):
        return np.inf
    a, b = a[active], b[active]
    with np.errstate(all="ignore"):
        h = np.where(a > 0.0, (-0.5 * b + np.sqrt(0.25 * b * b + a)) / (0.5 * a), 2.0 / np.where(b > 0, b, 1.0))
    # a or b so large (ks or kd near 1e300) that the root overflows: the stable substep is 0 to float64
    return 0.9 * float(np.min(np.where(np.isfinite(h), h, 0.0)))


def _make_limit_tethers(carrying: bool):
    """`_limit_tethers`, with pins on bodies or without (as `_make_limit_stretch`)."""

    @wp.kernel(name="_limit_tethers_carrying" if carrying else "_limit_tethers")
    def limit(particles: Particles, tethers: Tethers, carried: Carried, margin: float_t, serial: int):
        # one thread per particle, its tethers in turn: no two threads move the same particle, and
        # pins do not move but with a dynamic body carrying them (on CUDA, each thread then sees the
        # body moved by the threads before it, in no fixed order)
        x = particles.position
        inv_m = particles.inv_mass
        for p in range(wp.tid(), each_end(wp.tid(), serial, x.shape[0])):
            w = inv_m[p]
            if w <= float_t(0.0):
                continue
            xp = x[p]
            t0 = particles.tether_first[p]
            for t in range(t0, t0 + particles.tether_count[p]):
                a = tethers.pin[t]
                wa = inv_m[a]
                if wa <= float_t(0.0):
                    xa = x[a]
                    ka = int(-1)
                    if wp.static(carrying):
                        xa, ka = _carried_end(carried, a, xa, wa)
                    d = xp - xa
                    length = wp.length(d)
                    excess = length - tethers.limit[t] * margin
                    if excess > float_t(0.0):
                        # pull the particle back onto the sphere of radius margin * limit about the pin
                        # (a dynamic body's pin gives way by its share: the body's inverse mass at the pin)
                        dx = d * (excess / length)
                        if wp.static(carrying):
                            if ka >= 0:
                                dx = dx * (w / (w + carried_inverse_mass(carried, ka, d / length)))
                        xp = xp - dx
                        # the pin feels the particle's pull, m_p |dx| along the tether [kg m]
                        wp.atomic_add(particles.pin_load, a, dx / w)
                        if wp.static(carrying):
                            if ka >= 0:
                                carry(carried, ka, dx / w)
            x[p] = xp

    return limit


_LIMIT_TETHERS = {carrying: _make_limit_tethers(carrying) for carrying in (False, True)}


def limit_tethers(
    particles: Particles,
    tethers: Tethers,
    carried: Carried,
    *,
    margin: float = 0.99,
    cache: LaunchCache | None = None,
):
    """Long-range attachments: keep each free particle within its limit of its pins (see `grid.tethers`).

    Args:
        particles: the particle arrays: `position` is corrected in place; a tether acts only while
            its pin is pinned (`inv_mass` 0); `pin_load` adds the tethers' pull on their pins,
            m_p dx [kg m]; `tether_first`, `tether_count` give each particle's tethers.
        tethers: each tether's pin and largest length.
        carried: the pins on dynamic bodies (`BodyPins.carried`), as in `limit_stretch`.
        margin: particles are kept within margin * limit, the same margin as `limit_stretch`, so
            that a taut chain of springs between a particle and its pin fits inside both limits.
    """
    if tethers.pin.shape[0]:
        x = particles.position
        launch_each(
            _LIMIT_TETHERS[carried.count > 0], x.shape[0], [particles, tethers, carried, margin], x.device, cache
        )
