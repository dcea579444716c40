"""Issue 14 (a new user's first hour), first run: kernels kept compiling inside the timed steps
(45.7 steps/s cold against 798 warm), and "preparing kernels" was printed on every run."""

import re
import subprocess
import sys

import pytest
import warp as wp

import tumble
from tumble.runtime import kernel_modules, kernels_to_compile, prepare_kernels


def _world_with_cloth():
    world = tumble.World()
    world.add_plane()
    world.add_sphere(position=(0, 0, 1), radius=0.1)
    world.add_cloth(size=(0.5, 0.5), resolution=(4, 4), pins="top-edge")
    return world


def test_every_module_a_world_uses_is_listed_and_an_empty_cache_compiles_them_all(tmp_path, monkeypatch):
    """kernel_modules covers collision, solver and cloth; with an empty cache all are to compile, after prepare none."""
    _world_with_cloth()
    names = {m.name for m in kernel_modules()}
    for name in (
        "tumble.collision.narrowphase",
        "tumble.solver.contacts",
        "tumble.solver.integrate",
        "tumble.cloth.springs",
    ):
        assert name in names
    prepare_kernels("cpu")
    assert kernels_to_compile("cpu") == []
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    assert sorted(kernels_to_compile("cpu")) == sorted(names)


def _run(env, scene="bouncing_ball", duration="1"):
    return subprocess.run(
        [sys.executable, "-m", "tumble", "run", scene, "--duration", duration],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )


def _speed(stdout: str) -> float:
    return float(re.search(r"speed\s+([\d,.]+) steps/s", stdout).group(1).replace(",", ""))


def test_a_warm_run_says_nothing_about_compiling(tumble_subprocess_env):
    """With the kernels cached, `tumble run` prints no compile message."""
    tumble.load_scene("bouncing_ball")
    prepare_kernels("cpu")  # (this test's own process fills the cache first)
    result = _run(tumble_subprocess_env)
    assert result.returncode == 0, result.stderr
    assert "compil" not in result.stderr and "preparing" not in result.stderr


@pytest.mark.slow
def test_a_cold_run_says_it_compiles_and_its_speed_matches_a_warm_run(tumble_subprocess_env, tmp_path):
    """Empty kernel cache: the compile is announced and done before the clock; steps/s within 20 % of warm."""
    env = dict(tumble_subprocess_env, WARP_CACHE_PATH=str(tmp_path / "cache"))
    cold = _run(env, "rain", "2")
    assert cold.returncode == 0, cold.stderr
    assert "compiling" in cold.stderr and "kernels compiled in" in cold.stderr
    warm = _run(env, "rain", "2")
    assert "compil" not in warm.stderr
    assert _speed(cold.stdout) == pytest.approx(_speed(warm.stdout), rel=0.2)
