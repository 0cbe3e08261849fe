"""The preview's antialiasing over the pyramid: the A key, the pyramid kept
across frames, a view far zoomed out (levels >= 1)."""

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, RLinear

H, W = 120, 160
SRC = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]


@pytest.fixture
def ctx(gl_backend):
    from fpiwarp.backends.gl import shared_context

    c = shared_context()
    yield c
    assert c.error == "GL_NO_ERROR"


def _picture():
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    plate = 0.5 + 0.5 * np.cos(np.pi * ((x - W / 2) ** 2 + (y - H / 2) ** 2) / W)
    return np.repeat(np.round(255 * plate).astype(np.uint8)[..., None], 3, axis=-1)


def _draw(ctx, renderer, size):
    """The renderer's frame of ``size`` (w, h), top row first."""
    tex = ctx.texture(size, 4, dtype="f1")
    fbo = ctx.framebuffer(color_attachments=[tex])
    try:
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        renderer.draw((0, 0) + size, y_down=True)
        data = fbo.read(viewport=(0, 0) + size, components=4, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(size[1], size[0], 4)[..., :3].copy()
    finally:
        ctx.detect_framebuffer(0).use()
        fbo.release()
        tex.release()


def test_key_a_toggles_antialiasing_and_the_pyramid_is_built_once(ctx):
    from fpiwarp.backends import get_backend
    from fpiwarp.viewer import Editor, Renderer

    img = _picture()
    r = Renderer(ctx, warper=get_backend("gl").warper, antialias=False)
    try:
        ed = Editor(r, img, FPI(SRC, SRC))
        r.handles = r.outline = False
        r.view = (-0.5, -0.5, W - 0.5, H - 0.5)  # the source's extent, no margin
        size = (W // 8, H // 8)  # the fitted view shrinks 1/8: pyramid level 2
        plain = _draw(ctx, r, size)
        assert r.pyramid_builds == 0  # no antialiased frame yet, no pyramid
        ed.key("a")
        assert r.antialias and "antialiasing on" in ed.title()
        smooth = _draw(ctx, r, size)
        # the frame of a 1/8 view of the identity: warp_image(antialias=True) of a 1/8 shrink
        shrink = RLinear(0.125, 0, -0.4375 - 0.4375j)
        want = fpiwarp.warp_image(img, shrink, size[::-1], antialias=True, backend="numpy")
        assert np.abs(smooth.astype(int) - want).max() <= 1
        assert np.abs(plain.astype(int) - want).max() > 60  # point samples of the fine rings
        for dst in ([[2, 1], [150, 4], [158, 117], [1, 119]], SRC):  # new maps: the same pyramid
            ed.dst = np.array(dst, np.float64)
            ed.rebuild()
            _draw(ctx, r, size)
        assert r.pyramid_builds == 1
        ed.key("a")
        assert not r.antialias and "antialiasing off" in ed.title()
        np.testing.assert_array_equal(_draw(ctx, r, size), plain)
        r.antialias = True
        r.set_image(255 - img)  # a new picture: a new pyramid
        r.view = (-0.5, -0.5, W - 0.5, H - 0.5)
        want = fpiwarp.warp_image(255 - img, shrink, size[::-1], antialias=True, backend="numpy")
        assert np.abs(_draw(ctx, r, size).astype(int) - want).max() <= 1
        assert r.pyramid_builds == 2
    finally:
        r.release()


def test_zoomed_in_antialiased_frame_is_the_plain_one(ctx):
    from fpiwarp.viewer import render_image

    img = _picture()
    f = FPI(SRC, [[2, 1], [150, 4], [158, 117], [1, 119]])
    size = (2 * W, 2 * H)
    plain = render_image(img, f, size=size, renderer_options={"antialias": False})
    smooth = render_image(img, f, size=size, renderer_options={"antialias": True})
    np.testing.assert_array_equal(smooth, plain)
