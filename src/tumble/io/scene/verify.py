"""Checking a stepped world against a sample's `[check]` table (`check_world`).

The sample tests and `tumble run` call it after running a scene headless: it returns the list
of failures, empty when the world passes.
"""

from __future__ import annotations

import numpy as np

from .parse import parse_table
from .schema import SCHEMA

# ---------------------------------------------------------------------------------------- checks


def check_world(world, check: dict | None = None) -> list[str]:
    """Failures of a world against a sample's [check] table (empty list = pass).

    Always: every body and cloth particle value finite, no dynamic body centre (or cloth particle)
    behind a plane, every coordinate within max_extent. Then the optional limits of `check`.
    """
    if check is None:
        check = world.metadata.get("check") or parse_table(SCHEMA["check"], {}, None, None)
    failures = []
    from ...shapes import ShapeType

    shape = np.asarray(world.body_shape)
    position = np.asarray(world.body_position)
    velocity = np.asarray(world.body_velocity)
    dynamic = np.asarray(world.body_inv_mass) > 0
    parts = [position[dynamic]]
    cloth = world.cloth if world.has_cloth else None
    if cloth is not None:
        parts.append(np.asarray(cloth.particle_position))
    points = np.concatenate(parts) if parts else np.zeros((0, 3))

    for name, values in (
        ("body_position", position),
        ("body_velocity", velocity),
        ("body_angular_velocity", np.asarray(world.body_angular_velocity)),
        ("cloth particle_position", points),
    ):
        if not np.isfinite(values).all():
            failures.append(f"{name} is not finite")
    if failures:
        return failures

    planes = np.nonzero(shape == ShapeType.PLANE)[0]
    normals = np.asarray(world.body_plane_normal)
    for p in planes:
        distance = (points - position[p]) @ normals[p]
        if len(distance) and distance.min() < 0.0:
            failures.append(f"a body centre is {-distance.min():.4g} m behind plane {p}")
    if len(points) and np.abs(points).max() > check["max_extent"]:
        failures.append(f"a body is {np.abs(points).max():.4g} m from the origin (max_extent {check['max_extent']:g})")
    if check.get("min_z") is not None and dynamic.any() and position[dynamic, 2].min() < check["min_z"]:
        failures.append(f"lowest body centre z = {position[dynamic, 2].min():.4g} m < min_z {check['min_z']:g}")
    if check.get("max_speed") is not None and dynamic.any():
        speed = float(np.linalg.norm(velocity[dynamic], axis=1).max())
        if speed > check["max_speed"]:
            failures.append(f"fastest body {speed:.4g} m/s > max_speed {check['max_speed']:g}")
    if check.get("max_kinetic_energy") is not None:
        energy = world.kinetic_energy()
        if energy > check["max_kinetic_energy"]:
            failures.append(f"kinetic energy {energy:.4g} J > max_kinetic_energy {check['max_kinetic_energy']:g}")
    if check.get("max_strain") is not None and cloth is not None:
        strain = float(cloth.max_strain())
        if strain > check["max_strain"]:
            failures.append(f"cloth strain {strain:.4g} > max_strain {check['max_strain']:g}")
    if check.get("max_joint_error") is not None and world.joint_count:
        drift = float(np.max(world.joint_error))
        if drift > check["max_joint_error"]:
            failures.append(f"joint drift {drift:.4g} m > max_joint_error {check['max_joint_error']:g}")
    return failures
