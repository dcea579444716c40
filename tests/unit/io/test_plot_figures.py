"""`tumble plot`: energies, momentum, contacts and cloth strain from a recording."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from tumble.io.plot import build_figure, compute_series, max_strain, plot_record
from tumble.io.record import load_recording

G = 9.81


def _record(tmp_path, *, cloth=True, drop=(), name="rec.npz"):
    """Two spheres (1 kg, 2 kg) and a box (3 kg) in free fall from rest, the box emitted at frame 10."""
    f, n = 21, 3
    t = np.arange(f) / 20.0
    mass = np.array([1.0, 2.0, 3.0])
    pos = np.zeros((f, n, 3))
    pos[:, :, 0] = np.arange(n)
    pos[:, :, 2] = 2.0 - 0.5 * G * t[:, None] ** 2
    vel = np.zeros((f, n, 3))
    vel[:, :, 2] = -G * t[:, None]
    omega = np.zeros((f, n, 3))
    omega[:, 2] = (0.0, 0.0, 4.0)  # the box spins about its z axis
    pos[:10, 2] = vel[:10, 2] = omega[:10, 2] = np.nan  # not yet emitted
    arrays = dict(
        time=t,
        position=pos,
        velocity=vel,
        orientation=np.tile([0.0, 0.0, 0.0, 1.0], (f, n, 1)),
        angular_velocity=omega,
        shape=np.array([1, 1, 2]),
        shape_names=np.array(["plane", "sphere", "box"]),
        radius=np.array([0.1, 0.2, 0.0]),
        half_extents=np.array([[0, 0, 0], [0, 0, 0], [0.1, 0.2, 0.3]]),
        mass=mass,
        gravity=np.array([0.0, 0.0, -G]),
        contact_count=(t > 0.5).astype(np.int64) * 4,
    )
    if cloth:
        rest = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
        stretch = 1.0 + 0.1 * t  # uniform stretch: every edge is (1 + 0.1 t) times its rest length
        arrays.update(
            cloth_position=rest[None] * stretch[:, None, None],
            cloth_triangles=np.array([[0, 1, 3], [0, 3, 2]]),
            cloth_rest_position=rest,
        )
    for key in drop:
        arrays.pop(key)
    path = tmp_path / name
    np.savez(path, **arrays)
    return path, t, mass


def test_energy_and_momentum_match_free_fall(tmp_path):
    """KE = 1/2 m v^2 (+ 1/2 I w^2 for the spinning box), PE = m g z, p = m v over present bodies."""
    path, t, mass = _record(tmp_path)
    s = compute_series(load_recording(path))
    v = G * t
    present = np.where(np.arange(len(t)) >= 10, 1.0, 0.0)
    box_iz = 3.0 / 3.0 * (0.1**2 + 0.2**2)  # m/3 (a^2 + b^2) about z
    ke = 0.5 * (1.0 + 2.0 + 3.0 * present) * v**2 + present * 0.5 * box_iz * 16.0
    pe = (1.0 + 2.0 + 3.0 * present) * G * (2.0 - 0.5 * G * t**2)
    assert np.allclose(s.kinetic, ke)
    assert np.allclose(s.potential, pe)
    assert np.allclose(s.momentum[:, 2], -(1.0 + 2.0 + 3.0 * present) * v)
    assert np.array_equal(s.bodies, np.where(present > 0, 3, 2))
    assert np.allclose(s.strain, 0.1 * t)


def test_recorded_kinetic_energy_is_used_as_is(tmp_path):
    """A recording's own kinetic_energy array (which includes cloth) wins over the estimate."""
    path, t, _ = _record(tmp_path)
    arrays = dict(np.load(path))
    arrays["kinetic_energy"] = 7.0 + t
    np.savez(tmp_path / "ke.npz", **arrays)
    assert np.array_equal(compute_series(load_recording(tmp_path / "ke.npz")).kinetic, 7.0 + t)


def test_max_strain_of_one_stretched_edge():
    """Only the stretched edge counts: l / l0 - 1 of the longest relative stretch."""
    rest = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    moved = rest.copy()
    moved[1, 0] = 1.25
    assert max_strain(moved[None], np.array([[0, 1, 2]]), rest)[0] == pytest.approx(0.25)


def test_figure_has_the_expected_panels(tmp_path):
    """A cloth recording gives five panels: energies, momentum, contacts, strain."""
    path, _, _ = _record(tmp_path)
    fig = build_figure(load_recording(path))
    titles = [ax.get_title(loc="left").split(" (")[0] for ax in fig.axes]
    assert titles == ["Kinetic energy", "Potential energy", "Linear momentum", "Contact count", "Largest cloth strain"]
    assert "bodies only" in fig.axes[1].get_title(loc="left")  # no cloth_mass in this recording
    assert all(ax.lines for ax in fig.axes)


def test_missing_arrays_leave_panels_saying_so(tmp_path):
    """Without mass or contact counts, the affected panels say 'not recorded'; no cloth, no strain panel."""
    path, _, _ = _record(tmp_path, cloth=False, drop=("mass", "contact_count"))
    fig = build_figure(load_recording(path))
    titles = [ax.get_title(loc="left") for ax in fig.axes]
    assert len(titles) == 4
    assert titles[0].startswith("Kinetic energy: not recorded") and "mass" in titles[0]
    assert titles[3].startswith("Contact count: not recorded")
    assert "no cloth" in fig.get_suptitle()


def test_plot_file_is_a_png_of_the_figure_size(tmp_path):
    """plot_record writes a valid PNG (signature, IHDR size 800 x figure height)."""
    path, _, _ = _record(tmp_path)
    out = plot_record(path, tmp_path / "plot.png")
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    fig = build_figure(load_recording(path))
    assert (width, height) == (800, round(fig.get_figheight() * 100))


def test_bad_recordings_are_clear_errors(tmp_path):
    """A missing file or one without time raises ValueError naming the problem."""
    with pytest.raises(ValueError, match="no such recording"):
        load_recording(tmp_path / "missing.npz")
    np.savez(tmp_path / "empty.npz", position=np.zeros((2, 1, 3)))
    with pytest.raises(ValueError, match="'time'"):
        load_recording(tmp_path / "empty.npz")
    (tmp_path / "junk.npz").write_text("not a zip")
    with pytest.raises(ValueError, match="not a readable"):
        load_recording(tmp_path / "junk.npz")
