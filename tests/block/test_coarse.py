"""A warp's coarse pass (fpiwarp.block.coarse): the reference's seeded
positions solve the spline to the device tolerance and lie nearer the
float64 inverse than the per-point solve; the OpenCL warp samples where the
reference says."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.requirements import use_backend

import fpiwarp
from fpiwarp.block import evaluate
from fpiwarp.block.coarse import coarse_pass, coarse_shape, evaluate_pixels, pixel_seeds
from fpiwarp.block.describe import describe, stage_rows
from fpiwarp.block.layout import COARSE_STEP
from fpiwarp.block.reference import evaluate_stage, region_winner


def _local(height, width):
    w, h = width - 1.0, height - 1.0
    src = np.array([[0.3 * w, 0.25 * h], [0.7 * w, 0.25 * h], [0.7 * w, 0.75 * h], [0.3 * w, 0.75 * h]])
    dst = src + np.array([[0.02 * w, -0.05 * h], [0.03 * w, 0.02 * h], [-0.02 * w, 0.06 * h], [0.01 * w, -0.03 * h]])
    return fpiwarp.LocalDeformation(src, dst, edges=(1, 3))


def _grid(height, width):
    y, x = np.mgrid[0:height, 0:width]
    return np.stack([x, y], -1).astype(np.float64)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 200), st.integers(1, 200))
def test_the_nodes_cover_every_pixel(width, height):
    ny, nx = coarse_shape(width, height)
    assert COARSE_STEP * (nx - 2) <= width - 1 <= COARSE_STEP * (nx - 1)
    assert COARSE_STEP * (ny - 2) <= height - 1 <= COARSE_STEP * (ny - 1)


def test_a_pixel_on_a_node_gets_the_node_record():
    block = _local(60, 90).inverse.params()
    rec = coarse_pass(block, 90, 60)
    j, i = np.mgrid[0 : rec.shape[0] - 1, 0 : rec.shape[1] - 1]
    seed = pixel_seeds(rec, COARSE_STEP * i, COARSE_STEP * j)
    for k in range(3):
        np.testing.assert_array_equal(seed[k], rec[j, i, k])


def test_without_a_newton_core_there_is_no_pass():
    src = [[0, 0], [40, 0], [40, 30], [0, 30]]
    block = fpiwarp.FPI(src, [[1, 2], [41, -1], [38, 33], [-2, 29]]).inverse.params()
    assert coarse_pass(block, 40, 30) is None
    np.testing.assert_array_equal(evaluate_pixels(block, 40, 30), evaluate(block, _grid(30, 40), np.float32))


def test_seeded_positions_solve_the_spline_and_lie_nearer_the_inverse():
    """float32 reference at 1080p-like scale (rows subsampled): the seeded
    positions are the inverse to within the per-point solve's own error,
    and nearer it than that solve at the 99th percentile (the step by the
    interpolated inverse Jacobian, against Newton stopped at the tolerance)."""
    height, width = 270, 480
    local = _local(height, width)
    inverse = local.inverse
    block = inverse.params()
    rows = np.arange(0, height, 5)
    seeded = evaluate_pixels(block, width, height, np.float32, rows=rows)
    pts = _grid(height, width)[rows]
    plain = evaluate(block, pts, np.float32)
    truth = inverse(pts.reshape(-1, 2)).reshape(pts.shape)
    e_seeded = np.abs(seeded - truth).max(-1)
    e_plain = np.abs(plain - truth).max(-1)
    assert np.isfinite(seeded).all()
    assert e_seeded.max() <= e_plain.max() + 1e-3
    assert np.quantile(e_seeded, 0.99) < 0.5 * np.quantile(e_plain, 0.99)


def test_a_failed_node_leaves_its_pixels_to_the_per_point_solve():
    """NaN records (a node whose Newton failed) give the per-point solve's answer."""
    # (the seed check refuses a NaN seed, so each pixel falls back)
    height, width = 40, 64
    block = _local(height, width).inverse.params()
    rec = coarse_pass(block, width, height)
    rec[:] = np.nan
    y, x = np.mgrid[0:height, 0:width]
    b32 = np.asarray(block, np.float32)
    z = (x + 1j * y).astype(np.complex64)
    got = evaluate_stage(stage_rows(b32, 0), describe(block).stages[0], z, np.float32, pixel_seeds(rec, x, y))
    want = evaluate(block, _grid(height, width), np.float32)
    # the same solve; numpy's float32 SIMD and scalar loops differ in the last ulps
    np.testing.assert_allclose(np.stack([got.real, got.imag], -1), want, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("backend", ["opencl", "gl"])
@pytest.mark.parametrize("height, width", [(64, 129), (120, 257)])
def test_the_warp_samples_where_the_reference_says(backend, height, width, coarse_always):
    """A float32 image equal to its x (and y) coordinate, sampled at order 1,
    reads back the source position of each output pixel inside the picture:
    the OpenCL and GL warps' coarse-seeded positions are the reference's (at
    120 x 257 the per-point solve's lie up to 8e-3 px from them)."""
    use_backend(backend)
    local = _local(height, width)
    want = evaluate_pixels(local.inverse.params(), width, height, np.float32)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    img = np.stack([x, y, np.zeros_like(x)], -1)
    got = fpiwarp.warp_image(img, local, order=1, mode="constant", cval=-1.0, backend=backend)[..., :2]
    inside = (want[..., 0] >= 0) & (want[..., 0] <= width - 1) & (want[..., 1] >= 0) & (want[..., 1] <= height - 1)
    assert inside.mean() > 0.8
    np.testing.assert_allclose(got[inside], want[inside], rtol=0, atol=1e-3)


def _gl_records(warper):
    """The node records (ny, nx, 3) complex of the GL coarse pass drawn last."""
    xa, b = (np.frombuffer(t.read(), np.float32).reshape(t.height, t.width, 4)
             for t in warper.targets.get("coarse").color_attachments)
    return np.stack([xa[..., 0] + 1j * xa[..., 1], xa[..., 2] + 1j * xa[..., 3], b[..., 0] + 1j * b[..., 1]], -1)


def _read_nodes(block, width, height):
    """(ny, nx) bool: the nodes that a pixel the first stage's regions leave
    reads (GL skips the solve of the others, whose records are then NaN)."""
    kind = describe(block)
    z = (_grid(height, width) @ [1, 1j]).astype(np.complex64)
    won = region_winner(stage_rows(block, 0), kind.stages[0], z, np.float32)[0]
    ny, nx = coarse_shape(width, height)
    read = np.zeros((ny, nx), bool)
    j, i = np.nonzero(~won)
    ci, cj = np.minimum(i // COARSE_STEP, nx - 2), np.minimum(j // COARSE_STEP, ny - 2)
    for dj in (0, 1):
        for di in (0, 1):
            read[cj + dj, ci + di] = True
    return read


def _assert_records_close(got, want, read):
    """The GL records ``got`` are the reference's ``want`` at the nodes read."""
    assert got.shape == want.shape
    finite = np.isfinite(want[..., 0])
    assert np.array_equal(np.isfinite(got[..., 0])[read], finite[read]) and finite[read].mean() > 0.99
    assert 0.1 < read.mean() < 0.9  # the regions leave a band: some nodes are skipped, some solved
    np.testing.assert_allclose(got[read & finite], want[read & finite], rtol=1e-4, atol=2e-4)


@pytest.mark.parametrize("specialize", [True, False])
def test_gl_coarse_pass_writes_the_reference_records(make_gl_warper, specialize, coarse_always):
    """The GL warp's node textures hold coarse.coarse_pass's records (the
    specialized and the run-time stage walk alike) at every node that a
    pixel the regions leave reads."""
    height, width = 70, 133
    local = _local(height, width)
    warper = make_gl_warper(specialize=specialize)
    warper.warp_image(np.zeros((height, width, 1), np.float32), local, (height, width))
    block = local.inverse.params()
    _assert_records_close(_gl_records(warper), coarse_pass(block, width, height), _read_nodes(block, width, height))


@pytest.mark.parametrize("height, width", [(70, 133), (129, 200)])
def test_opencl_coarse_pass_writes_the_reference_records_and_skips_unread_nodes(height, width, coarse_always):
    """The OpenCL warp's coarse pass holds coarse.coarse_pass's records at
    every node that a pixel the regions leave reads, and skips the solve of
    nodes a region holds deeper than their reach (NaN records, as GL's)."""
    use_backend("opencl")
    from fpiwarp.backends import get_backend

    local = _local(height, width)
    fpiwarp.warp_image(np.zeros((height, width, 1), np.float32), local, backend="opencl")
    be = get_backend("opencl")
    job = next(j for j in reversed(list(be._jobs._items.values())) if j._coarse is not None)
    ny, nx = coarse_shape(width, height)
    raw = np.empty(ny * nx * 6, np.float32)
    be._cl.enqueue_copy(be.queue, raw, job._records)
    r = raw.reshape(ny, nx, 3, 2)
    got = r[..., 0] + 1j * r[..., 1]
    block = local.inverse.params()
    read = _read_nodes(block, width, height)
    _assert_records_close(got, coarse_pass(block, width, height), read)
    assert np.isnan(got[~read][..., 0]).mean() > 0.5  # most unread nodes were not solved


def test_gl_preview_nodes_start_at_its_viewport_corner(gl_backend):
    """The preview's pass (Renderer, method "pixel") at a viewport away from
    the framebuffer's corner, its view one output pixel per window pixel
    from there: the nodes are the warp's."""
    from fpiwarp.backends.gl import shared_context
    from fpiwarp.viewer import Renderer

    height, width = 48, 72
    local = _local(height, width)
    ctx = shared_context()
    r = Renderer(ctx, method="pixel")
    fbo = ctx.simple_framebuffer((width + 20, height + 9))
    try:
        r.set_image(np.zeros((height, width, 3), np.uint8))
        r.set_transform(local)
        r.view = (-0.5, -0.5, width - 0.5, height - 0.5)
        fbo.use()
        r.draw((13, 5, width, height), y_down=True)
        block = local.inverse.params()
        read = _read_nodes(block, width, height)
        _assert_records_close(_gl_records(r.warper), coarse_pass(block, width, height), read)
    finally:
        ctx.detect_framebuffer(0).use()
        fbo.release()
        r.release()
