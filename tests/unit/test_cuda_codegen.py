"""The CUDA path without a GPU: every Warp kernel of Tumble compiles to PTX for an H100 (sm_90).

`World(device="cuda")` runs the same kernels as the CPU, compiled by NVRTC, which ships in the
warp-lang wheel and needs no driver. Compiling them ahead of time catches code that only the
CPU compiler accepts; running them on a GPU is left to machines that have one.
"""

from __future__ import annotations

import importlib
import pkgutil

import pytest
import warp as wp

import tumble

SM_90 = 90  # NVIDIA H100
#: modules whose NVRTC compile takes too long for the default run (none now: the narrow phase,
#: whose one dispatch kernel inlines every collide_<a>_<b>, took over 15 minutes at -O3 while Warp
#: also generated its adjoint; with `enable_backward` off it compiles in about a minute)
SLOW_TO_COMPILE: set[str] = set()


def _kernel_modules() -> list[str]:
    names = []
    for info in pkgutil.walk_packages(tumble.__path__, "tumble."):
        if info.name.startswith(("tumble.viewer", "tumble.render")):
            continue  # GUI and OpenGL: no Warp kernels, and imports that need a display stack
        importlib.import_module(info.name)
        if wp.get_module(info.name).kernels:
            names.append(info.name)
    return names


def test_every_kernel_module_is_found():
    names = _kernel_modules()
    for expected in (
        "tumble.collision.broadphase",
        "tumble.collision.narrowphase",
        "tumble.solver.contacts",
        "tumble.solver.integrate",
        "tumble.cloth.springs",
    ):
        assert expected in names


@pytest.mark.parametrize("name", _kernel_modules())
def test_kernel_modules_compile_forward_code_only(name):
    # nothing in Tumble differentiates through its kernels; the adjoint code doubled the CPU compile
    # of a first run (a hammock sample: 68 s cold, 29 s without it) and the PTX compile of this file
    assert wp.get_module(name).options["enable_backward"] is False, f"{name}: set enable_backward False"


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_TO_COMPILE else n for n in _kernel_modules()]
)
def test_kernels_compile_for_cuda(name, tmp_path):
    files = wp.compile_aot_module(name, arch=SM_90, module_dir=tmp_path, use_ptx=True)
    ptx = [f for f in map(str, files) if f.endswith(".ptx")] or [str(p) for p in tmp_path.glob("*.ptx")]
    assert ptx, f"no PTX written for {name}"
    text = open(ptx[0]).read()
    assert ".target sm_90" in text
    # every kernel of the module has an entry point in the PTX
    for key in wp.get_module(name).kernels:
        assert key.split(".")[-1] in text, f"kernel {key} missing from the PTX of {name}"
