"""The Warp backend against the numpy reference, on every Warp device here.

map_points: within 1e-5 relative of the float64 reference away from the
pole. warp_image: within one uint8 level (257 for uint16, 1/255 for float32
images in [0, 1]) of the numpy backend on at least 99.8% of pixels.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.kernel_cases import (
    DTYPES,
    MAPS,
    MODES,
    ORDERS,
    RTOL,
    Staged,
    assert_close_relative,
    assert_images_agree,
    compare_warp,
    frame_points,
    make_image,
    newton_atol,
    reference,
    sample_fpi,
    tps_inverse_stage,
    tps_map,
)
from support.strategies import quads

import fpiwarp
from fpiwarp import FPI
from fpiwarp.backends.numpy import backend as numpy_backend
from fpiwarp.block import evaluate

_backends = {}


def _devices():
    """Warp devices to test: the CPU, and the first CUDA device where present."""
    from fpiwarp.backends.nvwarp.backend import probe

    if probe() is not None:
        return ["cpu"]
    import warp

    return ["cpu"] + (["cuda:0"] if warp.get_cuda_device_count() > 0 else [])


@pytest.fixture(params=_devices())
def warp(request, warp_backend):
    """A Warp backend object on each device (skips, or fails when required)."""
    from fpiwarp.backends.nvwarp.backend import Backend

    if request.param not in _backends:
        _backends[request.param] = Backend(device=request.param)
    return _backends[request.param]




@pytest.mark.parametrize("name", sorted(MAPS))
def test_map_points_matches_float64_reference(warp, name, rng):
    transform = MAPS[name]()
    pts = frame_points(rng)
    want = evaluate(transform.params(), pts, np.float64)
    assert np.all(np.isfinite(want))
    assert_close_relative(warp.map_points(transform, pts), want, atol=newton_atol(transform))
    if not isinstance(transform, Staged):  # and the map's own float64 formulas
        assert_close_relative(warp.map_points(transform, pts), transform(pts))


def _constrained_maps():
    """The §4 maps, where this version of fpiwarp has them."""
    cfpi, local = getattr(fpiwarp, "ConstrainedFPI", None), getattr(fpiwarp, "LocalDeformation", None)
    if cfpi is None or local is None:
        pytest.skip("ConstrainedFPI / LocalDeformation not in this version")
    src = [[0, 0], [63, 0], [63, 47], [0, 47]]
    return [
        cfpi(src, [[4, 3], [60, -2], [66, 50], [-3, 44]], edges=(0, 2)),
        local(src, [[4, 3], [60, -2], [66, 50], [-3, 44]], edges=(3, 1)),
        local(src, [[0, 0], [63, 0], [68, 52], [0, 47]], edges=(3, 0)),
    ]


def test_map_points_of_constrained_maps(warp, rng):
    """Their spline lives in parallelogram coordinates (unit size), so float32
    rounding is a fraction of the quad's size rather than of |w|: the error
    is measured relative to max(|w|, quad size). Inverses (Newton) are only
    defined to newton_tol in those coordinates, i.e. to about newton_tol
    times the quad size in pixels."""
    pts = frame_points(rng, 2000)
    size = 64.0
    for transform in _constrained_maps():
        for t in (transform, transform.inverse):
            want = evaluate(t.params(), pts, np.float64)
            got = warp.map_points(t, pts)
            err = np.linalg.norm(got - want, axis=-1) - 2 * size * newton_atol(t)
            assert np.max(err / np.maximum(np.linalg.norm(want, axis=-1), size)) <= RTOL, repr(t)


def test_newton_inverse_undoes_the_tps(warp, rng):
    pts = frame_points(rng, 1000, margin=0)
    forward = warp.map_points(tps_map(), pts)
    assert_close_relative(warp.map_points(tps_map().inverse, forward), pts, rtol=3e-5)


def test_newton_not_converged_gives_nan(warp, rng):
    transform = Staged([tps_inverse_stage(iters=1, tol=0.0)])
    out = warp.map_points(transform, frame_points(rng, 100))
    assert np.all(np.isnan(out))


@settings(max_examples=30, deadline=None)
@given(
    src=quads(min_scale=1, max_scale=1e3, convex=True),
    dst=quads(min_scale=1, max_scale=1e3, convex=True),
    seed=st.integers(0, 2**31),
)
def test_fpi_points_inside_the_quad_match_reference(src, dst, seed):
    """Random FPIs: points inside the (convex) source quad, far from the pole."""
    from support.strategies import orient_like

    from fpiwarp.backends.nvwarp.backend import Backend, probe

    if probe() is not None:
        pytest.skip(probe())
    if "cpu" not in _backends:
        _backends["cpu"] = Backend(device="cpu")
    transform = FPI(src, orient_like(dst, src))
    weights = np.random.default_rng(seed).dirichlet(np.ones(4), size=200)
    pts = weights @ src
    want = evaluate(transform.params(), pts, np.float64)
    got = _backends["cpu"].map_points(transform, pts)
    err = np.linalg.norm(got - want, axis=-1)
    scale = np.maximum(np.linalg.norm(want, axis=-1), np.abs(dst).max())
    assert np.max(err / scale) <= RTOL


def test_map_points_keeps_shape_and_accepts_odd_layouts(warp, rng):
    transform = sample_fpi()
    pts = frame_points(rng, 30).reshape(3, 5, 2, 2)[:, :, 0]  # not contiguous
    got = warp.map_points(transform, pts)
    assert got.shape == (3, 5, 2)
    assert_close_relative(got, transform(pts))
    assert warp.map_points(transform, np.zeros((0, 2))).shape == (0, 2)
    assert fpiwarp.map_points(transform, [[1, 2]], backend="warp").shape == (1, 2)


# --- warp_image ---------------------------------------------------------------


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("order", ORDERS)
def test_warp_image_matches_numpy_backend(warp, order, mode, dtype):
    transform = sample_fpi()
    for channels in (1, 2, 3, 4):
        img = make_image((48, 64, channels), dtype, seed=channels)
        cval = np.linspace(0.1, 0.9, channels) * (1 if dtype is np.float32 else np.iinfo(dtype).max)
        compare_warp(warp, img, transform, (52, 70), order, mode, cval)


@pytest.mark.parametrize("shape", [(1, 1, 2), (1, 9, 1), (7, 1, 3)])
def test_tiny_images_in_every_mode(warp, shape):
    """One-pixel-wide images: reflect has period 0 there, wrap and edge repeat."""
    img = make_image(shape, np.uint8, seed=3)
    for order in ORDERS:
        for mode in MODES:
            compare_warp(warp, img, MAPS["compound"](), (6, 8), order, mode, 17)


# --- compile once, device choice ---------------------------------------------


def test_new_values_do_not_recompile(warp, rng):
    """Maps of any kind share the point kernel; maps of one kind share
    the image kernels of each kind of sampling: new values make no kernel
    and load no module."""
    from fpiwarp.kernels.nvwarp import factory

    points = factory.point_kernel()
    if not hasattr(points.module, "execs"):
        pytest.skip("this Warp version does not expose module.execs")

    def quad(k):
        return FPI([[0, 0], [15, 0], [15, 15], [0, 15]], [[k, 0], [15, k / 2], [16, 15 - k], [0, 14]])

    warp.map_points(sample_fpi(), frame_points(rng, 10))
    for order in ORDERS:
        for dtype in DTYPES:
            warp.warp_image(make_image((12, 9, 2), dtype), quad(0.5), (7, 11), order=order, mode="wrap",
                            cval=np.zeros(2))
    made = dict(factory._cache)
    loaded = {key: dict(kernel.module.execs) for key, kernel in made.items()}
    for transform in (MAPS["mobius"](), tps_map(), MAPS["compound"]()):
        warp.map_points(transform, frame_points(rng, 10))
    for k in (1.0, 2.5, -1.0):
        for order in ORDERS:
            for dtype in DTYPES:
                img = make_image((12, 9, 2), dtype)
                warp.warp_image(img, quad(k), (7, 11), order=order, mode="wrap", cval=np.zeros(2))
    assert factory._cache == made
    assert {key: dict(kernel.module.execs) for key, kernel in made.items()} == loaded


def test_unknown_core_is_refused_by_the_host_and_outside_in_the_kernel(warp, rng):
    """A core no kernel knows: map_points raises before any launch; the
    kernel itself, given such a block anyway, returns NaN ("outside"),
    never a silent Newton inverse."""
    import warp as wp
    from fpiwarp.kernels.nvwarp import factory

    from fpiwarp.block import ROW_HEADER

    block = sample_fpi().params().copy()
    block[1 + ROW_HEADER, 0] = 7
    pts = frame_points(rng, n=256)

    class RawBlock:
        def params(self):
            return block

    with pytest.raises(ValueError, match="unknown core 7"):
        warp.map_points(RawBlock(), pts)
    blk = wp.array(block[None], dtype=wp.vec4, device=warp.device)
    which = wp.zeros(1, dtype=wp.int32, device=warp.device)
    src = wp.array(pts, dtype=wp.vec2d, device=warp.device)
    out = wp.zeros(len(pts), dtype=wp.vec2d, device=warp.device)
    wp.launch(factory.point_kernel(), dim=len(pts), inputs=[blk, which, src, out, 0], device=warp.device)
    assert np.isnan(out.numpy()).all()


def test_unknown_device_is_a_clear_error(warp_backend, monkeypatch):
    from fpiwarp.backends.nvwarp import backend as wb

    with pytest.raises(ValueError, match="cuda:97.*not available"):
        wb.Backend(device="cuda:97")
    monkeypatch.setenv(wb.DEVICE_ENV, "cuda:97")
    assert wb.DEVICE_ENV in wb.probe()
    monkeypatch.setenv(wb.DEVICE_ENV, "cpu")
    assert wb.probe() is None
    assert str(wb.Backend().device) == "cpu"


def test_cpu_bands_over_threads_give_the_same_result(warp_backend, monkeypatch, rng):
    """Splitting a CPU call into bands of rows (points) changes nothing."""
    from fpiwarp.backends.nvwarp import backend as wb

    single, pooled = wb.Backend(device="cpu", threads=1), wb.Backend(device="cpu", threads=3)
    monkeypatch.setattr(wb, "MIN_ITEMS_PER_THREAD", 7)
    transform = sample_fpi()
    img = make_image((23, 31, 3), np.uint16)
    for order in ORDERS:
        args = {"order": order, "mode": "reflect", "cval": np.zeros(3)}
        assert np.array_equal(
            single.warp_image(img, transform, (29, 37), **args), pooled.warp_image(img, transform, (29, 37), **args)
        )
    pts = frame_points(rng, 101)
    assert np.array_equal(single.map_points(transform, pts), pooled.map_points(transform, pts))


def test_thread_count_is_validated(warp_backend, monkeypatch):
    from fpiwarp.backends.nvwarp import backend as wb

    with pytest.raises(ValueError, match="threads must be a positive integer"):
        wb.Backend(device="cpu", threads=0)
    monkeypatch.setenv(wb.THREADS_ENV, "many")
    with pytest.raises(ValueError, match=wb.THREADS_ENV):
        wb.Backend(device="cpu")
    assert wb.THREADS_ENV in wb.probe()
    monkeypatch.setenv(wb.THREADS_ENV, "2")
    assert wb.Backend(device="cpu").threads == 2


def test_probe_names_the_missing_package(monkeypatch):
    import sys

    from fpiwarp.backends.nvwarp import backend as wb

    monkeypatch.setitem(sys.modules, "warp", None)  # import warp now raises ImportError
    assert "warp-lang" in wb.probe()


def test_copy_path_reuses_buffers(warp_backend, rng):
    """The path CUDA takes (upload into kept buffers, copy back), run on CPU
    memory so that machines without a GPU test it too."""
    import warp as wp_

    from fpiwarp.backends.nvwarp import backend as wb

    backend = wb.Backend(device="cpu", threads=1)
    backend._on_cpu = False  # force the copy path
    backend._block = wp_.zeros_like(backend._block)
    transform = sample_fpi()
    img = make_image((48, 64, 3), np.uint8)
    cv = np.zeros(3)
    want = numpy_backend.Backend().warp_image(img, transform, (40, 50), order=1, mode="edge", cval=cv)
    assert_images_agree(backend.warp_image(img, transform, (40, 50), order=1, mode="edge", cval=cv), want, np.uint8)
    kept = dict(backend._buffers)
    backend.warp_image(img, MAPS["mobius"](), (40, 50), order=1, mode="edge", cval=cv)
    assert all(backend._buffers[k] is v for k, v in kept.items())
    pts = frame_points(rng, 50)
    assert_close_relative(backend.map_points(transform, pts), transform(pts))
    backend.map_points(transform, pts[:20])  # a new shape: new buffers
    assert backend._buffers["points"].shape == (20,)


# --- the CPU paths: a thread per row, taps inside the image ---------------------


def _launch_both_layouts(warp, img, transform, shape, order, mode, cval, antialias=False):
    """One image through the factory's kernel with a thread per row and
    with a thread per pixel (the CUDA layout), on this backend's device."""
    import warp as wp
    from fpiwarp.kernels.nvwarp import factory

    from fpiwarp.block import describe
    from fpiwarp.block.sampling_rules import MODES

    block = np.ascontiguousarray(transform.inverse.params(), dtype=np.float32)
    kind = None if antialias else factory.kind_key(describe(block))
    static = (None, None, None) if antialias else (order, MODES.index(mode), img.shape[2])
    scalar = wp.dtype_from_numpy(img.dtype)
    blk = wp.array(block[None], dtype=wp.vec4, device=warp.device)
    first = wp.zeros(1, dtype=wp.int32, device=warp.device)
    src = wp.array(img, dtype=scalar, device=warp.device)
    cv = np.zeros(4, np.float32)
    cv[: img.shape[2]] = cval
    pyramid = warp.pyramid([(src, 0)], *img.shape).args if antialias else warp.no_pyramid
    outs = []
    for rows in (True, False):
        spec = factory.image_spec(kind, *static, img.dtype, rows=rows, antialias=antialias)
        out = wp.zeros((*shape, img.shape[2]), dtype=scalar, device=warp.device)
        inputs = [blk, first, src, out, img.shape[0], shape[0], 0, order, MODES.index(mode), wp.vec4(*cv.tolist()),
                  *pyramid, 0]
        wp.launch(factory.image_kernel(spec), dim=shape[0] if rows else shape, inputs=inputs, device=warp.device)
        outs.append(out.numpy())
    return outs


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("dtype", DTYPES)
def test_row_and_pixel_kernels_give_the_same_bits_and_match_the_reference(warp, order, mode, dtype):
    """The thread-per-row kernel (Warp's CPU device) and the thread-per-pixel
    one (CUDA) are one kernel body: the same bits, every order, mode and
    dtype, and within one level of the numpy reference (PIXEL_FRACTION of
    the pixels). The map moves the quad past every edge, so taps run both
    inside the image (direct indices) and across its border (border rule)."""
    transform = FPI([[0, 0], [20, 0], [20, 16], [0, 16]], [[-3, 2], [24, -2], [22, 19], [1, 14]])
    img = make_image((17, 21, 3), dtype, seed=order)
    by_row, by_pixel = _launch_both_layouts(warp, img, transform, (19, 23), order, mode, 9)
    np.testing.assert_array_equal(by_row, by_pixel)
    want, _ = reference(img, transform, (19, 23), order, mode, 9)
    assert_images_agree(by_row, want, img.dtype.type)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("dtype", DTYPES)
def test_split_row_chunks_give_the_pixel_kernels_bits(warp, order, channels, mode, dtype):
    """The row kernels' split chunks (taps and weights, then the taps
    inside read, then the mix, then the writes;
    :data:`~fpiwarp.kernels.nvwarp.factory.ROW_CHUNK` pixels each) give the
    thread-per-pixel kernel's bits: rows of two full chunks and a part,
    where pixels whose taps cross the border (sampled whole, with the
    border rule) sit between pixels read from inside, for every channel
    count, mode and dtype, with a cval per channel; and within one level
    of the numpy reference."""
    from fpiwarp.kernels.nvwarp.factory import ROW_CHUNK

    width = 2 * ROW_CHUNK + 13
    w, h = width - 1.0, 30.0
    transform = FPI([[0, 0], [w, 0], [w, h], [0, h]], [[-4, 3], [w + 5, -2], [w - 3, h + 4], [2, h - 5]])
    img = make_image((27, width - 6, channels), dtype, seed=channels)
    cval = np.array([3.0, 250.0, 0.5, 17.0][:channels])
    by_row, by_pixel = _launch_both_layouts(warp, img, transform, (31, width), order, mode, cval)
    np.testing.assert_array_equal(by_row, by_pixel)
    want, _ = reference(img, transform, (31, width), order, mode, cval)
    assert_images_agree(by_row, want, img.dtype.type)


@pytest.mark.parametrize("order", ORDERS)
def test_split_row_chunks_give_cval_at_positions_out_of_range(warp, order):
    """A Möbius map whose inverse has its pole on a pixel of the output:
    the positions there are not finite or beyond COORD_LIMIT, and the
    split row kernels give the thread-per-pixel kernel's bits (cval
    there, the samples around it)."""
    from fpiwarp.kernels.nvwarp.factory import ROW_CHUNK

    from fpiwarp.maps.mobius import Mobius

    pole = complex(ROW_CHUNK + 5, 9)
    transform = Mobius(1, 0, 1 / pole, 1)
    img = make_image((40, 3 * ROW_CHUNK, 3), np.uint8, seed=11)
    by_row, by_pixel = _launch_both_layouts(warp, img, transform, (20, 2 * ROW_CHUNK + 3), order, "constant", 7)
    np.testing.assert_array_equal(by_row, by_pixel)


@pytest.mark.parametrize("order", ORDERS)
def test_antialiased_row_and_pixel_kernels_give_the_same_bits(warp, order):
    shrink = FPI([[0, 0], [40, 0], [40, 30], [0, 30]], [[10, 8], [22, 9], [24, 18], [11, 17]])
    img = make_image((31, 41, 2), np.uint8, seed=3)
    by_row, by_pixel = _launch_both_layouts(warp, img, shrink, (30, 40), order, "reflect", 5, antialias=True)
    np.testing.assert_array_equal(by_row, by_pixel)
    np.testing.assert_array_equal(by_row, warp.warp_image(img, shrink, (30, 40), order=order, mode="reflect",
                                                          cval=np.full(2, 5.0), antialias=True))


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("mode", MODES)
def test_taps_at_the_edges_take_the_border_rule(warp, order, mode):
    """Translations by fractions of a pixel put source positions on, just
    inside and just beyond every edge: the direct path ends exactly where
    the border rule starts (float32 images, within 1e-5 of the float64
    reference: the sampling's float32 rounding). Order 0 skips the shifts
    by half a pixel, where floor(x + 0.5) is a tie that float32 and float64
    positions may break either way."""
    img = make_image((9, 12, 1), np.float32, seed=5)
    corners = np.array([[0, 0], [11, 0], [11, 8], [0, 8]], dtype=np.float64)
    for shift in (-1.5, -0.75, -0.25, 0.25, 0.5, 1.25):
        if order == 0 and shift % 1 == 0.5:
            continue
        transform = FPI(corners, corners + [shift, -shift])
        want, cv = reference(img, transform, (9, 12), order, mode, 0.25)
        got = warp.warp_image(img, transform, (9, 12), order=order, mode=mode, cval=cv)
        np.testing.assert_allclose(got, want, atol=1e-5, rtol=0)
