"""The cloth's arrays, each declared once, and the Warp structs that the cloth's kernels take.

`PARTICLE_FIELDS` declares the per-particle arrays (the parts' rows, their recording and their
docs derive from it); the topology tables declare the arrays of the springs, the stretch limit
and the tethers (`ClothModel.topology`). Each table gives its struct (`Particles`, `Springs`,
`Stretch`, `Structural`, `Limits`, `Tethers`), whose fields are the table's names without
their entity: `particle_position` is `particles.position` in a kernel.

A kernel module: its float types, and so its structs, are those of its precision's copy
(`tumble.precision`).
"""

from __future__ import annotations

from typing import Any

import warp as wp

from ..model import Field, Role, fields_of
from ..real import float_t, vec3
from ..structs import array_struct

#: every per-particle array, declared once (as `tumble.model.BODY_FIELDS` declares the body arrays)
PARTICLE_FIELDS: tuple[Field, ...] = (
    Field("particle_mass", float_t, Role.MODEL, "kg", "mass"),
    Field("particle_inv_mass", float_t, Role.MODEL, "1/kg", "inverse mass, 0 = pinned (pins may change it)"),
    Field("particle_thickness", float_t, Role.MODEL, "m", "collision thickness"),
    Field("particle_friction", float_t, Role.MODEL, "", "friction coefficient"),
    Field("particle_cloth", wp.int32, Role.MODEL, "", "index of the cloth in creation order"),
    Field("particle_i", wp.int32, Role.MODEL, "", "grid column in its cloth"),
    Field("particle_j", wp.int32, Role.MODEL, "", "grid row in its cloth"),
    Field("particle_rest_position", vec3, Role.MODEL, "m", "position in the rest shape"),
    Field("particle_position", vec3, Role.STATE, "m", "position"),
    Field("particle_velocity", vec3, Role.STATE, "m/s", "velocity"),
    Field("particle_pin_target", vec3, Role.STATE, "m", "where a pinned particle should be at the end of the step"),
    Field("particle_position_prev", vec3, Role.SCRATCH, "m", "position at the start of the substep"),
    Field("particle_force", vec3, Role.SCRATCH, "N", "force accumulated over the substep"),
    Field("particle_external_force", vec3, Role.CONTROL, "N", "user force for the current step"),
    Field("particle_wind", vec3, Role.SCRATCH, "m/s", "wind velocity at the particle this step"),
    Field(
        "particle_pin_load", vec3, Role.SCRATCH, "kg m", "the stretch limit's and tethers' pull on a pin, this substep"
    ),
    Field(
        "particle_support",
        vec3,
        Role.SCRATCH,
        "",
        "sum of the outward normals of the static bodies the particle touched in the last contact pass",
    ),
    Field("particle_tether_first", wp.int32, Role.MODEL, "", "first tether of the particle (derived from the pins)"),
    Field("particle_tether_count", wp.int32, Role.MODEL, "", "its number of tethers (derived from the pins)"),
)

#: particle indices, a row per spring (its two particles) or triangle (its three corners), int32
INDICES: Any = wp.array2d(dtype=wp.int32)

# the topology tables, one row per spring, limit entry or tether (`ClothModel.topology`), name -> row type
#: every spring of every kind (structural, shear, bend), all cloths
SPRING_FIELDS = {
    "spring_ids": INDICES,  # its particles (i, j), (m, 2)
    "spring_rest_length": float_t,  # l0 [m]
    "spring_stiffness": float_t,  # ks [N/m]
    "spring_damping": float_t,  # kd [N s/m]
}
#: the structural springs (what `ClothSystem.max_strain` measures)
STRUCTURAL_FIELDS = {
    "structural_ids": INDICES,  # its particles (i, j), (s, 2)
    "structural_rest_length": float_t,  # l0 [m]
}
#: the springs the stretch limit holds: the structural springs of cloths with a `max_stretch`
STRETCH_FIELDS = {
    "stretch_ids": INDICES,  # its particles (i, j), (s, 2)
    "stretch_limit": float_t,  # largest length (1 + max_stretch) l0 [m]
}
#: each particle's limited springs (rows `limit_first` .. + `limit_count` of a particle, sorted by particle)
LIMIT_FIELDS = {
    "limit_first": wp.int32,  # per particle: its first entry
    "limit_count": wp.int32,  # per particle: its number of entries
    "limit_other": wp.int32,  # per entry: the spring's other particle
    "limit_length": float_t,  # per entry: the spring's largest length [m]
}
#: each particle's tethers to the pins of its cloth (rows `particle_tether_first` .. + `particle_tether_count`)
TETHER_FIELDS = {
    "tether_pin": wp.int32,  # the pinned particle it holds to
    "tether_limit": float_t,  # its largest length [m]
}
#: the rest of the topology: triangles (T, 3) (the wind's and the triangle contacts') and the pinned particles
OTHER_TOPOLOGY = {"triangles": INDICES, "pin_index": wp.int32}
#: every array of `ClothModel.topology`, name -> row type
TOPOLOGY = {**SPRING_FIELDS, **STRUCTURAL_FIELDS, **STRETCH_FIELDS, **LIMIT_FIELDS, **TETHER_FIELDS, **OTHER_TOPOLOGY}

#: the particle arrays as the kernels take them: `particle_position` is `particles.position`
Particles = array_struct("Particles", fields_of(PARTICLE_FIELDS), "particle_", __name__)
#: the springs: `spring_ids` is `springs.ids`
Springs = array_struct("Springs", SPRING_FIELDS, "spring_", __name__)
#: the structural springs: `structural_rest_length` is `structural.rest_length`
Structural = array_struct("Structural", STRUCTURAL_FIELDS, "structural_", __name__)
#: the limited springs: `stretch_limit` is `stretch.limit`
Stretch = array_struct("Stretch", STRETCH_FIELDS, "stretch_", __name__)
#: each particle's limited springs: `limit_other` is `limits.other`
Limits = array_struct("Limits", LIMIT_FIELDS, "limit_", __name__)
#: the tethers: `tether_pin` is `tethers.pin`
Tethers = array_struct("Tethers", TETHER_FIELDS, "tether_", __name__)


@wp.func
def corners(triangles: wp.array2d(dtype=wp.int32), t: int):
    """The three particles of triangle t."""
    return triangles[t, 0], triangles[t, 1], triangles[t, 2]
