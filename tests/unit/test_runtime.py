"""Warp start-up: a CPU user sees no CUDA-driver warning, and other native output still shows."""

from __future__ import annotations

import subprocess
import sys

from tumble.runtime import unexpected_lines


def test_only_the_expected_no_gpu_line_is_dropped():
    text = (
        "Warp CUDA warning: Could not find or load the NVIDIA CUDA driver. GPU execution will not be available.\n"
        "Warp error: something else went wrong\n"
    )
    assert unexpected_lines(text) == "Warp error: something else went wrong\n"
    assert unexpected_lines("") == ""


def test_making_a_world_writes_nothing_to_stderr():
    code = "import tumble; w = tumble.World(); w.add_plane(); w.add_sphere(position=(0, 0, 1), radius=0.1, mass=1); w.step()"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
