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
