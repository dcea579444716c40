"""cloth/springs.py: spring forces, the stretch limit, tethers and the stable substep, on plain arrays."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import warp as wp

from tumble.cloth import springs
from tumble.cloth.arrays import PARTICLE_FIELDS, Particles, Springs, Stretch, Tethers
from tumble.cloth.attach import no_carried_pins
from tumble.model import fields_of
from tumble.state import ArraySet, float_t
from tumble.structs import fill_struct


def particles(x, inv_mass=None) -> tuple[Particles, dict[str, wp.array]]:
    """Particles at `x` (n, 3) with inverse masses `inv_mass` (default 1), at rest: the struct and its arrays."""
    n = len(x)
    arrays = ArraySet(fields_of(PARTICLE_FIELDS), device="cpu", capacity=n).arrays
    arrays["particle_position"].assign(np.asarray(x, dtype=np.float64))
    arrays["particle_inv_mass"].assign(np.ones(n) if inv_mass is None else np.asarray(inv_mass, dtype=np.float64))
    return fill_struct(Particles, arrays, "particle_"), arrays


def table(struct, prefix: str, **columns):
    """A struct of `arrays.py` over the given columns (named without `prefix`): index pairs int32, the rest float."""
    arrays = {}
    for name, values in columns.items():
        values = np.asarray(values)
        dtype = wp.int32 if values.dtype.kind == "i" else float_t
        arrays[prefix + name] = wp.array(values.astype(np.int32 if dtype is wp.int32 else np.float64), dtype=dtype)
    return fill_struct(struct, arrays, prefix)


def test_stable_substep_single_spring():
    """Undamped: h = 0.9 * 2 / sqrt(2 K w), the Gershgorin bound of symplectic Euler."""
    h = springs.stable_substep(np.array([10.0]), np.array([0.0]), np.array([100.0]))
    assert h == pytest.approx(0.9 * 2.0 / math.sqrt(2.0 * 10.0 * 100.0))
    assert springs.stable_substep(np.zeros(3), np.zeros(3), np.ones(3)) == math.inf


def test_stable_substep_of_overflowing_springs_is_zero():
    """Damping 1e300 overflows the root's b^2: the stable substep is 0 (no substep is stable), with no
    NumPy warning; before, it came out inf, which asked for one substep."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert springs.stable_substep(np.array([10.0]), np.array([1e300]), np.array([100.0])) == 0.0
        assert springs.stable_substep(np.array([1e300]), np.array([0.0]), np.array([1e300])) == 0.0


def test_spring_force_on_plain_arrays():
    """One stretched spring pulls its ends together with ks (|d| - l0)."""
    p, arrays = particles([[0.0, 0.0, 0.0], [1.5, 0.0, 0.0]])
    spring = table(Springs, "spring_", ids=[[0, 1]], rest_length=[1.0], stiffness=[4.0], damping=[0.0])
    springs.accumulate_spring_forces(p, spring)
    assert arrays["particle_force"].numpy() == pytest.approx(np.array([[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]]))


def test_stretch_limit_on_plain_arrays():
    """A spring stretched to 2 l0 is brought back to at most (1 + s) l0, pinned end fixed."""
    p, arrays = particles([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], inv_mass=[0.0, 1.0])
    flag = wp.zeros(1, dtype=wp.int32)
    springs.limit_stretch(p, table(Stretch, "stretch_", ids=[[0, 1]], limit=[1.1]), flag, no_carried_pins("cpu"))
    out = arrays["particle_position"].numpy()
    assert out[0] == pytest.approx([0.0, 0.0, 0.0])
    assert 1.0 < out[1, 0] <= 1.1


def test_tethers_on_plain_arrays():
    """A particle tethered to two pins ends within margin x limit of each; a released pin holds nothing."""
    x = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, -3.0, 0.0], [9.0, 9.0, 9.0]]
    p, arrays = particles(x, inv_mass=[0.0, 0.0, 1.0, 1.0])
    # particle 2 has tethers to pins 0 and 1 (limit 1.2 each); particle 3 none
    arrays["particle_tether_first"].assign(np.array([0, 0, 0, 2], dtype=np.int32))
    arrays["particle_tether_count"].assign(np.array([0, 0, 2, 0], dtype=np.int32))
    tethers = table(Tethers, "tether_", pin=[0, 1], limit=[1.2, 1.2])
    for _ in range(20):  # alternating projections onto two balls converge into their overlap
        springs.limit_tethers(p, tethers, no_carried_pins("cpu"))
    out = arrays["particle_position"].numpy()
    assert np.linalg.norm(out[2] - out[0]) <= 0.99 * 1.2 + 1e-9
    assert np.linalg.norm(out[2] - out[1]) <= 0.99 * 1.2 + 1e-9
    assert out[0] == pytest.approx([0.0, 0.0, 0.0]) and out[1] == pytest.approx([1.0, 0.0, 0.0])
    assert out[3] == pytest.approx([9.0, 9.0, 9.0])
    # pin 1 released (inverse mass > 0): its tether no longer acts
    arrays["particle_position"].assign(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [9.0, 9.0, 9.0]]))
    arrays["particle_inv_mass"].assign(np.array([0.0, 1.0, 1.0, 1.0]))
    springs.limit_tethers(p, tethers, no_carried_pins("cpu"))
    assert arrays["particle_position"].numpy()[2] == pytest.approx([0.0, -1.0, 0.0])
