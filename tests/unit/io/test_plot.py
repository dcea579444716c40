"""io/plot.py: the arrays it documents are the ones the recorder writes; an old recording (before
every declared array was recorded) plots to the same series; energies and strain from the arrays."""

from __future__ import annotations

import re

import numpy as np
import pytest

import tumble
from tumble.io import plot
from tumble.io.record import Recorder, load_recording

DT = 1.0 / 64.0
FPS = 16.0

#: the arrays a recording had before every declared body and particle array was recorded
OLD_FORMAT = {
    *("format_version", "time", "contact_count", "kinetic_energy", "momentum", "gravity", "dt", "fps"),
    *("position", "velocity", "orientation", "angular_velocity", "shape", "shape_names", "radius"),
    *("half_extents", "mass", "restitution", "friction"),
    *("cloth_position", "cloth_triangles", "cloth_rest_position", "cloth_mass", "cloth_max_strain"),
}


def recorded_world() -> dict:
    """0.5 s of a falling sphere and box over a plane, and a cloth hanging from two corners."""
    world = tumble.World(dt=DT, substeps=2)
    world.add_plane()
    world.add_sphere(position=(0.0, 0.0, 1.0), radius=0.1, mass=1.0, velocity=(0.5, 0.0, 0.0))
    world.add_box(position=(1.0, 0.0, 0.5), half_extents=(0.1, 0.2, 0.3), mass=2.0, angular_velocity=(0, 0, 3))
    world.add_cloth(size=(0.5, 0.5), resolution=(4, 3), position=(0.0, 1.0, 1.0), mass=0.3, pins="top-corners")
    recorder = Recorder(world, fps=FPS)
    world.run(0.5, callback=recorder)
    return recorder.arrays()


@pytest.fixture(scope="module")
def rec() -> dict:
    return recorded_world()


def documented() -> set[str]:
    """The array names plot.py's docstring lists, each followed by its shape: "position (F, N, 3)"."""
    assert plot.__doc__ is not None
    return set(re.findall(r"\b([a-z][a-z_]*) \((?:F|N|P|T|3|6)\b", plot.__doc__))


def test_every_array_plot_documents_is_written_by_the_recorder(rec):
    """Each array named in plot.py's docstring is in a recording of bodies and cloth."""
    names = documented()
    assert {"time", "position", "mass", "cloth_position", "cloth_max_strain", "momentum"} <= names
    assert names <= set(rec), names - set(rec)


def test_an_old_format_recording_plots_to_the_same_series(rec, tmp_path):
    """A file with only the old arrays loads and gives the series the full recording gives."""
    assert OLD_FORMAT <= set(rec) and set(rec) - OLD_FORMAT  # the new recording holds more
    old = tmp_path / "old.npz"
    np.savez_compressed(old, **{k: v for k, v in rec.items() if k in OLD_FORMAT})
    loaded = load_recording(old)
    assert set(loaded) == OLD_FORMAT
    before, now = plot.compute_series(loaded), plot.compute_series(rec)
    for name in ("time", "kinetic", "potential", "momentum", "contacts", "strain", "bodies"):
        np.testing.assert_array_equal(getattr(before, name), getattr(now, name), err_msg=name)
    assert before.missing == now.missing == {}
    assert plot.plot_record(old, tmp_path / "old.png").stat().st_size > 0


def test_kinetic_energy_from_the_arrays_matches_the_engines(rec):
    """Without the recorded energy, 1/2 m v^2 + 1/2 w_b . I w_b of the bodies is the engine's (no cloth moving at t=0)."""
    bodies_only = {k: v for k, v in rec.items() if not k.startswith("cloth_") and k != "kinetic_energy"}
    series = plot.compute_series(bodies_only)
    # frame 0: sphere 1/2 1 0.5^2 = 0.125 J; box spinning at 3 rad/s about z: 1/2 I_z w^2, I_z = m (a^2 + b^2) / 3
    i_z = 2.0 * (0.1**2 + 0.2**2) / 3.0
    assert series.kinetic is not None
    assert series.kinetic[0] == pytest.approx(0.125 + 0.5 * i_z * 9.0, rel=1e-12)
