"""The viewer's joint toggle, dragging jointed bodies, and picking capsules and hulls (pytest-qt, offscreen)."""

import math

import numpy as np
import pytest
from PySide6 import QtCore

import tumble

Qt = QtCore.Qt
DT = 1.0 / 240.0
PIVOT = (0.0, 0.0, 1.0)
BOB = (0.0, 0.0, 0.5)


def pendulum_world():
    """A 0.1 m ball hung 0.5 m under a world pivot by a ball joint (a rigid rod), beside a capsule and a hull."""
    world = tumble.World(dt=DT, substeps=4)
    world.add_plane()
    bob = world.add_sphere(position=BOB, radius=0.1, mass=1.0)
    world.add_joint("ball", None, bob, anchor=PIVOT)
    q = (0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4))
    world.add_capsule(position=(-0.5, 0.0, 0.1), radius=0.08, half_height=0.15, orientation=q)
    pytest.importorskip("scipy")
    tetra = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.3]])
    world.add_convex(points=tetra, position=(0.4, 0.0, 0.0))
    world.metadata["camera"] = {"position": [0.0, -3.0, 0.8], "target": [0.0, 0.0, 0.5], "fov": 40}
    return world


@pytest.fixture
def window(open_viewer):
    return open_viewer(pendulum_world)


def _pixel_of(window, point):
    x, y, depth = window.camera.project(np.asarray(point, dtype=float), window.view.width(), window.view.height())
    assert depth > 0
    return int(x), int(y)


def test_joint_toggle_draws_the_joints(window, qtbot):
    """The Display box's Joints checkbox (and key J) turns the overlay on: the rod shows, then goes again."""
    assert not window.controls.joints.isChecked() and not window.view.show_joints
    before = window.view.render_image()
    window.controls.joints.setChecked(True)
    assert window.view.show_joints
    shown = window.view.render_image()
    x, y = _pixel_of(window, (0.0, 0.0, 0.8))  # on the rod from the pivot to the ball
    assert np.abs(shown[y, x].astype(int) - before[y, x].astype(int)).max() > 40
    qtbot.keyClick(window.view, Qt.Key.Key_J)
    assert not window.controls.joints.isChecked() and not window.view.show_joints
    np.testing.assert_array_equal(window.view.render_image(), before)


def test_snapshot_carries_the_joint_lines(window):
    """The window draws a snapshot: it holds one joint row, the pivot and the ball's centre."""
    lines = window.scene.joint_lines
    assert lines.shape == (1, 4, 3)
    np.testing.assert_allclose(lines[0, 1], PIVOT)
    np.testing.assert_allclose(lines[0, 3], BOB)


def test_dragging_a_jointed_body_swings_it_on_its_joint(window, qtbot):
    """Grab the hanging ball and pull sideways: it swings out about the pivot and stays 0.5 m from it."""
    x, y = _pixel_of(window, BOB)
    qtbot.mousePress(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(x, y))
    assert window.held is not None and window.held.kind == "body" and window.held.index == 1
    qtbot.mouseMove(window.view, QtCore.QPoint(x + 60, y))
    assert window.held.target[0] > 0.2
    for _ in range(120):
        window.step()
    p = window.world.body_position[1]
    assert p[0] > 0.1  # pulled out to the side ...
    assert np.linalg.norm(p - PIVOT) == pytest.approx(0.5, abs=2e-3)  # ... on its rod
    assert window.world.joint_error[0] < 2e-3
    qtbot.mouseRelease(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(x + 60, y))
    assert window.held is None


@pytest.mark.parametrize("index, point", [(2, (-0.5, 0.0, 0.1)), (3, (0.05, 0.0, 0.05))])
def test_pressing_on_a_capsule_or_a_hull_grabs_it(window, qtbot, index, point):
    """A click on the capsule or on the hull holds that body."""
    centre = np.asarray(window.scene.body_position)[index]
    target = centre if index == 2 else np.asarray((0.4, 0.0, 0.0)) + point
    x, y = _pixel_of(window, target)
    qtbot.mousePress(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(x, y))
    assert window.held is not None and window.held.index == index
    qtbot.mouseRelease(window.view, Qt.MouseButton.LeftButton, pos=QtCore.QPoint(x, y))
