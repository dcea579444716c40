"""Soak: every sample runs 30 simulated seconds, staying finite, in bounds and inside its energy budget.

Issue 13. Slow (minutes): run with `-m slow`. $TUMBLE_SOAK_S changes the simulated seconds.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

import tumble
from tumble.io.scene import check_world, list_samples

SOAK_S = float(os.environ.get("TUMBLE_SOAK_S", "30"))
#: energy a closed scene may gain over the soak: 2 % of its total energy, plus 1 mJ (cloth springs
#: store energy that `kinetic_energy + potential_energy` leaves out and give it back as motion)
GAIN_SHARE, GAIN_J = 0.02, 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("path", list_samples(), ids=[p.stem for p in list_samples()])
def test_sample_soak(path):
    """Check every simulated second: finite, above its planes, within max_extent, no energy gained."""
    world = tumble.load_scene(path)
    check = dict(world.metadata["check"])
    driven = world.has_cloth and getattr(world, "metadata", {}).get("scene").table("wind") is not None
    reference = None
    for second in range(int(SOAK_S)):
        world.run(1.0)
        # the [check] limits are for the check run; after it only the always-checked rules apply
        assert check_world(world, {"max_extent": check["max_extent"]}) == [], f"t = {world.time:.1f} s"
        energy = world.kinetic_energy() + world.potential_energy()
        assert np.isfinite(energy)
        if driven or not all(e.done for e in world.emitters):
            continue  # wind feeds energy in; emitters add bodies (and their energy)
        if reference is None:
            reference = energy
        assert energy <= reference + GAIN_SHARE * abs(reference) + GAIN_J, (second, energy, reference)
