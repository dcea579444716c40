"""The float types of one copy of the kernel modules: float64 here, float32 in `tumble._float32.real`.

Kernel modules take `float_t`, `vec3`, `quat`, `mat33` (and `vec2`, `mat22`) and the struct of body arrays
`BodyArrays` from here, never from `tumble.state`, so that each precision's copy of them
(`tumble.precision`) compiles with its own types.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import warp as wp

from .model import KERNEL_FIELDS
from .precision import precision_of_module, specialize, types_of
from .structs import array_struct

#: the precision of this copy of the kernels
PRECISION = precision_of_module(__name__)
TYPES = types_of(PRECISION)

if TYPE_CHECKING:  # type checkers see the float64 copy's types (their operators are the same)
    float_t = wp.float64
    vec3 = wp.vec3d
    quat = wp.quatd
    mat33 = wp.mat33d
    vec2 = wp.vec2d
    mat22 = wp.mat22d
else:
    float_t = TYPES.float_t
    vec3 = TYPES.vec3
    quat = TYPES.quat
    mat33 = TYPES.mat33
    vec2 = TYPES.vec2
    mat22 = TYPES.mat22

#: quantities carried through many substeps that must not pick up float32's rounding bias (the free
#: rotation: solver/integrate.py), and a joint's ill-conditioned block factor (solver/joints.py), are
#: worked in float64 in both copies
wide_t = wp.float64
vec3w = wp.vec3d
quatw = wp.quatd
mat33w = wp.mat33d

#: the body arrays the kernels read and write, as one struct (contacts, joints, cloth coupling and pins alike):
#: `body_position` is `b.position`
BodyArrays = array_struct(
    "BodyArrays", {f.name: specialize(f.dtype, PRECISION) for f in KERNEL_FIELDS}, "body_", __name__
)
