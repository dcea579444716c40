"""The renderer's GLSL sources (tumble.render.shaders): every pass compiles and links, and the shared
`COMMON` helpers (sRGB conversions, tone curve, dither, sky colour) compute what they say, read back
from a float framebuffer."""

from __future__ import annotations

import numpy as np
import pytest

from tumble.render import shaders

#: (vertex, fragment) of every program the renderer links
PASSES = [
    ("SKY_VERTEX", "SKY_FRAGMENT"),
    ("SKY_VERTEX", "PLANE_FRAGMENT"),
    ("SPHERE_VERTEX", "SPHERE_FRAGMENT"),
    ("BOX_VERTEX", "BOX_FRAGMENT"),
    ("CLOTH_VERTEX", "CLOTH_FRAGMENT"),
    ("SOLID_VERTEX", "SOLID_FRAGMENT"),
    ("CAPSULE_VERTEX", "CAPSULE_FRAGMENT"),
    ("SHADOW_SPHERE_VERTEX", "SHADOW_SPHERE_FRAGMENT"),
    ("SHADOW_BOX_VERTEX", "EMPTY_FRAGMENT"),
    ("SHADOW_MESH_VERTEX", "EMPTY_FRAGMENT"),
    ("SHADOW_SOLID_VERTEX", "EMPTY_FRAGMENT"),
    ("CAPSULE_VERTEX", "SHADOW_CAPSULE_FRAGMENT"),
]

#: pieces spliced into the stages, not stages themselves
PIECES = {"COMMON", "ROTATE", "CAPSULE_RAY", "CAPSULE_FRAGMENT_HEAD", "CAPSULE_HIT"}


def test_every_stage_is_glsl_330_and_used_by_a_pass():
    """Each stage starts with `#version 330`; every stage is in a pass, every piece is spliced into a stage."""
    names = [n for n in dir(shaders) if n.isupper() and isinstance(getattr(shaders, n), str)]
    stages = set(names) - PIECES
    assert stages == {name for pair in PASSES for name in pair}
    for name in stages:
        assert getattr(shaders, name).lstrip().startswith("#version 330\n"), name
    for piece in PIECES:
        assert any(getattr(shaders, piece) in getattr(shaders, s) for s in stages), f"{piece} is in no stage"


@pytest.mark.parametrize("vertex, fragment", PASSES, ids=[f"{v}+{f}" for v, f in PASSES])
def test_every_pass_compiles_and_links(gl_context, vertex, fragment):
    """The driver (Mesa llvmpipe here) compiles and links each pass the renderer uses; every colour pass is
    lit by the sun and dithered (docs/rendering.md: every colour gets the dither), no shadow pass is."""
    with gl_context:
        program = gl_context.program(vertex_shader=getattr(shaders, vertex), fragment_shader=getattr(shaders, fragment))
        active = set(program)  # uniforms and attributes the linked program uses
        program.release()
    if vertex.startswith("SHADOW_") or fragment.startswith("SHADOW_"):
        assert "u_dither" not in active
    else:
        assert {"u_dither", "u_light_dir", "u_eye"} <= active, active


def _evaluate(gl_context, body: str, width: int, height: int = 1, **uniforms) -> np.ndarray:
    """Run a fragment shader `COMMON + body` over a width x height float framebuffer; its RGB, row 0 first.

    The body sees `x` in (0, 1) across the image (pixel centres) and writes `f_color`."""
    fragment = (
        "#version 330\nin vec2 v_ndc;\nout vec4 f_color;\n"
        + shaders.COMMON
        + "void main() {\n float x = (v_ndc.x + 1.0) * 0.5;\n"
        + body
        + "\n}\n"
    )
    with gl_context:
        program = gl_context.program(vertex_shader=shaders.SKY_VERTEX, fragment_shader=fragment)
        for name, value in uniforms.items():
            if name in program:  # (unused uniforms are optimised away)
                program[name].value = value
        texture = gl_context.texture((width, height), 4, dtype="f4")
        fbo = gl_context.framebuffer(color_attachments=[texture])
        fbo.use()
        vao = gl_context.vertex_array(program, [])
        vao.render(vertices=3)
        rgba = np.frombuffer(fbo.read(components=4, dtype="f4"), dtype=np.float32).reshape(height, width, 4)
        for obj in (vao, fbo, texture, program):
            obj.release()
    return rgba[..., :3].astype(np.float64)


def test_srgb_conversions_and_tone_curve_follow_their_formulas(gl_context):
    """to_linear = c^2.2, tonemap = 1 - exp(-1.5 c), to_srgb = clamp(c)^(1/2.2): checked against NumPy."""
    n = 64
    x = (np.arange(n) + 0.5) / n
    out = _evaluate(
        gl_context,
        "f_color = vec4(to_linear(vec3(x)).x, tonemap(vec3(2.0 * x)).x, to_srgb(vec3(1.5 * x - 0.25)).x, 1.0);",
        n,
    )
    np.testing.assert_allclose(out[0, :, 0], x**2.2, atol=2e-6)
    np.testing.assert_allclose(out[0, :, 1], 1.0 - np.exp(-3.0 * x), atol=2e-6)
    np.testing.assert_allclose(out[0, :, 2], np.clip(1.5 * x - 0.25, 0.0, 1.0) ** (1 / 2.2), atol=2e-6)


def test_dither_is_within_one_step_without_bias_and_off_when_asked(gl_context):
    """dither(c) adds triangular noise within +-1/255, mean near zero, the same every frame; none at u_dither 0."""
    on = _evaluate(gl_context, "f_color = vec4(dither(vec3(0.5)), 1.0);", 64, 64, u_dither=1.0)
    noise = (on - 0.5) * 255.0  # in 8-bit steps
    assert np.abs(noise).max() <= 1.0 + 1e-4
    assert abs(noise.mean()) < 0.05  # triangular noise of 4096 pixels: std of the mean ~ 0.007
    assert 0.3 < noise.std() < 0.5  # triangular on [-1, 1]: sqrt(1/6) = 0.41
    assert len(np.unique(np.round(noise[..., 0], 4))) > 100  # varies from pixel to pixel
    np.testing.assert_array_equal(
        on, _evaluate(gl_context, "f_color = vec4(dither(vec3(0.5)), 1.0);", 64, 64, u_dither=1.0)
    )
    off = _evaluate(gl_context, "f_color = vec4(dither(vec3(0.5)), 1.0);", 64, 64, u_dither=0.0)
    np.testing.assert_array_equal(off, 0.5)


def test_sky_runs_from_the_zenith_colour_to_the_horizon_and_a_haze_below(gl_context):
    """sky_color: straight up is SKY_ZENITH, level is SKY_HORIZON, from 14.5 degrees down SKY_BELOW (sun away)."""
    n = 181  # directions from 90 degrees below to 90 above, in the x-z plane
    # pixel k looks (k - 90) degrees up: whole degrees, so that 0 and 90 are exact
    body = "float a = radians(floor(gl_FragCoord.x) - 90.0); f_color = vec4(sky_color(vec3(cos(a), 0.0, sin(a))), 1.0);"
    sky = _evaluate(gl_context, body, n, u_up=(0.0, 0.0, 1.0), u_light_dir=(0.0, -1.0, 0.0))[0]
    zenith, horizon, below = (0.30, 0.50, 0.80), (0.84, 0.89, 0.95), (0.60, 0.64, 0.69)
    np.testing.assert_allclose(sky[180], zenith, atol=1e-5)  # (cos 90 degrees is not quite 0 in float)
    np.testing.assert_allclose(sky[90], horizon, atol=1e-5)
    # below the horizon: SKY_BELOW once sin(a) <= -1/4, i.e. from 14.48 degrees down
    np.testing.assert_allclose(sky[: 90 - 15], np.tile(below, (90 - 15, 1)), atol=1e-5)
    # from the horizon up, red and blue both fall steadily towards the zenith's deeper blue
    assert np.all(np.diff(sky[90:, 0]) < 0) and np.all(np.diff(sky[90:, 2]) < 0)
