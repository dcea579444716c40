"""io/scene/verify.py: check_world reports what a stepped world fails of its [check] table."""

from __future__ import annotations

import tumble
from tumble.io.scene import check_world


def test_check_world_reports_a_body_behind_a_plane(write_scene):
    """Fail the generic check when a body centre is behind a plane or too far away."""
    world = tumble.load_scene(
        write_scene(
            "[[plane]]\n[[sphere]]\nposition = [0, 0, -0.5]\nradius = 0.1\n"
            "[[sphere]]\nposition = [500, 0, 1]\nradius = 0.1\n"
        )
    )
    failures = check_world(world)
    assert any("behind plane 0" in f for f in failures)
    assert any("max_extent" in f for f in failures)


def test_check_world_applies_the_sample_limits(write_scene):
    """Fail min_z and max_speed limits given in [check]."""
    world = tumble.load_scene(
        write_scene(
            "[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\nvelocity = [3, 0, 0]\n[check]\nmin_z = 2\nmax_speed = 1\n"
        )
    )
    failures = check_world(world)
    assert any("min_z" in f for f in failures) and any("max_speed" in f for f in failures)


def test_check_world_passes_a_ball_at_rest_on_the_floor(write_scene):
    """Report no failure for a world inside every limit, with the [check] defaults when it has none."""
    world = tumble.load_scene(write_scene("[[plane]]\n[[sphere]]\nposition = [0, 0, 0.1]\nradius = 0.1\n"))
    world.run(0.1)
    assert check_world(world) == []
    assert check_world(world, {"max_extent": 100.0, "max_kinetic_energy": 1.0}) == []


def test_check_world_reports_energy_and_extent_limits_given_by_the_caller(write_scene):
    """Apply the caller's table rather than the scene's: kinetic energy and max_extent."""
    world = tumble.load_scene(write_scene("[[sphere]]\nposition = [0, 0, 3]\nradius = 0.1\nvelocity = [0, 0, 2]\n"))
    failures = check_world(world, {"max_extent": 1.0, "max_kinetic_energy": 0.1})
    assert any("max_extent 1" in f for f in failures)
    assert any("max_kinetic_energy 0.1" in f for f in failures)
