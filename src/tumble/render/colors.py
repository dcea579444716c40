"""Body colours: a stable hash of the body index into a small, pleasant palette.

The viewer and the exporter both call `body_colors`, so a body has the same colour on screen
and in a video, in every run, whatever else the scene holds.
"""

from __future__ import annotations

import numpy as np

#: sRGB colours in [0, 1], saturated enough to tell apart, light enough to shade well
PALETTE = np.array(
    [
        (0.894, 0.373, 0.318),  # coral red
        (0.949, 0.639, 0.235),  # amber
        (0.957, 0.820, 0.353),  # mustard
        (0.510, 0.765, 0.404),  # leaf green
        (0.271, 0.667, 0.592),  # teal
        (0.345, 0.604, 0.835),  # sky blue
        (0.447, 0.463, 0.808),  # indigo
        (0.690, 0.459, 0.800),  # lavender
        (0.906, 0.478, 0.655),  # rose
        (0.765, 0.565, 0.420),  # tan
        (0.820, 0.835, 0.863),  # pale grey
        (0.380, 0.784, 0.839),  # cyan
    ],
    dtype=np.float32,
)

#: colour of the cloth's front side (sRGB); the back is drawn a little lighter
CLOTH_COLOR = np.array((0.843, 0.298, 0.357), dtype=np.float32)


def _hash32(i: np.ndarray) -> np.ndarray:
    """Integer hash (xorshift-multiply, after "lowbias32") of uint32 values, vectorised."""
    x = i.astype(np.uint32)
    x ^= x >> np.uint32(16)
    x *= np.uint32(0x7FEB352D)
    x ^= x >> np.uint32(15)
    x *= np.uint32(0x846CA68B)
    x ^= x >> np.uint32(16)
    return x


def body_colors(indices) -> np.ndarray:
    """Colours of bodies by index: sRGB in [0, 1], shape (n, 3), float32.

    The palette entry comes from a hash of the index (so neighbours differ), and the
    brightness varies by up to +-8 % (so two bodies with the same entry still differ a little).
    """
    with np.errstate(over="ignore"):
        h = _hash32(np.asarray(indices, dtype=np.int64).reshape(-1) & 0xFFFFFFFF)
    base = PALETTE[(h % np.uint32(len(PALETTE))).astype(np.intp)]
    jitter = ((h >> np.uint32(8)) & np.uint32(0xFF)).astype(np.float32) / 255.0  # in [0, 1]
    return np.clip(base * (0.92 + 0.16 * jitter)[:, None], 0.0, 1.0).astype(np.float32)
