"""A real consumer of the USD export: Blender (bpy) imports the stage headless and sees the recording.

Marked `blender` and left out of the default run. Needs `bpy` (Blender as a Python module) in the
interpreter running pytest; see docs/export.md:

    python -m venv --system-site-packages .venv-blender && .venv-blender/bin/pip install bpy==5.0.1
    PYTHONPATH=src .venv-blender/bin/python -m pytest -m blender tests/blender -q

It also renders frame RENDER_FRAME with Cycles into docs/images/usd_blender_hammock.png, and the
same frame with Tumble's renderer into docs/images/usd_tumble_hammock.png (when EGL is there).
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tumble
from tumble.io import usd
from tumble.io.record import Recorder
from tumble.io.scene import SAMPLES_DIR
from tumble.npmath import quat_to_matrix

pytestmark = pytest.mark.blender

HERE = Path(__file__).resolve().parent
DOCS_IMAGES = HERE.parents[1] / "docs" / "images"
FPS = 30.0
FRAMES = 37  # 1.2 s of the hammock
CHECKED = (0, 12, 24, 36)
RENDER_FRAME = 30
SIZE = (640, 360)


def _run_to(world, time: float) -> None:
    """Step as the Recorder samples: until the world is within half a step of `time`."""
    while world.time + 0.5 * world.dt < time:
        world.step()


@pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs bpy (pip install bpy==5.0.1)")
def test_blender_imports_the_instancer_and_the_cloth(tmp_path):
    """Blender's instances and cloth vertices equal the recording at 4 frames; the frame range and camera carry over."""
    world = tumble.load_scene(SAMPLES_DIR / "hammock.toml")
    recorder = Recorder(world, fps=FPS)
    while recorder.frame_count < FRAMES:
        world.step()
        recorder(world)
    rec = recorder.arrays()
    stage = usd.export(rec, tmp_path / "hammock.usdc")

    render = tmp_path / "blender.png"
    report_path = tmp_path / "report.json"
    subprocess.run(
        [
            sys.executable,
            str(HERE / "blender_check.py"),
            str(stage),
            str(report_path),
            ",".join(map(str, CHECKED)),
            str(render),
            str(RENDER_FRAME),
            f"{SIZE[0]}x{SIZE[1]}",
        ],
        check=True,
        timeout=600,
        capture_output=True,
    )
    report = json.loads(report_path.read_text(encoding="utf-8"))
    print(f"blender: import {report['import_seconds']:.2f} s, Cycles render {report['render_seconds']:.1f} s")

    assert (report["frame_start"], report["frame_end"]) == (0, FRAMES - 1)
    assert report["camera_fov_y"] == pytest.approx(float(rec["camera_fov"]), abs=0.01)  # the sample's lens
    moving = np.flatnonzero(rec["mass"] > 0)  # the three balls, instance k is moving[k]
    for f in CHECKED:
        seen = report["frames"][str(f)]
        m = np.array([seen["instances"][str(k)] for k in range(len(moving))])  # Blender: column vectors
        assert len(seen["instances"]) == len(moving)
        np.testing.assert_allclose(m[:, :3, 3], rec["position"][f, moving], atol=1e-5)
        rot = quat_to_matrix(rec["orientation"][f, moving]) * rec["radius"][moving, None, None]
        # orientations travel as half-precision quaternions: matrix entries good to ~1e-3 of the scale
        np.testing.assert_allclose(m[:, :3, :3], rot, atol=2e-3 * 0.1)
        np.testing.assert_allclose(np.array(seen["cloth"]), rec["cloth_position"][f], atol=1e-5)
    # the balls moved and the cloth sagged, so the frames checked differ
    assert np.abs(rec["position"][CHECKED[-1], moving] - rec["position"][0, moving]).max() > 0.3
    assert np.abs(rec["cloth_position"][CHECKED[-1]] - rec["cloth_position"][0]).max() > 0.1

    # the pictures for docs/export.md: Blender's render, and Tumble's of the same frame
    DOCS_IMAGES.mkdir(parents=True, exist_ok=True)
    os.replace(render, DOCS_IMAGES / "usd_blender_hammock.png")
    try:
        from tumble.render import Camera, Renderer, create_context

        ctx = create_context()
    except Exception:  # noqa: BLE001 - no EGL here: keep the committed picture
        return
    from PIL import Image

    world = tumble.load_scene(SAMPLES_DIR / "hammock.toml")
    camera = Camera.for_world(world, aspect=SIZE[0] / SIZE[1])
    _run_to(world, RENDER_FRAME / FPS)
    np.testing.assert_allclose(world.body_position[moving], rec["position"][RENDER_FRAME, moving])
    renderer = Renderer(ctx, *SIZE, samples=4)
    try:
        image = renderer.render(world, camera)
    finally:
        renderer.release()
        ctx.release()
    tmp = DOCS_IMAGES / ".usd_tumble_hammock.tmp.png"
    Image.fromarray(image).save(tmp)
    os.replace(tmp, DOCS_IMAGES / "usd_tumble_hammock.png")
