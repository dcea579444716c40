"""tumble.real: the float types of one copy of the kernel modules."""

from __future__ import annotations

import importlib

import warp as wp

from tumble import real
from tumble.model import KERNEL_FIELDS
from tumble.precision import specialize


def test_the_float64_copy_has_float64_types():
    assert real.PRECISION == "float64"
    assert (real.float_t, real.vec3, real.quat, real.mat33) == (wp.float64, wp.vec3d, wp.quatd, wp.mat33d)
    assert (real.vec2, real.mat22) == (wp.vec2d, wp.mat22d)


def test_the_float32_copy_has_float32_types():
    r32 = importlib.import_module("tumble._float32.real")
    assert r32.PRECISION == "float32"
    assert (r32.float_t, r32.vec3, r32.quat, r32.mat33) == (wp.float32, wp.vec3f, wp.quatf, wp.mat33f)
    assert (r32.vec2, r32.mat22) == (wp.vec2f, wp.mat22f)


def test_body_arrays_has_every_kernel_field_in_the_copy_s_types():
    r32 = importlib.import_module("tumble._float32.real")
    for copy in (real, r32):
        fields = copy.BodyArrays.vars
        assert list(fields) == [f.name.removeprefix("body_") for f in KERNEL_FIELDS]
        for f in KERNEL_FIELDS:
            assert fields[f.name.removeprefix("body_")].type.dtype is specialize(f.dtype, copy.PRECISION)
