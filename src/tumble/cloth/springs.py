"""Spring forces, semi-implicit Euler integration and Provot's stretch limit for cloth particles.

Stage functions over particle and spring arrays:

- `accumulate_spring_forces` reads positions and velocities, adds every spring's force into
  `particle_force` (one thread per spring, scattered with atomics; on the CPU kernels run
  serially, so the sum order and the result are deterministic). Cost O(springs).
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

from ..launch import LaunchCache, launch
from ..real import float_t, vec3


@wp.struct
class Limits:
    """Each particle's limited (structural) springs: CSR rows `first`, `count`; per entry the other end and limit."""

    first: wp.array(dtype=wp.int32)
    count: wp.array(dtype=wp.int32)
    other: wp.array(dtype=wp.int32)
    length: wp.array(dtype=float_t)  # (1 + max_stretch) l0 [m]


@wp.kernel
def _spring_forces(
    x: wp.array(dtype=vec3),
    v: wp.array(dtype=vec3),
    ids: wp.array2d(dtype=wp.int32),
    rest: wp.array(dtype=float_t),
    ks: wp.array(dtype=float_t),
    kd: wp.array(dtype=float_t),
    f: wp.array(dtype=vec3),
):
    s = wp.tid()
    i = ids[s, 0]
    j = ids[s, 1]
    d = x[j] - x[i]
    length = wp.length(d)
    if length > float_t(1.0e-12):
        n = d / length
        # f_i = n [ks (|xj - xi| - l0) + kd (vj - vi) . n],  f_j = -f_i
        fs = n * (ks[s] * (length - rest[s]) + kd[s] * wp.dot(v[j] - v[i], n))
        wp.atomic_add(f, i, fs)
        wp.atomic_sub(f, j, fs)


@wp.kernel
def _integrate(
    x: wp.array(dtype=vec3),
    v: wp.array(dtype=vec3),
    x_prev: wp.array(dtype=vec3),
    f: wp.array(dtype=vec3),
    f_ext: wp.array(dtype=vec3),
    inv_m: wp.array(dtype=float_t),
    pin_target: wp.array(dtype=vec3),
    gravity: vec3,
    h: float_t,
    pin_alpha: float_t,
):
    p = wp.tid()
    xp = x[p]
    x_prev[p] = xp
    w = inv_m[p]
    if w > float_t(0.0):
        # semi-implicit Euler: v += h (g + w f); x += h v
        vp = v[p] + h * (gravity + w * (f[p] + f_ext[p]))
        v[p] = vp
        x[p] = xp + h * vp
    else:
        # pinned: move a fraction of the way to the target, reaching it at the end of the step
        x[p] = xp + pin_alpha * (pin_target[p] - xp)
    f[p] = vec3(float_t(0.0))


@wp.kernel
def _limit_stretch(
    x: wp.array(dtype=vec3),
    inv_m: wp.array(dtype=float_t),
    ids: wp.array2d(dtype=wp.int32),
    limit: wp.array(dtype=float_t),
    pin_load: wp.array(dtype=vec3),
    margin: float_t,
    relax: float_t,
    reverse: int,
):
    s = wp.tid()
    if reverse != 0:
        s = ids.shape[0] - 1 - s
    i = ids[s, 0]
    j = ids[s, 1]
    wi = inv_m[i]
    wj = inv_m[j]
    if wi + wj <= float_t(0.0):
        return
    d = x[j] - x[i]
    length = wp.length(d)
    # Provot: a spring longer than its limit is shortened to margin * limit (slightly inside, so
    # that the sweeps converge to "no spring over the limit"), both ends moving along the spring
    # in proportion to their inverse masses
    target = limit[s] * margin
    excess = length - target
    if excess > float_t(0.0):
        w = wi + wj
        c = d * (excess * relax / (length * w))
        wp.atomic_add(x, i, c * wi)
        wp.atomic_sub(x, j, c * wj)
        # a pinned end feels the free end's pull, its momentum change times h: m_j (c w_j) = c [kg m]
        if wi == float_t(0.0):
            wp.atomic_add(pin_load, i, c)
        if wj == float_t(0.0):
            wp.atomic_sub(pin_load, j, c)


@wp.kernel
def _over_limit(
    x: wp.array(dtype=vec3),
    ids: wp.array2d(dtype=wp.int32),
    limit: wp.array(dtype=float_t),
    violated: wp.array(dtype=wp.int32),
):
    # one spring over its limit settles the answer: on the CPU, where threads run in order,
    # the rest of the check is then skipped
    if violated[0] != 0:
        return
    s = wp.tid()
    if wp.length(x[ids[s, 1]] - x[ids[s, 0]]) > limit[s]:
        violated[0] = 1


@wp.kernel
def _update_velocities(
    x: wp.array(dtype=vec3),
    x_prev: wp.array(dtype=vec3),
    v: wp.array(dtype=vec3),
    inv_h: float_t,
):
    p = wp.tid()
    v[p] = (x[p] - x_prev[p]) * inv_h


@wp.kernel
def _strain(
    x: wp.array(dtype=vec3),
    ids: wp.array2d(dtype=wp.int32),
    rest: wp.array(dtype=float_t),
    strain: wp.array(dtype=float_t),
):
    s = wp.tid()
    strain[s] = wp.length(x[ids[s, 1]] - x[ids[s, 0]]) / rest[s] - float_t(1.0)


def accumulate_spring_forces(
    x, v, spring_ids, spring_rest_length, spring_stiffness, spring_damping, force, *, cache: LaunchCache | None = None
):
    """Add spring forces into `force`.

    Args:
        x: particle positions [m], shape (P,) vec3.
        v: particle velocities [m/s], shape (P,) vec3.
        spring_ids: particle pairs (i, j), shape (m, 2) int32.
        spring_rest_length: rest lengths l0 [m], shape (m,).
        spring_stiffness: ks [N/m], shape (m,).
        spring_damping: kd [N s/m], shape (m,).
        force: per-particle force accumulator [N], shape (P,) vec3 (added to).
    """
    m = spring_ids.shape[0]
    if m:
        launch(
            _spring_forces,
            m,
            [x, v, spring_ids, spring_rest_length, spring_stiffness, spring_damping, force],
            x.device,
            cache,
        )


def integrate(
    x,
    v,
    x_prev,
    force,
    external_force,
    inv_mass,
    pin_target,
    gravity,
    h,
    pin_alpha,
    *,
    cache: LaunchCache | None = None,
):
    """Semi-implicit Euler for free particles; pinned ones (inverse mass 0) move towards their target.

    Stores the start positions in `x_prev` and clears `force` for the next substep.

    Args:
        x, v, x_prev: positions [m], velocities [m/s], start positions [m], shape (P,) vec3.
        force: accumulated spring and wind forces [N], shape (P,) vec3.
        external_force: user forces for this step [N], shape (P,) vec3.
        inv_mass: inverse masses [1/kg], shape (P,); 0 = pinned.
        pin_target: where pinned particles should be at the end of the step [m], shape (P,) vec3.
        gravity: [m/s^2], shape (3,).
        h: substep [s].
        pin_alpha: fraction of the remaining way to the pin target covered by this substep.
    """
    launch(
        _integrate,
        x.shape[0],
        [x, v, x_prev, force, external_force, inv_mass, pin_target, vec3(*gravity), float(h), float(pin_alpha)],
        x.device,
        cache,
    )


def limit_stretch(
    x,
    inv_mass,
    stretch_ids,
    stretch_limit,
    violated,
    *,
    pin_load=None,
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
        x: particle positions [m], shape (P,) vec3 (corrected in place).
        inv_mass: inverse masses [1/kg], shape (P,).
        stretch_ids: particle pairs of the limited (structural) springs, shape (s, 2) int32.
        stretch_limit: largest allowed length (1 + max_stretch) l0 [m], shape (s,).
        violated: scratch flag, shape (1,) int32.
        pin_load: adds, on pinned particles, the corrections' pull on them lambda u [kg m], shape (P,)
            vec3 (divided by the substep it is the impulse the pins take; default: not kept).
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
    count = stretch_ids.shape[0]
    if count == 0 or max_iterations <= 0:
        return 0
    if pin_load is None:
        pin_load = wp.zeros(x.shape[0], dtype=vec3, device=x.device)
    flag = violated.numpy() if violated.device.is_cpu else None
    it = 0
    target = max(0, min_iterations)
    while True:
        while it < min(target, max_iterations):
            # plain projections first (enough for cloth that is barely over its limit), then
            # over-relaxed ones, which converge much faster where the whole cloth is taut
            launch(
                _limit_stretch,
                count,
                [
                    x,
                    inv_mass,
                    stretch_ids,
                    stretch_limit,
                    pin_load,
                    margin,
                    1.0 if it < plain else relax,
                    it % 2 if relax == 1.0 else 0,
                ],
                x.device,
                cache,
            )
            it += 1
        if it >= max_iterations:
            return it
        violated.zero_()
        launch(_over_limit, count, [x, stretch_ids, stretch_limit, violated], x.device, cache)
        if int((flag if flag is not None else violated.numpy())[0]) == 0:
            return it
        target = it + 2


def update_velocities(x, x_prev, v, h, *, cache: LaunchCache | None = None):
    """Velocities from the corrected positions: v = (x - x_prev) / h."""
    launch(_update_velocities, x.shape[0], [x, x_prev, v, 1.0 / h], x.device, cache)


def strain(x, ids, rest, out) -> np.ndarray:
    """Strain (|xj - xi| - l0) / l0 of each spring, shape (m,), written into `out` and returned."""
    if ids.shape[0]:
        wp.launch(_strain, dim=ids.shape[0], inputs=[x, ids, rest, out], device=x.device)
    return out.numpy()[: ids.shape[0]]


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
    a = 2.0 * particle_stiffness * inv_mass
    b = 2.0 * particle_damping * inv_mass
    active = (a > 0.0) | (b > 0.0)
    if not np.any(active):
        return np.inf
    a, b = a[active], b[active]
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(a > 0.0, (-0.5 * b + np.sqrt(0.25 * b * b + a)) / (0.5 * a), 2.0 / np.where(b > 0, b, 1.0))
    return 0.9 * float(np.min(h))


@wp.struct
class Tethers:
    """Each particle's tethers (`first`, `count`: per particle) and each tether's pin and largest length."""

    first: wp.array(dtype=wp.int32)
    count: wp.array(dtype=wp.int32)
    pin: wp.array(dtype=wp.int32)
    limit: wp.array(dtype=float_t)


def tether_arrays(first, count, pin, limit) -> Tethers:
    """The struct over the tether arrays (see `grid.tethers`)."""
    t = Tethers()
    t.first, t.count, t.pin, t.limit = first, count, pin, limit
    return t


@wp.kernel
def _limit_tethers(
    x: wp.array(dtype=vec3),
    inv_m: wp.array(dtype=float_t),
    tethers: Tethers,
    pin_load: wp.array(dtype=vec3),
    margin: float_t,
):
    # one thread per particle, its tethers in turn: no two threads move the same particle, and
    # pins do not move, so the sweep is the same on the CPU and on CUDA
    p = wp.tid()
    w = inv_m[p]
    if w <= float_t(0.0):
        return
    xp = x[p]
    for t in range(tethers.first[p], tethers.first[p] + tethers.count[p]):
        a = tethers.pin[t]
        if inv_m[a] <= float_t(0.0):
            d = xp - x[a]
            length = wp.length(d)
            excess = length - tethers.limit[t] * margin
            if excess > float_t(0.0):
                # pull the particle back onto the sphere of radius margin * limit about the pin
                dx = d * (excess / length)
                xp = xp - dx
                # the pin feels the particle's pull, m_p |dx| along the tether [kg m]
                wp.atomic_add(pin_load, a, dx / w)
    x[p] = xp


def limit_tethers(
    x, inv_mass, tethers: Tethers, *, pin_load=None, margin: float = 0.99, cache: LaunchCache | None = None
):
    """Long-range attachments: keep each free particle within its limit of its pins (see `grid.tethers`).

    Args:
        x: particle positions [m], shape (P,) vec3 (corrected in place).
        inv_mass: inverse masses [1/kg], shape (P,); a tether acts only while its pin is pinned.
        tethers: each particle's tethers, their pins and largest lengths (`tether_arrays`).
        pin_load: adds the tethers' pull on their pins, m_p dx [kg m], shape (P,) vec3 (default: not kept).
        margin: particles are kept within margin * limit, the same margin as `limit_stretch`, so
            that a taut chain of springs between a particle and its pin fits inside both limits.
    """
    if tethers.pin.shape[0]:
        if pin_load is None:
            pin_load = wp.zeros(x.shape[0], dtype=vec3, device=x.device)
        launch(_limit_tethers, x.shape[0], [x, inv_mass, tethers, pin_load, margin], x.device, cache)
