"""Plots of a recorded simulation (`tumble run --record`): energy, momentum, contacts, cloth strain.

A recording is an .npz with, for F frames and N bodies (rows of bodies not yet emitted are
NaN and count as absent)::

    time (F,)  position (F, N, 3)  velocity (F, N, 3)  orientation (F, N, 4) as (x, y, z, w)
    angular_velocity (F, N, 3)  shape (N,) int  shape_names (6,)  radius (N,)  half_extents (N, 3)
    mass (N,)  gravity (3,)  contact_count (F,)  kinetic_energy (F,) (used as is when present)
    cloth_position (F, P, 3)  cloth_triangles (T, 3)  cloth_rest_position (P, 3)
    cloth_mass (P,)  cloth_max_strain (F,)  momentum (F, 3) (bodies and cloth, used as is when present)

Everything but `time` is optional: a panel whose inputs are missing says so in its title.
Figures are drawn with matplotlib's Agg backend (no display needed)::

    from tumble.io.plot import plot_record
    plot_record("drop.npz", "drop.png")
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..npmath import quat_rotate_inverse
from ..shapes import ShapeType, box_inertia, sphere_inertia
from .record import load_recording


@dataclass
class Series:
    """Quantities over time computed from a recording; None where the inputs were not recorded.

    Attributes:
        time: [s], shape (F,).
        kinetic: kinetic energy [J], shape (F,).
        potential: gravitational potential energy relative to the origin [J], shape (F,).
        momentum: total linear momentum [kg m/s], shape (F, 3).
        contacts: contact count, shape (F,).
        strain: largest cloth stretch (l / l0 - 1) over all edges, shape (F,).
        bodies: number of bodies present in each frame, shape (F,).
        missing: panel name -> why it could not be computed.
    """

    time: np.ndarray
    kinetic: np.ndarray | None = None
    potential: np.ndarray | None = None
    momentum: np.ndarray | None = None
    contacts: np.ndarray | None = None
    strain: np.ndarray | None = None
    bodies: np.ndarray | None = None
    has_cloth: bool = False
    missing: dict[str, str] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)


def _body_inertia(record, mass: np.ndarray) -> np.ndarray | None:
    """Principal moments of inertia in the body frame [kg m^2], shape (N, 3), or None."""
    shape = record.get("shape")
    if shape is None:
        return None
    shape = np.asarray(shape).astype(int)
    n = len(mass)
    radius = np.asarray(record.get("radius", np.zeros(n)), dtype=np.float64)
    half = np.asarray(record.get("half_extents", np.zeros((n, 3))), dtype=np.float64)
    inertia = np.zeros((n, 3))
    sphere, box = shape == ShapeType.SPHERE, shape == ShapeType.BOX
    inertia[sphere] = sphere_inertia(mass[sphere], radius[sphere])
    inertia[box] = box_inertia(mass[box], half[box])
    return inertia


def compute_series(record: dict) -> Series:
    """Energies, momentum, contacts and strain over time from a recording's arrays."""
    time = np.asarray(record["time"], dtype=np.float64)
    f = len(time)
    s = Series(time=time)

    pos = record.get("position")
    if pos is not None:
        pos = np.asarray(pos, dtype=np.float64)
        if pos.ndim != 3 or pos.shape[0] != f or pos.shape[2] != 3:
            raise ValueError(f"recording array 'position' has shape {pos.shape}, expected ({f}, N, 3)")
    vel = record.get("velocity")
    mass = record.get("mass")
    gravity = record.get("gravity")
    g = None if gravity is None else np.asarray(gravity, dtype=np.float64).reshape(3)
    n = 0 if pos is None else pos.shape[1]
    if pos is not None:
        present = np.isfinite(pos).all(axis=2)  # (F, N): emitted bodies only
        s.bodies = present.sum(axis=1)
    if mass is not None:
        mass = np.asarray(mass, dtype=np.float64).reshape(-1)
        if pos is not None and len(mass) != n:
            raise ValueError(f"recording array 'mass' has {len(mass)} entries for {n} bodies")
    if vel is not None:
        vel = np.asarray(vel, dtype=np.float64)
        if pos is not None and vel.shape != pos.shape:
            raise ValueError(f"recording array 'velocity' has shape {vel.shape}, expected {pos.shape}")

    # kinetic energy: the engine's own value when recorded (it includes the cloth), else
    # sum 1/2 m v^2 + 1/2 w_b . I w_b, with w_b the angular velocity in the body frame
    recorded_kinetic = record.get("kinetic_energy")
    if recorded_kinetic is not None:
        s.kinetic = np.asarray(recorded_kinetic, dtype=np.float64).reshape(-1)[:f]
    elif pos is None or vel is None or mass is None:
        s.missing["kinetic"] = "needs " + " and ".join(
            k for k, v in (("position", pos), ("velocity", vel), ("mass", mass)) if v is None
        )
    else:
        v = np.where(present[..., None], vel, 0.0)
        v = np.nan_to_num(v)
        kinetic = 0.5 * np.einsum("n,fn->f", mass, np.einsum("fni,fni->fn", v, v))
        omega = record.get("angular_velocity")
        inertia = _body_inertia(record, mass)
        if omega is not None and inertia is not None:
            w = np.nan_to_num(np.where(present[..., None], np.asarray(omega, dtype=np.float64), 0.0))
            q = record.get("orientation")
            if q is not None:
                q = np.nan_to_num(np.asarray(q, dtype=np.float64))
                q = np.where(np.linalg.norm(q, axis=-1, keepdims=True) > 0, q, [0.0, 0.0, 0.0, 1.0])
                w = quat_rotate_inverse(q, w)
            kinetic = kinetic + 0.5 * np.einsum("ni,fni->f", inertia, w * w)
        s.kinetic = kinetic

    # potential energy: -sum m g . x (zero at the origin)
    if pos is None or mass is None or gravity is None:
        s.missing["potential"] = "needs " + " and ".join(
            k for k, v in (("position", pos), ("mass", mass), ("gravity", gravity)) if v is None
        )
    else:
        x = np.nan_to_num(np.where(present[..., None], pos, 0.0))
        s.potential = -np.einsum("n,fn->f", mass, x @ g)

    # linear momentum: the engine's own total when recorded (bodies and cloth), else sum m v
    recorded_momentum = record.get("momentum")
    if recorded_momentum is not None:
        s.momentum = np.asarray(recorded_momentum, dtype=np.float64).reshape(-1, 3)[:f]
    elif vel is None or mass is None or pos is None:
        s.missing["momentum"] = "needs " + " and ".join(
            k for k, v in (("position", pos), ("velocity", vel), ("mass", mass)) if v is None
        )
    else:
        v = np.nan_to_num(np.where(present[..., None], vel, 0.0))
        s.momentum = np.einsum("n,fni->fi", mass, v)

    contacts = record.get("contact_count")
    if contacts is None:
        s.missing["contacts"] = "needs contact_count"
    else:
        s.contacts = np.asarray(contacts, dtype=np.float64).reshape(-1)[:f]

    # cloth: energies of the particles join the bodies'; strain from edge lengths
    cloth_pos = record.get("cloth_position")
    s.has_cloth = cloth_pos is not None or "cloth_max_strain" in record
    if cloth_pos is not None:
        cloth_pos = np.asarray(cloth_pos, dtype=np.float64)
        cloth_mass = record.get("cloth_mass")
        if cloth_mass is None and s.potential is not None:
            s.notes["potential"] = "bodies only: no cloth_mass recorded"
        if cloth_mass is not None:
            cm = np.broadcast_to(np.asarray(cloth_mass, dtype=np.float64), cloth_pos.shape[1:2])
            if s.potential is not None:
                s.potential = s.potential - np.einsum("p,fp->f", cm, np.nan_to_num(cloth_pos) @ g)
        # recordings carry the engine's kinetic energy and momentum with the cloth's share; without
        # them only the bodies' are summed (cloth velocities are not recorded)
        if s.kinetic is not None and recorded_kinetic is None:
            s.notes["kinetic"] = "bodies only: no kinetic_energy recorded"
        if s.momentum is not None and recorded_momentum is None:
            s.notes["momentum"] = "bodies only: no momentum recorded"
    if "cloth_max_strain" in record:
        s.strain = np.asarray(record["cloth_max_strain"], dtype=np.float64).reshape(-1)[:f]
    elif s.has_cloth:
        tri, rest = record.get("cloth_triangles"), record.get("cloth_rest_position")
        if tri is None or rest is None:
            s.missing["strain"] = "needs " + " and ".join(
                k for k, v in (("cloth_triangles", tri), ("cloth_rest_position", rest)) if v is None
            )
        else:
            assert cloth_pos is not None  # has_cloth without cloth_max_strain
            s.strain = max_strain(cloth_pos, np.asarray(tri), np.asarray(rest, dtype=np.float64))
            s.notes["strain"] = "over triangle edges, diagonals included"
    return s


def triangle_edges(triangles: np.ndarray) -> np.ndarray:
    """Unique undirected edges (i < j) of a triangle mesh, shape (E, 2)."""
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    e.sort(axis=1)
    return np.unique(e, axis=0)


def max_strain(position: np.ndarray, triangles: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Largest stretch l / l0 - 1 over the mesh's edges per frame; position (F, P, 3) -> (F,)."""
    e = triangle_edges(triangles)
    if e.size and (e.min() < 0 or e.max() >= len(rest)):
        raise ValueError(f"cloth_triangles index particles outside 0..{len(rest) - 1}")
    l0 = np.linalg.norm(rest[e[:, 1]] - rest[e[:, 0]], axis=1)
    keep = l0 > 1e-12
    e, l0 = e[keep], l0[keep]
    length = np.linalg.norm(position[:, e[:, 1]] - position[:, e[:, 0]], axis=2)
    return np.max(length / l0 - 1.0, axis=1, initial=0.0)


#: panel key -> (title, y label)
PANELS = {
    "kinetic": ("Kinetic energy", "J"),
    "potential": ("Potential energy", "J"),
    "momentum": ("Linear momentum", "kg m/s"),
    "contacts": ("Contact count", "contacts"),
    "strain": ("Largest cloth strain", "l / l0 - 1"),
}


def _quiet_font_cache() -> None:
    """Keep matplotlib's "Could not save font_manager cache" off the user's screen.

    On its first start matplotlib builds a font list and caches it in its config folder; when that
    write fails (a full disk, a read-only home) it logs a warning and simply rebuilds the list next
    time. It says nothing about the user's plot, whose own write errors Tumble reports in one line.
    """
    import logging

    logger = logging.getLogger("matplotlib.font_manager")
    if not any(isinstance(f, _FontCacheFilter) for f in logger.filters):
        logger.addFilter(_FontCacheFilter())


class _FontCacheFilter:
    def filter(self, record) -> bool:
        return not str(record.msg).startswith("Could not save font_manager cache")


def build_figure(record: dict, *, name: str | None = None):
    """A matplotlib Figure (Agg) with one panel per quantity, stacked over a shared time axis.

    The strain panel appears only for recordings with cloth. A panel whose inputs are missing
    stays empty and its title says "not recorded" and what it needs; a quantity that is zero
    throughout says so in the panel (with a symmetric axis, not fractional ticks). While
    bodies are being emitted every panel shades that time span, and the potential-energy
    panel's title says how many appeared (the energy changes as they do).
    """
    _quiet_font_cache()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    s = compute_series(record)
    keys = [k for k in PANELS if k != "strain" or s.has_cloth]
    fig = Figure(figsize=(8.0, 1.9 * len(keys) + 0.8), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(keys), 1, sharex=True, squeeze=False)[:, 0]
    t = s.time
    emitting = emission_span(t, s.bodies)
    for ax, key in zip(axes, keys):
        label, unit = PANELS[key]
        data = getattr(s, key)
        ax.grid(True, alpha=0.3)
        ax.set_ylabel(unit)
        if data is None:
            ax.set_title(f"{label}: not recorded ({s.missing.get(key, 'missing')})", loc="left", fontsize=10)
            ax.text(0.5, 0.5, "not recorded", transform=ax.transAxes, ha="center", va="center", color="0.5")
            continue
        ax.set_title(label + (f" ({s.notes[key]})" if key in s.notes else ""), loc="left", fontsize=10)
        if emitting is not None:
            ax.axvspan(*emitting, color="#edae49", alpha=0.12, lw=0, label="_emitting")
        values = np.asarray(data, dtype=np.float64)
        if not np.isfinite(values).any() or np.all(values[np.isfinite(values)] == 0.0):
            # nothing to draw: say so, on an axis with whole ticks around zero
            # (contacts are counted at the frames: a bounce shorter than a frame's interval leaves none)
            what = {"contacts": "no contacts at the recorded frames", "strain": "no strain"}.get(key, "zero throughout")
            if not np.isfinite(values).any():
                what = "no finite values"
            ax.axhline(0.0, color="0.6", lw=1.0)
            ax.set_ylim(-1.0, 1.0)
            ax.set_yticks([-1.0, 0.0, 1.0])
            ax.text(0.5, 0.5, what, transform=ax.transAxes, ha="center", va="center", color="0.4")
            continue
        if key == "momentum":
            for i, (axis, colour) in enumerate(zip("xyz", ("#d1495b", "#66a182", "#2e86ab"))):
                ax.plot(t, data[:, i], color=colour, lw=1.2, label=f"p{axis}")
            ax.plot(t, np.linalg.norm(data, axis=1), color="0.2", lw=1.2, ls="--", label="|p|")
            ax.legend(loc="best", fontsize=8, ncols=4, framealpha=0.8)
        elif key == "contacts":
            from matplotlib.ticker import MaxNLocator

            ax.step(t, data, where="post", color="#8d6a9f", lw=1.2)
            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        else:
            colour = {"kinetic": "#d1495b", "potential": "#2e86ab", "strain": "#edae49"}[key]
            ax.plot(t, data, color=colour, lw=1.4)
        if key == "potential" and emitting is not None:
            assert s.bodies is not None  # an emission span needs the body counts
            first, last = int(s.bodies[0]), int(s.bodies.max())
            notes = [s.notes[key]] if key in s.notes else []
            notes.append(
                f"changes as bodies are emitted: {first:,} to {last:,} bodies "
                f"from {emitting[0]:.3g} to {emitting[1]:.3g} s, shaded"
            )
            ax.set_title(f"{label} ({'; '.join(notes)})", loc="left", fontsize=10)
    axes[-1].set_xlabel("time [s]")
    if len(t) > 1 and t[-1] > t[0]:
        axes[-1].set_xlim(t[0], t[-1])
    bodies = "" if s.bodies is None else f", {int(s.bodies.max(initial=0))} bodies"
    title = f"{len(t)} frames, {t[0]:.3g} to {t[-1]:.3g} s{bodies}" + ("" if s.has_cloth else ", no cloth")
    fig.suptitle(title if name is None else f"{name}: {title}", fontsize=11)
    return fig


def emission_span(time: np.ndarray, bodies: np.ndarray | None) -> tuple[float, float] | None:
    """(first, last) time at which the body count grew, or None when it never did."""
    if bodies is None or len(bodies) < 2:
        return None
    grew = np.nonzero(np.diff(bodies) > 0)[0]
    if len(grew) == 0:
        return None
    return float(time[grew[0]]), float(time[grew[-1] + 1])


#: image formats `plot_record` writes, by suffix
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def plot_record(path, out, *, dpi: int = 100) -> Path:
    """Read recording `path` and write its plot to `out` (.png, .svg or .pdf), atomically.

    Raises:
        OutputError: `out` cannot be written (checked before the recording is read).
        RecordingError: `path` is not a readable recording.
    """
    from .atomic import atomic_path, check_output

    path = Path(path)
    out = check_output(out, suffixes=PLOT_SUFFIXES, option="")
    record = load_recording(path)
    try:
        fig = build_figure(record, name=path.name)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=dpi, format=out.suffix[1:].lower())
    return out
