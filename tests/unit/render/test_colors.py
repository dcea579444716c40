"""Body colours (tumble.render.colors): a stable hash of the body index into the palette, dimmed or
brightened by up to 8 %."""

from __future__ import annotations

import numpy as np
import pytest

from tumble.render import CLOTH_COLOR, PALETTE, body_colors


def _lowbias32(x: int) -> int:
    """The "lowbias32" integer hash, on Python integers (the reference for the vectorised one)."""
    x &= 0xFFFFFFFF
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    x ^= x >> 16
    return x


def test_body_colors_are_stable_and_varied():
    """Colours depend only on the index, stay in [0, 1], and neighbours differ."""
    a = body_colors(np.arange(200))
    assert a.shape == (200, 3) and a.dtype == np.float32
    assert np.array_equal(a, body_colors(np.arange(200)))
    assert np.array_equal(a[57], body_colors([57])[0])
    assert a.min() >= 0.0 and a.max() <= 1.0
    same_as_next = np.all(np.abs(a[1:] - a[:-1]) < 1e-6, axis=1)
    assert same_as_next.mean() < 0.15
    assert len(np.unique(np.round(a, 3), axis=0)) > 50


@pytest.mark.parametrize("index", [0, 1, 2, 57, 1000, 2**31 - 1])
def test_colour_is_the_hashed_palette_entry_scaled_by_the_hashed_brightness(index):
    """body_colors(i) = PALETTE[h % 12] x (0.92 + 0.16 ((h >> 8) & 255) / 255), h = lowbias32(i), clipped to 1."""
    h = _lowbias32(index)
    expected = np.clip(PALETTE[h % len(PALETTE)].astype(np.float64) * (0.92 + 0.16 * ((h >> 8) & 0xFF) / 255.0), 0, 1)
    np.testing.assert_allclose(body_colors([index])[0], expected, rtol=1e-6)


def test_every_colour_is_a_palette_entry_within_8_percent():
    """Each colour is some palette entry times one factor in [0.92, 1.08] (its hue is the entry's)."""
    colours = body_colors(np.arange(500)).astype(np.float64)
    ratio = colours[:, None, :] / PALETTE[None, :, :]  # (n, entries, rgb)
    unclipped = colours < 1.0 - 1e-6
    for c, r, free in zip(colours, ratio, unclipped):
        fits = [
            k for k in range(len(PALETTE)) if np.ptp(r[k][free]) < 1e-5 and 0.92 - 1e-6 <= r[k][free][0] <= 1.08 + 1e-6
        ]
        assert fits, f"{c} is no palette entry scaled by 0.92 to 1.08"
    # and every entry is used by some body among 500
    entries = {int(np.argmin(np.abs(ratio[i] - ratio[i].mean(axis=1, keepdims=True)).sum(axis=1))) for i in range(500)}
    assert entries == set(range(len(PALETTE)))


def test_indices_of_any_shape_give_one_row_each():
    """A scalar, a list and a 2-D array of indices give (n, 3) float32 rows in order."""
    assert body_colors(7).shape == (1, 3)
    grid = body_colors(np.arange(6).reshape(2, 3))
    assert grid.shape == (6, 3) and grid.dtype == np.float32
    np.testing.assert_array_equal(grid, body_colors([0, 1, 2, 3, 4, 5]))
    assert body_colors([]).shape == (0, 3)


def test_palette_and_cloth_colour_are_srgb_in_range():
    """The palette's twelve entries and the cloth colour are distinct sRGB triples in (0, 1)."""
    assert PALETTE.shape == (12, 3) and PALETTE.dtype == np.float32
    assert len(np.unique(PALETTE, axis=0)) == len(PALETTE)
    assert np.all((PALETTE > 0.0) & (PALETTE < 1.0))
    assert CLOTH_COLOR.shape == (3,) and np.all((CLOTH_COLOR > 0.0) & (CLOTH_COLOR < 1.0))
