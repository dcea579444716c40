"""The viewer on a world with cloth: wind controls and pulling a cloth particle."""

import math

import numpy as np
import pytest
from PySide6 import QtCore

import tumble

pytest.importorskip("tumble.cloth.system")  # the cloth lives on its own branch until merged

Qt = QtCore.Qt


def make_cloth_world():
    """A 12 x 12 cloth hanging from two corners in a light wind."""
    world = tumble.World(dt=1.0 / 240.0, substeps=2)
    world.add_plane()
    world.add_cloth(size=(1.0, 1.0), resolution=(12, 12), position=(0.0, 0.0, 1.0), mass=0.2, pins="top-corners")
    world.set_wind(velocity=(1.0, 0.0, 0.0), turbulence=0.5, scale=0.5, seed=1, drag=1.0, lift=0.2)
    return world


@pytest.fixture
def window(open_viewer):
    """A paused 320x240 viewer on `make_cloth_world`, saving into tmp_path."""
    return open_viewer(make_cloth_world)


def test_wind_controls_set_the_cloth_wind(window):
    """Speed and direction sliders rebuild the wind; turbulence, scale and face coefficients are kept."""
    controls = window.controls.controls
    assert window.controls.groups["Wind"].isEnabled()
    assert controls["wind_speed"].value() == pytest.approx(1.0)
    controls["wind_speed"].spin.setValue(5.0)
    controls["wind_heading"].spin.setValue(90.0)
    wind = window.world.cloth.wind
    np.testing.assert_allclose(wind.velocity, [0.0, 5.0, 0.0], atol=1e-9)
    assert wind.turbulence == pytest.approx(0.5) and wind.scale == pytest.approx(0.5)
    assert wind.drag == pytest.approx(1.0) and wind.lift == pytest.approx(0.2)
    controls["wind_turbulence"].spin.setValue(2.0)
    assert window.world.cloth.wind.turbulence == pytest.approx(2.0)
    assert "particles 144" in window.status_text()


def test_drag_pulls_a_cloth_particle(window, qtbot):
    """Pressing on a free cloth particle grabs it; pulling towards the camera moves it that way."""
    cloth = window.world.cloth
    free = np.flatnonzero(np.asarray(cloth.particle_inv_mass) > 0)
    i = int(free[len(free) // 2])
    w, h = window.view.width(), window.view.height()
    x, y, depth = window.camera.project(cloth.particle_position[i], w, h)
    qtbot.mousePress(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(int(x), int(y)))
    held = window.held
    assert held is not None and held.kind == "particle"
    qtbot.mouseMove(window.view, QtCore.QPoint(int(x), int(y) - 60))
    start = np.array(cloth.particle_position[held.index])
    for _ in range(30):
        window.step()
    moved = np.array(window.world.cloth.particle_position[held.index]) - start
    toward = held.target - start
    assert moved @ toward / np.linalg.norm(toward) > 0.02  # at least 2 cm towards the cursor
    assert math.isfinite(float(np.abs(window.world.cloth.particle_position).max()))
