"""The band's split draw (fpiwarp/backends/gl/band.py): its spans cover
every pixel the first stage's regions leave in float32, and the split
draw (region pass, then the full program over the spans) equals the
single draw bit for bit, in warp_image and in the preview, within a
caller's scissor box."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fpiwarp
from fpiwarp.backends.gl import band
from fpiwarp.block import ROW_REGIONS, describe


def _local(h, w, k=0):
    """A local deformation over the middle of an h x w frame (its quad
    edges 1 and 3 held to similarities), corners moved by k-dependent amounts."""
    sw, sh = w - 1.0, h - 1.0
    src = np.array([[0.4 * sw, 0.3 * sh], [0.6 * sw, 0.3 * sh], [0.6 * sw, 0.7 * sh], [0.4 * sw, 0.7 * sh]])
    moves = np.array([[0.02, -0.05], [0.03, 0.02], [-0.02, 0.06], [0.01, -0.03]]) * (1 + 0.3 * k)
    return fpiwarp.LocalDeformation(src, src + moves * [sw, sh], edges=(1, 3) if k % 2 == 0 else (0, 2))


def _left_by_regions(block, view, viewport):
    """Window pixels (x, y) of viewport whose float32 region depths (as
    glsl/include/map.glsl computes them) are all <= 0: the band."""
    x0, y0, w, h = viewport
    j, i = np.mgrid[y0:y0 + h, x0:x0 + w]
    f = np.float32
    zx = f(view[0]) + f(view[2]) * (i + f(0.5) - f(0.5)).astype(f)
    zy = f(view[1]) + f(view[3]) * (j + f(0.5) - f(0.5)).astype(f)
    best = np.zeros(zx.shape, f)
    for r in range(describe(block).stages[0].n_regions):
        ox, oy, nx, ny = block[1 + ROW_REGIONS + 2 * r].astype(f)
        best = np.maximum(best, (zx - ox) * nx - (zy - oy) * -ny)
    return i[best <= 0], j[best <= 0]


@settings(max_examples=25, deadline=None)
@given(k=st.integers(0, 3), zoom=st.floats(0.3, 3.0), flip=st.booleans(),
       shift=st.tuples(st.floats(-50, 50), st.floats(-50, 50)), corner=st.tuples(st.integers(0, 9), st.integers(0, 9)),
       strip=st.sampled_from([1, 7, 32]))
def test_spans_cover_the_pixels_no_region_takes(k, zoom, flip, shift, corner, strip):
    h, w = 90, 140
    block = _local(h, w, k).inverse.params()
    kind = describe(block)
    assert band.applies(kind)
    viewport = (corner[0], corner[1], 120, 70)
    vw = -zoom if flip else zoom
    view = (shift[0], shift[1] + (70 * zoom if flip else 0.0), zoom, vw)
    spans = band.band_spans(block, kind, view, viewport, strip)
    covered = np.zeros((200, 200), bool)
    for x, y, sw, sh in spans:
        assert sh <= strip and viewport[0] <= x and x + sw <= viewport[0] + viewport[2]
        covered[y:y + sh, x:x + sw] = True
    xs, ys = _left_by_regions(block, view, viewport)
    assert covered[ys, xs].all()
    if strip == 1:  # and not much more: a row's band is one interval, widened by a pixel each side
        assert covered.sum() <= len(xs) + 4 * 70 + 2 * 120


def test_applies_only_to_newton_first_stages_with_regions():
    h, w = 40, 60
    quads = ([[0, 0], [59, 0], [59, 39], [0, 39]], [[2, 1], [57, -2], [61, 41], [-1, 37]])
    assert band.applies(describe(_local(h, w).inverse.params()))
    assert not band.applies(describe(fpiwarp.FPI(*quads).inverse.params()))
    assert not band.applies(describe(fpiwarp.ConstrainedFPI(*quads, edges=(0, 2)).inverse.params()))


def _split_off(monkeypatch):
    monkeypatch.setattr(band, "applies", lambda kind: False)


@pytest.mark.parametrize("shape", [(90, 140, 3), (240, 200, 1), (130, 190, 4)])
@pytest.mark.parametrize("order", [0, 1, 3])
def test_split_warp_equals_the_single_draw(gl_backend, monkeypatch, rng, shape, order, coarse_always):
    """A seeded warp (the pass forced: these small maps' rule solves per pixel) splits, bit for bit."""
    img = (rng.random(shape) * 255).astype(np.uint8)
    m = _local(shape[0], shape[1], order % 2)
    calls = []
    split_draw = band.split_draw
    monkeypatch.setattr(band, "split_draw", lambda *a: (calls.append(1), split_draw(*a)))
    split = fpiwarp.warp_image(img, m, order=order, backend=gl_backend)
    assert calls, "the split draw did not run"
    with monkeypatch.context() as mp:
        _split_off(mp)
        single = fpiwarp.warp_image(img, m, order=order, backend=gl_backend)
    np.testing.assert_array_equal(split, single)


def _preview(ctx, renderer, size, scissor=None):
    tex = ctx.texture(size, 4, dtype="f1")
    fbo = ctx.framebuffer(color_attachments=[tex])
    try:
        fbo.use()
        ctx.clear(0.2, 0.3, 0.4, 1.0)
        if scissor is not None:
            ctx.scissor = scissor
        renderer.draw((3, 5, size[0] - 10, size[1] - 9), y_down=True)
        box = tuple(ctx.scissor)
        ctx.scissor = None
        return np.frombuffer(fbo.read(components=4), np.uint8).reshape(size[1], size[0], 4).copy(), box
    finally:
        fbo.release()
        tex.release()


@pytest.mark.parametrize("scissor", [None, (20, 10, 90, 61)])
def test_split_preview_equals_the_single_draw(gl_backend, monkeypatch, rng, scissor):
    from fpiwarp.backends import get_backend
    from fpiwarp.viewer import Renderer

    warper = get_backend(gl_backend).warper
    ctx = warper.ctx
    img = (rng.random((80, 120, 3)) * 255).astype(np.uint8)
    renderer = Renderer(ctx, order=1, warper=warper, method="pixel")
    renderer.set_image(img)
    renderer.set_transform(_local(80, 120))
    renderer.view = (-10.0, -6.0, 125.0, 84.0)  # zoomed out a little: the band's view is not the identity
    split, box = _preview(ctx, renderer, (150, 100), scissor)
    _split_off(monkeypatch)
    single, box_single = _preview(ctx, renderer, (150, 100), scissor)
    np.testing.assert_array_equal(split, single)
    assert box == box_single  # the caller's scissor box is set again
    if scissor is not None:
        assert box == scissor
