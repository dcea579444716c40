"""Shared fixtures: headless Qt, scene files written on the fly, a subprocess environment, one GL context, viewers."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

# Hypothesis draws the same examples on every run (derived from each test), so that a CI run on a
# fresh machine is as repeatable as the engine; HYPOTHESIS_PROFILE=explore draws new ones each run
settings.register_profile("repeatable", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))

SRC = Path(__file__).resolve().parents[1] / "src"


def pytest_addoption(parser):
    parser.addoption(
        "--precision",
        choices=("float32", "float64"),
        default=None,
        help="the precision of the tests' worlds (default: Tumble's default); tests marked float64 keep float64",
    )


#: folders and files (under tests/) whose tests run in both precisions when `--precision` names none:
#: the numerics float32 must hold as float64 does (collision, the solvers, the cloth) and the physics
#: files that pass in float32 (test_independent_checks and test_cloth_coupling still fail 7 tests
#: there: friction and spring loads short by rounding of positions past 1 m, a drape; `pytest
#: --precision float32 tests/physics` lists them)
BOTH_PRECISIONS = (
    "unit/collision",
    "unit/solver",
    "unit/cloth",
    *(
        f"physics/test_{name}.py"
        for name in (
            "capsules", "cloth", "cloth_mesh_features", "convex_bodies", "free_rotation", "joints",
            "kinematic", "meshes", "mixed_scene", "particles", "restitution", "rigid_bodies", "stacks",
        )
    ),
)  # fmt: skip
TESTS = Path(__file__).resolve().parent


def pytest_generate_tests(metafunc):
    """Tests in `BOTH_PRECISIONS`, and tests marked `both_precisions` elsewhere, run once in each
    precision (ids [float32], [float64]), unless marked float64 or slow, or run with `--precision`."""
    if "_precision" not in metafunc.fixturenames:
        return
    if metafunc.config.getoption("--precision") is not None or metafunc.definition.get_closest_marker("float64"):
        return
    if metafunc.definition.get_closest_marker("slow"):
        return  # the long runs stay one each (in float32: `-m slow --precision float32`)
    path = Path(str(metafunc.definition.fspath)).resolve().relative_to(TESTS).as_posix()
    listed = any(path == d or path.startswith(d + "/") for d in BOTH_PRECISIONS)
    if listed or metafunc.definition.get_closest_marker("both_precisions"):
        metafunc.parametrize("_precision", ["float32", "float64"], indirect=True)


@pytest.fixture(autouse=True)
def _precision(request, monkeypatch):
    """`@pytest.mark.float64("why")`: the test's worlds default to float64, for bookkeeping that float32
    cannot keep (momentum or energy to ~1e-12). Every other test runs in Tumble's default precision,
    or in the one `--precision` names (`pytest --precision float32 tests/physics`), or in each
    (`BOTH_PRECISIONS`)."""
    marker = request.node.get_closest_marker("float64")
    precision = getattr(request, "param", None) or request.config.getoption("--precision")
    if marker is not None:
        if not (marker.args and isinstance(marker.args[0], str) and marker.args[0]):
            raise pytest.UsageError(f"{request.node.nodeid}: @pytest.mark.float64 needs a reason")
        precision = "float64"
    if precision is not None:
        import tumble.precision

        monkeypatch.setattr(tumble.precision, "DEFAULT_PRECISION", precision)


@pytest.fixture
def write_scene(tmp_path):
    """Write TOML text to a file under tmp_path and return its path: write_scene(text, name="scene.toml")."""

    def write(text: str, name: str = "scene.toml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write


@pytest.fixture
def tumble_subprocess_env():
    """Environment for `python -m tumble.cli` in a subprocess, importing this checkout's src."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PYTHONIOENCODING"] = "utf-8"
    env["COLUMNS"] = "120"
    return env


# ------------------------------------------------------------------------------------------------ renderer
# The renderer's tests (tests/unit/render, tests/unit/io/test_video.py, tests/unit/commands/test_render.py,
# the regression pictures) share one headless GL context (EGL, Mesa llvmpipe) per session. Imports are
# made when a fixture is first used, so that a test session without them never loads moderngl.


@pytest.fixture(scope="session")
def gl_context():
    """A headless moderngl context shared by the session's tests."""
    from tumble.render import create_context

    return create_context()


@pytest.fixture(scope="session")
def renderer(gl_context):
    """A small renderer (160 x 120); tests resize it as they need."""
    from tumble.render import Renderer

    r = Renderer(gl_context, 160, 120)
    yield r
    r.release()


@pytest.fixture
def small_renderer(renderer):
    """The session renderer reset to 160 x 120 with default settings."""
    renderer.resize(160, 120)
    renderer.shadows = True
    renderer.ground_cell_size = 1.0
    return renderer


class GridCloth:
    """Stand-in for a ClothSystem: a bent nx x ny grid with the views the renderer reads."""

    def __init__(self, nx: int = 12, ny: int = 10, *, centre=(0.0, 0.0, 0.8), size=1.2):
        import numpy as np

        x, y = np.meshgrid(np.linspace(-0.5, 0.5, nx) * size, np.linspace(-0.5, 0.5, ny) * size)
        z = 0.15 * np.sin(3.0 * x) * np.cos(2.0 * y)
        self.particle_position = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1) + np.asarray(centre)
        idx = np.arange(nx * ny).reshape(ny, nx)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
        self.triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
        self.particle_count = nx * ny


def world_with_cloth_class():
    """`WorldWithCloth`: a World whose cloth is a stand-in (`GridCloth`); the renderer reads only
    `has_cloth` and `cloth`. (Made on first use, so that importing this conftest does not import tumble.)"""
    import tumble

    class WorldWithCloth(tumble.World):
        def __init__(self, cloth, **settings):
            super().__init__(**settings)
            self.stand_in = cloth

        @property
        def has_cloth(self) -> bool:
            return True

        @property
        def cloth(self):
            return self.stand_in

    return WorldWithCloth


@pytest.fixture
def cloth_world():
    """Factory of `WorldWithCloth`: cloth_world(make_cloth(...)) is an empty World showing that cloth."""
    return world_with_cloth_class()


def falling_world(n: int = 3):
    """A ground plane and `n` spheres side by side, dropped from different heights."""
    import tumble

    world = tumble.World(dt=1.0 / 120.0)
    world.add_plane()
    for i in range(n):
        world.add_sphere(position=(0.4 * (i - (n - 1) / 2), 0.0, 0.6 + 0.2 * i), radius=0.12, mass=1.0)
    return world


@pytest.fixture
def make_falling_world():
    """Factory of `falling_world` scenes."""
    return falling_world


@pytest.fixture
def make_cloth():
    """Factory of `GridCloth` stand-ins."""
    return GridCloth


def chroma(rgb):
    """Chromaticity r, g, b / (r + g + b): colour without brightness, so shading does not change it."""
    import numpy as np

    c = np.asarray(rgb, dtype=np.float64).reshape(-1, 3)
    return c / np.maximum(c.sum(axis=1, keepdims=True), 1e-9)


@pytest.fixture
def chromaticity():
    return chroma


# ------------------------------------------------------------------------------------------------ viewer
# Viewer tests (tests/unit/viewer, tests/viewer) run on Qt's offscreen platform (no display, no GPU): the
# window uses the EGL image view.


@pytest.fixture
def open_viewer(qtbot, tmp_path):
    """open_viewer(factory): a paused 320x240 viewer (offscreen image view) saving into tmp_path."""
    pytest.importorskip("PySide6")
    from tumble.viewer import make_application
    from tumble.viewer.window import ViewerWindow

    make_application()
    windows = []

    def open_(factory):
        win = ViewerWindow(factory=factory, size=(320, 240), paused=True, view="image", output_dir=tmp_path)
        qtbot.addWidget(win)
        win.show()
        qtbot.waitExposed(win)
        windows.append(win)
        return win

    yield open_
    for win in windows:
        win.close()
