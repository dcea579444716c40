"""The live controls panel: one slider and one number field per physics parameter.

Every control writes straight into the running world (see `ControlsPanel.apply`), so a change
takes effect on the next step. A control whose value only reaches new bodies, or only cloth,
says so under its slider.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from PySide6 import QtCore, QtWidgets

from .picking import cloth_of

if TYPE_CHECKING:
    from ..world import World

_SLIDER_STEPS = 1000


@dataclass
class Param:
    """Description of one live parameter.

    Attributes:
        key: identifier, e.g. "gravity_z".
        label: text shown left of the slider.
        unit: unit shown after the value ("m/s²", "" for none).
        minimum, maximum: slider range (the number field accepts the same range).
        decimals: digits after the point in the number field (0 for integers).
        read: world -> current value, or None when the parameter does not apply to this world.
        write: (world, value) -> None, applying the value to the running world.
        note: a short remark shown under the slider (e.g. "applies to new bodies").
    """

    key: str
    label: str
    unit: str
    minimum: float
    maximum: float
    decimals: int
    read: Callable[[World], float | None]
    write: Callable[[World, float], None]
    note: str = ""
    tooltip: str = ""


class ParamControl(QtWidgets.QWidget):
    """A labelled slider with a number field (value and unit) and an optional note below."""

    valueChanged = QtCore.Signal(float)

    def __init__(self, param: Param, parent=None):
        super().__init__(parent)
        self.param = param
        self.touched = False  # set once the user changes the value
        self._updating = False

        self.label = QtWidgets.QLabel(param.label)
        self.slider = QtWidgets.QSlider(QtCore.Qt.Orientation.Horizontal)
        self.slider.setRange(0, _SLIDER_STEPS if param.decimals else int(param.maximum - param.minimum))
        self.spin = QtWidgets.QDoubleSpinBox()
        self.spin.setDecimals(param.decimals)
        self.spin.setRange(param.minimum, param.maximum)
        self.spin.setSingleStep(10.0**-param.decimals if param.decimals else 1.0)
        self.spin.setKeyboardTracking(False)
        self.spin.setSuffix(f" {param.unit}" if param.unit else "")
        self.spin.setMinimumWidth(96)
        self.spin.setAlignment(QtCore.Qt.AlignmentFlag.AlignRight)
        for w in (self.label, self.slider, self.spin):
            if param.tooltip:
                w.setToolTip(param.tooltip)

        grid = QtWidgets.QGridLayout(self)
        grid.setContentsMargins(0, 2, 0, 2)
        grid.setHorizontalSpacing(6)
        grid.setVerticalSpacing(0)
        grid.addWidget(self.label, 0, 0, 1, 2)
        grid.addWidget(self.slider, 1, 0)
        grid.addWidget(self.spin, 1, 1)
        if param.note:
            note = QtWidgets.QLabel(param.note)
            note.setObjectName("note")
            note.setWordWrap(True)
            grid.addWidget(note, 2, 0, 1, 2)
        grid.setColumnStretch(0, 1)

        self.slider.valueChanged.connect(self._slider_moved)
        self.spin.valueChanged.connect(self._spin_changed)

    # slider position <-> value
    def _to_slider(self, value: float) -> int:
        p = self.param
        if not p.decimals:
            return int(round(value - p.minimum))
        return int(round((value - p.minimum) / (p.maximum - p.minimum) * _SLIDER_STEPS))

    def _from_slider(self, position: int) -> float:
        p = self.param
        if not p.decimals:
            return p.minimum + position
        return round(p.minimum + position / _SLIDER_STEPS * (p.maximum - p.minimum), p.decimals)

    def value(self) -> float:
        """The control's current value."""
        return float(self.spin.value())

    def set_value(self, value: float, *, user: bool = False) -> None:
        """Show `value`; with `user=True` it counts as a user change and is emitted."""
        value = min(max(float(value), self.param.minimum), self.param.maximum)
        self._updating = not user
        try:
            self.spin.setValue(value)
            self.slider.setValue(self._to_slider(value))
        finally:
            self._updating = False

    def _slider_moved(self, position: int) -> None:
        self._follow(self.spin, self._from_slider, position)

    def _spin_changed(self, value: float) -> None:
        self._follow(self.slider, self._to_slider, value)

    def _follow(self, other, convert: Callable, value) -> None:
        """The user moved one widget to `value`: `other` shows `convert(value)` (its own change not
        taken for the user's), then the change is signalled."""
        if self._updating:
            return
        self._updating = True
        try:
            other.setValue(convert(value))
        finally:
            self._updating = False
        self._emit()

    def _emit(self) -> None:
        self.touched = True
        self.valueChanged.emit(self.value())


# ---------------------------------------------------------------------- the parameters


def _gravity_component(axis: int) -> tuple[Callable, Callable]:
    def read(world):
        return float(world.gravity[axis])

    def write(world, value):
        g = np.array(world.gravity, dtype=np.float64)
        g[axis] = value
        world.gravity = g

    return read, write


def _dynamic(world) -> np.ndarray:
    return np.asarray(world.body_inv_mass) > 0.0


def _material(name: str) -> tuple[Callable, Callable]:
    def read(world):
        values = np.asarray(getattr(world, f"body_{name}"))
        if len(values) == 0:
            return None
        dynamic = _dynamic(world)
        return float(np.median(values[dynamic] if dynamic.any() else values))

    def write(world, value):
        world.set_material(**{name: float(value)})

    return read, write


def wind_state(world) -> dict | None:
    """The cloth's wind as `world.set_wind` keywords (velocity (3,), turbulence, scale, seed, and the
    face coefficients when the wind has them); None without cloth."""
    cloth = cloth_of(world)
    if cloth is None:
        return None
    wind = getattr(cloth, "wind", None)
    state = {
        "velocity": np.asarray(getattr(wind, "velocity", (0.0, 0.0, 0.0)), dtype=np.float64).copy(),
        "turbulence": float(getattr(wind, "turbulence", 0.0)),
        "scale": float(getattr(wind, "scale", 1.0)),
        "seed": int(getattr(wind, "seed", 0)),
    }
    for name in ("drag", "lift", "air_density"):  # keep the scene's coefficients
        if hasattr(wind, name):
            state[name] = float(getattr(wind, name))
    return state


def _set_wind(world, **changes) -> None:
    state = wind_state(world)
    if state is None:
        return
    velocity = state["velocity"]
    speed = float(np.hypot(velocity[0], velocity[1]))
    heading = math.degrees(math.atan2(velocity[1], velocity[0])) if speed > 0 else 0.0
    speed = changes.get("speed", speed)
    heading = changes.get("heading", heading)
    a = math.radians(heading)
    state["velocity"] = np.array([speed * math.cos(a), speed * math.sin(a), velocity[2]])
    state["turbulence"] = changes.get("turbulence", state["turbulence"])
    world.set_wind(**state)


def _wind_read(part: str) -> Callable:
    def read(world):
        state = wind_state(world)
        if state is None:
            return None
        v = state["velocity"]
        if part == "speed":
            return float(np.hypot(v[0], v[1]))
        if part == "heading":
            return float(math.degrees(math.atan2(v[1], v[0])) % 360.0) if np.hypot(v[0], v[1]) > 0 else 0.0
        return state["turbulence"]

    return read


def _wind_param(
    part: str, label: str, unit: str, maximum: float, decimals: int, *, note: str = "", tooltip: str = ""
) -> Param:
    """The panel's control of one part of the wind ("speed", "heading" or "turbulence"), from 0 to `maximum`."""
    return Param(
        f"wind_{part}",
        label,
        unit,
        0.0,
        maximum,
        decimals,
        _wind_read(part),
        lambda w, v: _set_wind(w, **{part: v}),
        note=note,
        tooltip=tooltip,
    )


def _emitter_rate_read(world):
    emitters = getattr(world, "emitters", [])
    return float(emitters[0].rate) if emitters else None


def _emitter_rate_write(world, value):
    for emitter in world.emitters:
        emitter.rate = float(value)


def default_params() -> list[tuple[str, list[Param]]]:
    """The panel's groups of parameters, in display order."""
    gx, gy, gz = (_gravity_component(i) for i in range(3))
    rest, fric = _material("restitution"), _material("friction")
    return [
        (
            "Gravity",
            [
                Param("gravity_z", "Gravity z (up)", "m/s²", -30.0, 10.0, 2, gz[0], gz[1]),
                Param("gravity_x", "Gravity x", "m/s²", -10.0, 10.0, 2, gx[0], gx[1]),
                Param("gravity_y", "Gravity y", "m/s²", -10.0, 10.0, 2, gy[0], gy[1]),
            ],
        ),
        (
            "Material (all bodies)",
            [
                Param(
                    "restitution",
                    "Restitution",
                    "",
                    0.0,
                    1.0,
                    2,
                    rest[0],
                    rest[1],
                    tooltip="Bounciness of every body and plane: 0 = no bounce, 1 = elastic.",
                ),
                Param(
                    "friction",
                    "Friction",
                    "",
                    0.0,
                    2.0,
                    2,
                    fric[0],
                    fric[1],
                    tooltip="Coulomb friction coefficient of every body and plane.",
                ),
            ],
        ),
        (
            "Wind",
            [
                _wind_param("speed", "Wind speed", "m/s", 30.0, 1, note="horizontal wind; acts on cloth only"),
                _wind_param("heading", "Wind direction", "°", 360.0, 0, tooltip="0° blows towards +x, 90° towards +y."),
                _wind_param(
                    "turbulence",
                    "Turbulence",
                    "m/s",
                    10.0,
                    2,
                    tooltip="RMS speed of the gusts added to the mean wind, per component.",
                ),
            ],
        ),
        (
            "Emitters",
            [
                Param(
                    "emission_rate",
                    "Emission rate",
                    "bodies/s",
                    0.0,
                    1000.0,
                    0,
                    _emitter_rate_read,
                    _emitter_rate_write,
                    note="sets every emitter; applies to bodies not yet emitted",
                ),
            ],
        ),
        (
            "Solver",
            [
                Param(
                    "substeps",
                    "Substeps",
                    "per step",
                    1.0,
                    32.0,
                    0,
                    lambda w: float(w.substeps),
                    lambda w, v: setattr(w, "substeps", int(round(v))),
                    tooltip="Solver substeps per world step: more = stiffer stacks, slower.",
                ),
            ],
        ),
    ]


class ControlsPanel(QtWidgets.QWidget):
    """Side panel: groups of `ParamControl`s bound to a world, plus a time-scale control.

    Signals:
        changed(str, float): a parameter was changed by the user (key, new value).
        timeScaleChanged(float): the time scale was changed.
        shadowsToggled(bool): sun shadows were switched on or off.
        jointsToggled(bool): drawing the joints was switched on or off.
    """

    changed = QtCore.Signal(str, float)
    timeScaleChanged = QtCore.Signal(float)
    shadowsToggled = QtCore.Signal(bool)
    jointsToggled = QtCore.Signal(bool)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.world = None
        # runs a change to the world; the viewer passes its simulation thread's `submit`,
        # so that a change made while a step runs waits for that step's end
        self.apply: Callable[[Callable[[], None]], object] = lambda change: change()
        self.controls: dict[str, ParamControl] = {}
        self.groups: dict[str, QtWidgets.QGroupBox] = {}
        self._group_of: dict[str, str] = {}
        self.scene_values: dict[str, float] = {}  # values the world had when it was built

        layout = QtWidgets.QVBoxLayout(self)
        layout.setContentsMargins(6, 6, 6, 6)

        time_box = QtWidgets.QGroupBox("Time")
        time_layout = QtWidgets.QVBoxLayout(time_box)
        self.time_scale = ParamControl(
            Param(
                "time_scale",
                "Time scale",
                "×",
                0.05,
                4.0,
                2,
                lambda w: 1.0,
                lambda w, v: None,
                tooltip="Simulated seconds per real second; the step dt stays fixed.",
            )
        )
        self.time_scale.set_value(1.0)
        self.time_scale.valueChanged.connect(self.timeScaleChanged)
        time_layout.addWidget(self.time_scale)
        self.dt_label = QtWidgets.QLabel()
        self.dt_label.setObjectName("note")
        self.dt_label.setWordWrap(True)
        time_layout.addWidget(self.dt_label)
        layout.addWidget(time_box)

        for title, params in default_params():
            box = QtWidgets.QGroupBox(title)
            box_layout = QtWidgets.QVBoxLayout(box)
            for param in params:
                control = ParamControl(param)
                control.valueChanged.connect(lambda value, key=param.key: self._on_change(key, value))
                box_layout.addWidget(control)
                self.controls[param.key] = control
                self._group_of[param.key] = title
            self.groups[title] = box
            layout.addWidget(box)

        display = QtWidgets.QGroupBox("Display")
        display_layout = QtWidgets.QVBoxLayout(display)
        self.shadows = QtWidgets.QCheckBox("Sun shadows")
        self.shadows.setChecked(True)
        self.shadows.setToolTip("Shadows need a second drawing pass: turn them off for speed without a GPU.")
        self.shadows.toggled.connect(self.shadowsToggled)
        display_layout.addWidget(self.shadows)
        self.joints = QtWidgets.QCheckBox("Joints (J)")
        self.joints.setChecked(False)
        self.joints.setToolTip("Draw each joint: rods from the bodies' centres to its anchors, a dot on each anchor.")
        self.joints.toggled.connect(self.jointsToggled)
        display_layout.addWidget(self.joints)
        layout.addWidget(display)

        self.defaults_button = QtWidgets.QPushButton("Scene values")
        self.defaults_button.setToolTip("Put every control back to the value the scene started with.")
        self.defaults_button.clicked.connect(self.restore_scene_values)
        layout.addWidget(self.defaults_button)
        layout.addStretch(1)

    def bind(self, world, *, keep_user_values: bool = False) -> None:
        """Show `world`'s values; with `keep_user_values`, write the user's changes into it instead.

        Groups that do not apply to this world (no cloth, no emitters) are disabled with a reason.
        """
        self.world = world
        self.dt_label.setText(
            f"step dt = {world.dt * 1000:.3g} ms (fixed; {1 / world.dt:.0f} steps per simulated second)"
        )
        disabled: dict[str, str] = {}
        self.scene_values = {}
        for key, control in self.controls.items():
            value = control.param.read(world)
            group = self._group_of[key]
            if value is None:
                disabled[group] = {
                    "Wind": "This scene has no cloth; wind acts on cloth only.",
                    "Emitters": "This scene has no emitters.",
                }.get(group, "Not available in this scene.")
                continue
            self.scene_values[key] = value
            if keep_user_values and control.touched:
                control.param.write(world, control.value())
            else:
                control.touched = False
                control.set_value(value)
        for title, box in self.groups.items():
            reason = disabled.get(title)
            box.setEnabled(reason is None)
            box.setToolTip(reason or "")
            box.setTitle(title + (" — not in this scene" if reason else ""))

    def restore_scene_values(self) -> None:
        """Forget the user's changes: put the scene's own values back into the controls and the world."""
        for key, value in self.scene_values.items():
            control = self.controls[key]
            control.set_value(value)
            control.touched = False
            self._write(key, value)

    def _on_change(self, key: str, value: float) -> None:
        self._write(key, value)
        self.changed.emit(key, value)

    def _write(self, key: str, value: float) -> None:
        world, write = self.world, self.controls[key].param.write
        if world is not None:
            self.apply(lambda: write(world, value))
