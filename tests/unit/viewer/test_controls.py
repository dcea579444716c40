"""The live controls panel (tumble.viewer.controls): its parameters read and write a world; in a window,
its sliders change the running world, and groups that do not apply are disabled."""

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

import tumble  # noqa: E402
from tumble.viewer.controls import default_params, wind_state  # noqa: E402

from . import make_cloth_world  # noqa: E402

DT = 1.0 / 240.0


def make_world():
    """A ground plane and three spheres at rest in the air, friction 0.5, restitution 0.3."""
    world = tumble.World(gravity=(0.0, 0.0, -9.81), dt=DT, substeps=2)
    world.add_plane(restitution=0.3, friction=0.5)
    for p in [(-0.4, 0.0, 0.3), (0.0, 0.0, 0.6), (0.4, 0.0, 0.3)]:
        world.add_sphere(position=p, radius=0.1, mass=1.0, restitution=0.3, friction=0.5)
    return world


@pytest.fixture
def cloth_window(open_viewer):
    """A paused 320x240 viewer on `make_cloth_world`, saving into tmp_path."""
    pytest.importorskip("tumble.cloth.system")
    return open_viewer(make_cloth_world)


@pytest.fixture
def window(open_viewer):
    """A paused 320x240 viewer on `make_world`, saving into tmp_path."""
    return open_viewer(make_world)


def _params():
    return {p.key: p for _, group in default_params() for p in group}


def test_parameters_have_unique_keys_and_read_values_in_their_range():
    """Every parameter has its own key, a range low < high, and reads a value inside it from a plain scene."""
    groups = default_params()
    keys = [p.key for _, group in groups for p in group]
    assert len(keys) == len(set(keys))
    assert {"gravity_z", "friction", "restitution", "substeps", "wind_speed", "emission_rate"} <= set(keys)
    world = make_world()
    values = {}
    for p in _params().values():
        assert p.minimum < p.maximum, p.key
        values[p.key] = value = p.read(world)
        assert value is None or p.minimum <= value <= p.maximum, (p.key, value)
    assert values["gravity_z"] == pytest.approx(-9.81) and values["gravity_x"] == 0.0
    assert values["friction"] == pytest.approx(0.5) and values["restitution"] == pytest.approx(0.3)
    assert values["substeps"] == 2


def test_material_reads_the_median_of_the_moving_bodies_and_writes_every_body():
    """Friction reads as the median over dynamic bodies (static ones left out); writing sets it on all."""
    world = tumble.World()
    world.add_plane(friction=0.9)
    for f in (0.2, 0.6, 0.3):
        world.add_sphere(position=(0.0, 0.0, 1.0), radius=0.1, friction=f)
    world.add_box(position=(1.0, 0.0, 0.5), half_extents=(0.1, 0.1, 0.1), static=True, friction=0.95)
    friction = _params()["friction"]
    assert friction.read(world) == pytest.approx(0.3)  # median of 0.2, 0.6, 0.3; not of 0.9 and 0.95 too
    friction.write(world, 0.7)
    np.testing.assert_allclose(world.body_friction, 0.7)


def test_gravity_components_write_only_their_axis():
    """gravity_x writes world.gravity[0] and keeps y and z."""
    world = make_world()
    gx = _params()["gravity_x"]
    gx.write(world, 2.5)
    np.testing.assert_allclose(world.gravity, [2.5, 0.0, -9.81])
    assert gx.read(world) == pytest.approx(2.5)


def test_wind_and_emitter_parameters_do_not_apply_to_a_scene_without_them():
    """Without cloth there is no wind state and the wind reads None; without emitters the rate reads None."""
    world = make_world()
    assert wind_state(world) is None
    params = _params()
    assert params["wind_speed"].read(world) is None
    assert params["emission_rate"].read(world) is None


def test_wind_controls_set_the_cloth_wind(cloth_window):
    window = cloth_window
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


def test_sliders_change_the_running_world(window):
    """Gravity, friction, restitution and substeps controls write into the world at once."""
    controls = window.controls.controls
    gz = controls["gravity_z"]
    gz.slider.setValue(gz.slider.maximum())  # slider end = +10 m/s^2
    assert window.world.gravity[2] == pytest.approx(10.0)
    assert gz.spin.value() == pytest.approx(10.0)
    assert gz.spin.suffix().strip() == "m/s²"

    controls["friction"].spin.setValue(1.25)
    np.testing.assert_allclose(window.world.body_friction, 1.25)
    controls["restitution"].spin.setValue(0.8)
    np.testing.assert_allclose(window.world.body_restitution, 0.8)
    controls["substeps"].spin.setValue(7)
    assert window.world.substeps == 7

    window.controls.restore_scene_values()
    assert window.world.gravity[2] == pytest.approx(-9.81)
    np.testing.assert_allclose(window.world.body_friction, 0.5)


def test_groups_that_do_not_apply_are_disabled(window):
    """Without cloth or emitters, the wind and emitter groups are disabled and say why."""
    assert not window.controls.groups["Wind"].isEnabled()
    assert "cloth" in window.controls.groups["Wind"].toolTip()
    assert not window.controls.groups["Emitters"].isEnabled()
    assert window.controls.groups["Gravity"].isEnabled()


def test_emission_rate_control_sets_every_emitter(qtbot, tmp_path):
    """The emission-rate control writes emitter.rate; at 0 no more bodies appear."""
    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerWindow

    def build():
        world = make_world()
        world.add_emitter(shape="sphere", rate=240.0, count=50, position=(0.0, 0.0, 1.5), radius=0.03)
        world.add_emitter(shape="box", rate=120.0, count=50, position=(1.0, 0.0, 1.5), half_extents=0.03)
        return world

    make_application()
    win = ViewerWindow(factory=build, size=(320, 240), paused=True, view="image", output_dir=tmp_path)
    qtbot.addWidget(win)
    control = win.controls.controls["emission_rate"]
    assert win.controls.groups["Emitters"].isEnabled()
    assert control.value() == 240.0
    control.spin.setValue(0.0)
    assert [e.rate for e in win.world.emitters] == [0.0, 0.0]
    n = win.world.body_count
    for _ in range(10):
        win.step()
    assert win.world.body_count == n
    control.spin.setValue(480.0)
    for _ in range(10):
        win.step()
    assert win.world.body_count > n
    win.close()
