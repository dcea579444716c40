"""Warp start-up without the noise: `init_warp()` is `wp.init()` minus the CUDA-driver warning.

On a machine without an NVIDIA driver, Warp's native library writes "Could not find or load the
NVIDIA CUDA driver" to the process's stderr on every start, from C, where Python's
`warnings` cannot reach it. Tumble runs on the CPU by default, so that line tells a user
nothing; `init_warp` catches the native output of the first initialisation and passes on every
other line. `--device cuda` / `World(device="cuda")` still say clearly when there is no GPU.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from collections.abc import Callable

import warp as wp

#: native start-up lines dropped by `init_warp` (substrings)
EXPECTED_WITHOUT_GPU = ("Could not find or load the NVIDIA CUDA driver",)

_initialised = False


def init_warp() -> None:
    """Initialise Warp once, dropping the expected no-GPU warning from stderr."""
    global _initialised
    if _initialised:
        return
    _initialised = True
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        wp.init()  # no usable file descriptor 2: nothing to filter
        return
    with tempfile.TemporaryFile() as capture:
        try:
            os.dup2(capture.fileno(), 2)
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        capture.seek(0)
        text = capture.read().decode(errors="replace")
    kept = unexpected_lines(text)
    if kept:
        sys.stderr.write(kept)
        sys.stderr.flush()


def unexpected_lines(text: str) -> str:
    """The lines of Warp's native start-up output that `init_warp` passes on."""
    lines = text.splitlines(keepends=True)
    return "".join(line for line in lines if not any(s in line for s in EXPECTED_WITHOUT_GPU))


# ---------------------------------------------------------------------- kernel modules
#
# Warp compiles a module (one Python file's kernels) the first time one of its kernels is
# launched, so without a preload a cold run compiles during the timed steps: contacts when the
# first contact appears, emitters' kernels when the first body spawns. `prepare_kernels` loads
# every Tumble module that has been imported (a world imports what it uses: cloth only with
# cloth) before the clock starts; `kernels_to_compile` says beforehand whether that will
# compile anything, so a command can say what it is doing only when it is doing it.


def kernel_modules() -> list:
    """Warp modules of Tumble imported so far (`tumble.solver.contacts`, ...), sorted by name."""
    from warp._src.context import user_modules

    return [user_modules[name] for name in sorted(user_modules) if name.startswith("tumble.")]


def _launch_block_dim(module, device) -> int:
    # a CPU launch without an explicit block_dim uses 1; CUDA uses the module's option
    return 1 if device.is_cpu else int(module.options["block_dim"])


def kernels_to_compile(device="cpu") -> list[str]:
    """Names of the Tumble kernel modules that are not in Warp's kernel cache for `device`.

    Looks for each module's compiled binary under `wp.config.kernel_cache_dir` (where Warp
    itself looks). Where Warp's layout cannot be read, every module is listed (better to say
    "compiling" once too often than to leave a long silence unexplained).
    """
    init_warp()
    device = wp.get_device(device)
    missing = []
    for module in kernel_modules():
        try:
            assert wp.config.kernel_cache_dir is not None  # set by init_warp (if not: as any other failure here)
            block_dim = _launch_block_dim(module, device)
            directory = os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier(block_dim))
            binary = module._get_compile_output_name(device, block_dim=block_dim)
            cached = os.path.exists(os.path.join(directory, binary))
        except Exception:  # noqa: BLE001 (a private Warp detail changed: assume it compiles)
            cached = False
        if not cached:
            missing.append(module.name)
    return missing


def prepare_kernels(device="cpu", *, report: Callable[[str], None] | None = None) -> float:
    """Load every imported Tumble kernel module on `device`, compiling those not yet cached.

    Args:
        device: the Warp device the world runs on.
        report: called with one line before compiling ("compiling 5 Warp kernel modules ...")
            and one after ("kernels compiled in 64.4 s"), only when something is to compile.

    Returns:
        Seconds spent compiling (0.0 when every module was cached).
    """
    init_warp()
    device = wp.get_device(device)
    if not kernel_modules():
        return 0.0
    missing = kernels_to_compile(device)
    if missing and report is not None:
        report(
            f"compiling {len(missing)} Warp kernel modules (only on the first run on this machine; up to a minute)..."
        )
    start = time.perf_counter()
    # one call for all of them, so that Warp compiles several modules at once
    wp.load_module("tumble", device=device, recursive=True, block_dim=1 if device.is_cpu else None)
    seconds = time.perf_counter() - start if missing else 0.0
    if missing and report is not None:
        report(f"kernels compiled in {seconds:.1f} s")
    return seconds
