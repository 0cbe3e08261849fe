"""The "opencl" backend against the numpy reference (float32 on the device).

map_points must agree with ``fpiwarp.block.evaluate`` in float64 to 1e-5
relative to the coordinates' scale away from the pole, and warp_image with
the numpy backend within one uint8 level (or the equivalent for uint16 and
float32) on at least 99.8 % of the pixels, for every order, border mode,
dtype and channel count. Tests run on whatever device the backend picks
(FPIWARP_OPENCL_DEVICE chooses); they skip without a driver unless
FPIWARP_REQUIRE_BACKENDS lists opencl.
"""

import dataclasses
import weakref

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, Mobius, RLinear
from fpiwarp.backends import get_backend
from fpiwarp.block import (
    CORE_TPS,
    CORE_TPS_INVERSE,
    ROW_HEADER,
    LinearPart,
    MobiusPart,
    Region,
    Stage,
    evaluate,
    pack,
)
from fpiwarp.maps.thin_plate_spline import DEVICE_RTOL

RTOL = 1e-5
#: share of pixels that must be within one level of the reference
PIXEL_SHARE = 0.998


@pytest.fixture
def backend(opencl_backend):
    return get_backend(opencl_backend)


class BlockMap:
    """A stand-in transform for a hand-built parameter block (the backend
    only reads ``params()``)."""

    def __init__(self, stages):
        self.stage = stages[0]
        self.block = pack(stages)

    def params(self):
        return self.block


def rel_error(got, ref):
    """|got - ref| per point, relative to the points' overall scale."""
    scale = max(1.0, float(np.max(np.abs(ref))))
    return np.linalg.norm(got - ref, axis=-1) / scale


def grid_points(rng, lo=-20.0, hi=80.0, n=4000):
    return rng.uniform(lo, hi, size=(n, 2))


# ---- map_points -----------------------------------------------------------


def test_map_points_fpi_mobius_rlinear_compound(backend, rng, sample_fpi):
    pts = grid_points(rng)
    mob = Mobius.centered(30 + 20j, 0.002 - 0.001j, 1.1 + 0.2j, 3 - 1j)
    maps = [
        sample_fpi,
        sample_fpi.inverse,
        mob,
        RLinear(1.2 + 0.1j, 0.15 - 0.05j, 4 - 2j),
        sample_fpi @ RLinear(0.9 - 0.1j, 0.05j, 1 + 1j),
        FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[2, 1], [61, 3], [60, 45], [1, 49]]) @ sample_fpi,
    ]
    for f in maps:
        ref = evaluate(f.params(), pts)
        got = backend.map_points(f, pts)
        assert got.dtype == np.float64 and got.shape == pts.shape
        assert rel_error(got, ref).max() < RTOL, f


def test_map_points_with_and_without_zero_copy(backend, sample_fpi, rng, monkeypatch):
    """Both data paths (host pointers on CPU devices, copies elsewhere)."""
    pts = grid_points(rng, n=3001)
    for zero_copy in (True, False):
        monkeypatch.setattr(backend, "zero_copy", zero_copy)
        assert rel_error(backend.map_points(sample_fpi, pts), sample_fpi(pts)).max() < RTOL


def test_map_points_keeps_shape(backend, sample_fpi, rng):
    pts = rng.uniform(0, 60, size=(3, 5, 2))
    got = fpiwarp.map_points(sample_fpi, pts, backend="opencl")
    assert got.shape == (3, 5, 2)
    assert rel_error(got, sample_fpi(pts)).max() < RTOL
    assert fpiwarp.map_points(sample_fpi, np.zeros((0, 2)), backend="opencl").shape == (0, 2)
    frozen = np.broadcast_to(pts[0, 0], (4, 2))  # read-only input
    assert rel_error(fpiwarp.map_points(sample_fpi, frozen, backend="opencl"), sample_fpi(frozen)).max() < RTOL


def tps_stage(rng, core, **kw):
    """A stage with a TPS core in O(1) coordinates between pixel-sized
    pre- and post-Möbius maps (as ConstrainedFPI builds them)."""
    n = 16
    return Stage(
        pre=MobiusPart(center=30 + 20j, inverse_pole=0.001 + 0.0005j, scale=1 / 40),
        linear=LinearPart(1.05 + 0.05j, 0.08 - 0.03j, 0.02 + 0.01j),
        post=MobiusPart(inverse_pole=0.01 - 0.02j, scale=40 + 2j, offset=30 + 20j),
        core=core,
        centers=rng.uniform(-1, 1, n) + 1j * rng.uniform(-1, 1, n),
        weights=0.01 * (rng.standard_normal(n) + 1j * rng.standard_normal(n)),
        **kw,
    )


def test_map_points_tps_core(backend, rng):
    pts = grid_points(rng)
    f = BlockMap([tps_stage(rng, CORE_TPS)])
    ref = evaluate(f.params(), pts)
    assert rel_error(backend.map_points(f, pts), ref).max() < RTOL


def test_map_points_tps_newton_inverse(backend, rng):
    """Newton's inverse of the TPS core: where both converge, the device and
    the float64 reference agree (each is within newton_tol of the root)."""
    pts = grid_points(rng)
    f = BlockMap([tps_stage(rng, CORE_TPS_INVERSE, newton_iters=12, newton_tol=2e-6)])
    ref = evaluate(f.params(), pts)
    got = backend.map_points(f, pts)
    both = np.isfinite(ref).all(-1) & np.isfinite(got).all(-1)
    assert both.mean() > 0.99
    assert rel_error(got[both], ref[both]).max() < RTOL
    # a tolerance float32 rarely reaches gives NaN ("outside"), never a wrong value
    strict = BlockMap([dataclasses.replace(f.stage, newton_tol=1e-12)])
    ref = evaluate(strict.params(), pts)
    got = backend.map_points(strict, pts)
    ok = np.isfinite(got).all(-1)
    assert 0.2 < (~ok).mean() and rel_error(got[ok], ref[ok]).max() < RTOL


def test_map_points_regions(backend, rng):
    inner = tps_stage(rng, CORE_TPS)
    regions = (
        Region(origin=70 + 0j, normal=1 + 0j, a=1.1 + 0.1j, b=-5 + 2j),
        Region(origin=0 - 10j, normal=0.2 - 1j, a=0.9 + 0j, b=3 + 3j),
    )
    stage = dataclasses.replace(inner, regions=regions)
    pts = grid_points(rng, -40, 110)
    f = BlockMap([stage, Stage(linear=LinearPart(1 + 0.1j, 0.05, 2 - 1j))])
    ref = evaluate(f.params(), pts)
    got = backend.map_points(f, pts)
    assert rel_error(got, ref).max() < RTOL
    # every branch was exercised: some points in each region, some inside
    z = pts[:, 0] + 1j * pts[:, 1]
    depths = [((z - r.origin) * np.conj(r.normal)).real for r in regions]
    assert all((d > 0).sum() > 50 for d in depths) and ((depths[0] <= 0) & (depths[1] <= 0)).sum() > 50


def test_map_points_matches_constrained_and_local_maps(backend, rng):
    from fpiwarp.maps.constrained import ConstrainedFPI
    from fpiwarp.maps.local import LocalDeformation

    src = [[10, 8], [50, 6], [54, 40], [8, 42]]
    dst = [[12, 9], [49, 4], [58, 44], [6, 40]]
    pts = grid_points(rng)
    for f in (ConstrainedFPI(src, dst, edges=(3, 1)), LocalDeformation(src, dst, edges=(3, 1))):
        ref = evaluate(f.params(), pts)
        got = backend.map_points(f, pts)
        assert rel_error(got, ref).max() < RTOL
        inv = f.inverse
        ref = evaluate(inv.params(), pts)
        got = backend.map_points(inv, pts)
        both = np.isfinite(ref).all(-1) & np.isfinite(got).all(-1)
        assert both.mean() > 0.99
        # the device Newton stops at DEVICE_RTOL relative (fpiwarp.maps.thin_plate_spline): so does the match
        assert rel_error(got[both], ref[both]).max() < DEVICE_RTOL


def run_map_points_kernel(backend, block, pts, kind_options=()):
    """map_points' kernel on a raw block, bypassing the host's checks:
    without kind options the generic program reads the kind from the block."""
    cl = pytest.importorskip("pyopencl")
    options = tuple(kind_options) + backend._point_options + (f"-DFW_LOCAL_X={backend.local_x}",)
    kern = backend.kernel("map_points", options)
    pts = pts.astype(np.float64 if backend.has_fp64 else np.float32)
    out = np.empty_like(pts)
    mf = cl.mem_flags
    buf = cl.Buffer(backend.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(block))
    src = cl.Buffer(backend.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=pts)
    dst = cl.Buffer(backend.context, mf.WRITE_ONLY, out.nbytes)
    kern(backend.queue, (len(pts),), (backend.local_x,), buf, src, dst, np.int32(len(pts)))
    cl.enqueue_copy(backend.queue, out, dst)
    backend.queue.finish()
    return out


def test_generic_program_reads_the_kind_from_the_block(backend, rng, sample_fpi):
    """Without kind defines, fw_map loops over the stages of any block."""
    f = BlockMap([tps_stage(rng, CORE_TPS), sample_fpi.stages()[0], Stage(linear=LinearPart(1j, 0.1, 3))])
    pts = grid_points(rng, n=backend.local_x)
    out = run_map_points_kernel(backend, f.params(), pts)
    assert rel_error(out, evaluate(f.params(), pts)).max() < RTOL


def test_unknown_core_is_refused_by_the_host_and_outside_in_the_kernel(backend, rng, sample_fpi):
    """A core no kernel knows: map_points raises before any launch; the
    kernel itself, given such a block anyway, returns NaN ("outside") in
    the generic program and in one specialized to that kind, never a
    silent Newton inverse."""
    block = sample_fpi.params().copy()
    block[1 + ROW_HEADER, 0] = 7

    class RawBlock:
        def params(self):
            return block

        @property
        def inverse(self):
            return self

    pts = grid_points(rng, n=backend.local_x)
    with pytest.raises(ValueError, match="unknown core 7"):
        backend.map_points(RawBlock(), pts)
    with pytest.raises(ValueError, match="unknown core 7"):
        backend.warp_image(np.zeros((4, 4, 1), np.uint8), RawBlock(), (4, 4), order=1, mode="edge", cval=[0.0])
    for kind in ((), ("-DFW_KIND_0=7,0,0,0",)):
        assert np.isnan(run_map_points_kernel(backend, block, pts, kind)).all(), kind


def test_map_points_pole_is_not_finite(backend):
    mob = Mobius.centered(0j, 0.5 + 0j, 1 + 0j, 0j)  # pole at u = 2
    got = backend.map_points(mob, np.array([[2.0, 0.0], [1.0, 0.0]]))
    assert not np.isfinite(got[0]).all() and np.allclose(got[1], [2.0, 0.0])


# ---- warp_image -----------------------------------------------------------


def test_image(rng, dtype, channels, shape=(40, 56)):
    values = rng.random(shape + (channels,))
    if np.dtype(dtype).kind == "u":
        return (values * np.iinfo(dtype).max).astype(dtype)
    return values.astype(dtype)


test_image.__test__ = False  # a helper, not a test


def level(dtype):
    """One uint8 level in the units of ``dtype``."""
    return {np.uint8: 1, np.uint16: 257, np.float32: 1 / 255}[dtype]


def assert_close_to_numpy(image, f, **kw):
    got = fpiwarp.warp_image(image, f, backend="opencl", **kw)
    ref = fpiwarp.warp_image(image, f, backend="numpy", **kw)
    assert got.dtype == image.dtype and got.shape == ref.shape
    assert np.isfinite(got.astype(np.float64)).all()
    diff = np.abs(got.astype(np.float64) - ref.astype(np.float64))
    share = (diff <= level(image.dtype.type) * 1.0001).mean()
    assert share >= PIXEL_SHARE, (kw, share, diff.max())


@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", ["constant", "edge", "reflect", "wrap"])
def test_warp_orders_and_modes(opencl_backend, rng, sample_fpi, order, mode):
    image = test_image(rng, np.uint8, 3)
    # a map pulling the border in, so border modes decide many pixels
    f = sample_fpi @ RLinear(0.7 + 0.1j, 0.05, 10 + 8j)
    assert_close_to_numpy(image, f, order=order, mode=mode, cval=(10, 200, 30))


@pytest.mark.parametrize(("dtype", "order", "mode"), [
    (np.uint16, 1, "constant"),
    (np.float32, 1, "edge"),
    (np.float32, 3, "reflect"),
    (np.uint16, 0, "wrap"),
])
def test_warp_dtypes(opencl_backend, rng, sample_fpi, dtype, order, mode):
    image = test_image(rng, dtype, 3)
    assert_close_to_numpy(image, sample_fpi, order=order, mode=mode, cval=0.25 if dtype == np.float32 else 7)


@pytest.mark.parametrize("channels", [1, 2, 4])
def test_warp_channels(opencl_backend, rng, sample_fpi, channels):
    image = test_image(rng, np.uint8, channels)
    assert_close_to_numpy(image, sample_fpi, order=1, mode="constant", cval=list(range(5, 5 + channels)))
    # (H, W) images come back as (H, W)
    if channels == 1:
        got = fpiwarp.warp_image(image[:, :, 0], sample_fpi, backend="opencl")
        assert got.shape == image.shape[:2]


@pytest.mark.parametrize(("dtype", "channels", "order", "mode"), [
    (np.uint8, 3, 1, "constant"),  # one 32-bit load per tap
    (np.uint16, 2, 0, "wrap"),  # 16-bit channels of one 32-bit load
    (np.uint16, 3, 1, "edge"),  # a load per channel
    (np.float32, 1, 3, "reflect"),
])
def test_warp_one_lane_and_copies(backend, rng, sample_fpi, monkeypatch, dtype, channels, order, mode):
    """The data paths CPUs do not take by default: sampling one pixel per
    work-item (as on GPUs) and the output copied back rather than written
    in place."""
    monkeypatch.setattr(backend, "lanes", 1)
    monkeypatch.setattr(backend, "zero_copy", False)
    image = test_image(rng, dtype, channels)
    f = sample_fpi @ RLinear(0.7 + 0.1j, 0.05, 10 + 8j)
    assert_close_to_numpy(image, f, order=order, mode=mode, cval=list(range(3, 3 + channels)))


@pytest.mark.parametrize(("dtype", "channels"), [(np.uint8, 3), (np.uint16, 2)])
def test_warp_identity_is_exact(backend, rng, dtype, channels):
    """At pixel centers bilinear sampling returns the pixels exactly: every
    channel comes out of its 32-bit word in place, the last pixel too
    (whose word runs past the end of the image)."""
    image = test_image(rng, dtype, channels, shape=(5, 7))
    got = fpiwarp.warp_image(image, RLinear(1, 0, 0), order=1, mode="constant", backend="opencl")
    np.testing.assert_array_equal(got, image)


def test_warp_output_shape_and_pole(opencl_backend, rng):
    """An output crossing the pole: non-finite positions give cval, and an
    output shape that is not a multiple of the work-group width."""
    image = test_image(rng, np.float32, 1)
    f = Mobius.centered(20 + 15j, 0.04 + 0.02j, 1 + 0j, 0j).inverse
    assert_close_to_numpy(image, f, output_shape=(37, 71), order=1, mode="edge", cval=0.5)


def test_warp_constrained_and_local(opencl_backend, rng):
    from fpiwarp.maps.constrained import ConstrainedFPI
    from fpiwarp.maps.local import LocalDeformation

    src = [[10, 8], [50, 6], [54, 40], [8, 42]]
    dst = [[12, 9], [49, 4], [58, 44], [6, 40]]
    image = test_image(rng, np.uint8, 3)
    for f in (ConstrainedFPI(src, dst, edges=(3, 1)), LocalDeformation(src, dst, edges=(3, 1))):
        assert_close_to_numpy(image, f, order=1, mode="constant", cval=0)


# ---- caching and device choice -----------------------------------------


def test_programs_and_buffers_are_reused(backend, rng, sample_fpi):
    image = test_image(rng, np.uint8, 3)
    backend.warp_image(image, sample_fpi, image.shape[:2], order=1, mode="edge", cval=np.zeros(3))
    programs = dict(backend._kernels)
    buffers = dict(backend._buffers)
    other = FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[1, 2], [62, 1], [64, 46], [-1, 45]])
    backend.warp_image(image, other, image.shape[:2], order=1, mode="edge", cval=np.ones(3))
    assert backend._kernels == programs  # new values, same kind: no new build
    assert all(backend._buffers[k] is v for k, v in buffers.items())


def test_unchanged_block_is_not_uploaded_again_and_a_changed_one_is(backend, rng, sample_fpi, monkeypatch):
    """The block upload is skipped only for the very same block: maps
    alternating in one kind each give their own result."""
    image = test_image(rng, np.uint8, 3)
    other = FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[1, 2], [62, 1], [64, 46], [-1, 45]])
    kw = {"order": 1, "mode": "edge", "cval": np.zeros(3)}
    maps = [sample_fpi, other]
    first = [backend.warp_image(image, f, image.shape[:2], **kw).copy() for f in maps]
    uploads = []
    real_copy = backend._cl.enqueue_copy

    def copy(queue, dst, src, **k):
        uploads.append(src)
        return real_copy(queue, dst, src, **k)

    monkeypatch.setattr(backend._cl, "enqueue_copy", copy)
    for i in (1, 1, 0, 0, 1):
        np.testing.assert_array_equal(backend.warp_image(image, maps[i], image.shape[:2], **kw), first[i])
    blocks = [u for u in uploads if isinstance(u, np.ndarray) and u.dtype == np.float32 and u.ndim == 2]
    assert len(blocks) == 2  # other's block is kept from the last call; sample_fpi once, other once again


def test_large_outputs_are_written_in_place_and_small_ones_copied(backend, rng, sample_fpi):
    from fpiwarp.backends.opencl import backend as ocl

    if not backend.zero_copy:
        pytest.skip("the device does not share host memory")
    for shape in [(48, 64), (600, 700)]:  # 9 KB and 1.26 MB of uint8 RGB output
        image = test_image(rng, np.uint8, 3, shape=shape)
        job = backend.prepare_warp(image, shape, order=1, mode="constant", cval=np.zeros(3))
        assert job._zero_copy == (image.nbytes >= ocl.ZERO_COPY_MIN_BYTES)
        assert_close_to_numpy(image, sample_fpi, order=1, mode="constant", cval=0)


@pytest.mark.parametrize(("shape", "dtype"), [((1, 3), np.uint8), ((1, 4), np.uint8), ((3, 5, 3), np.uint16),
                                             ((40, 56, 3), np.float32)])
def test_sources_read_in_place_warp_as_uploaded_ones(backend, rng, monkeypatch, shape, dtype):
    """On a device sharing host memory the kernel reads a source of
    IMAGE_SLACK bytes or more where it lies (its 32-bit loads never run past
    the last byte), a smaller one from an upload: both give what the
    uploaded source gives, bit for bit, at every order and mode."""
    from fpiwarp.backends.opencl import prepared

    if not backend.zero_copy:
        pytest.skip("the device does not share host memory")
    image = test_image(rng, dtype, shape[2] if len(shape) == 3 else 1, shape=shape[:2])
    image = image.reshape(*shape[:2], -1)
    f = FPI([[0, 0], [9, 0], [9, 9], [0, 9]], [[0.3, 0.2], [9.4, -0.3], [9.2, 9.5], [-0.4, 8.7]])
    for order, mode in [(0, "edge"), (1, "constant"), (3, "reflect"), (1, "wrap")]:
        kw = {"order": order, "mode": mode, "cval": np.full(image.shape[2], 2.0)}
        monkeypatch.setattr(backend, "_jobs", prepared.JobCache())
        in_place = backend.warp_image(image, f, shape[:2], **kw)
        (job,) = [backend._jobs.lookup(k, None) for k in backend._jobs.keys()]
        assert job._src_in_place == (image.nbytes >= prepared.IMAGE_SLACK)
        with monkeypatch.context() as m:
            m.setattr(backend, "zero_copy", False)
            m.setattr(backend, "_jobs", prepared.JobCache())
            uploaded = backend.warp_image(image, f, shape[:2], **kw)
        np.testing.assert_array_equal(in_place, uploaded)


def test_large_outputs_are_recycled_only_once_dropped(opencl_backend, rng, sample_fpi, monkeypatch):
    """An output of RECYCLE_MIN_BYTES or more is reused by a later call
    once nothing refers to it: a result held (or a view of it, or a weak
    reference) keeps its pixels through later calls, every result is the
    warp of its own image, and a loop that holds each result until the next
    call allocates two arrays."""
    from fpiwarp.backends.opencl import prepared

    if prepared._UNUSED_REFS is None:
        pytest.skip("no reference counts in this interpreter")
    monkeypatch.setattr(prepared, "RECYCLE_MIN_BYTES", 1000)  # the 40 x 56 RGB float32 outputs (27 KB)
    a, b = (test_image(rng, np.float32, 3) for _ in range(2))
    expected = {id(img): fpiwarp.warp_image(img, sample_fpi, backend="numpy") for img in (a, b)}
    allocated = []
    real_empty = prepared.np.empty

    def counting_empty(*args, **kw):
        allocated.append(args)
        return real_empty(*args, **kw)

    monkeypatch.setattr(prepared.np, "empty", counting_empty)

    def check(result, img):
        np.testing.assert_allclose(result, expected[id(img)], atol=2e-3)

    warper = fpiwarp.Warper(sample_fpi, backend=opencl_backend)
    out = None
    for img in (a, b, a, b, a):
        out = warper(img)
        check(out, img)
    assert len(allocated) == 2
    del out

    warper = fpiwarp.Warper(sample_fpi, backend=opencl_backend)
    allocated.clear()
    held = warper(a)
    first = held.copy()
    again = warper(b)  # `held` is held: a new array
    assert again is not held and len(allocated) == 2
    np.testing.assert_array_equal(held, first)
    check(again, b)
    del again
    for img in (a, b, a):  # each result dropped: `again`'s array, reused
        check(warper(img), img)
    assert len(allocated) == 2
    view = warper(b)[5:, :, 1]
    check(warper(a), a)  # both spares are held (`held`, the view's array): a new one
    check(view.base, b)
    assert len(allocated) == 3
    del view
    result = warper(b)  # the view's array, free again: reused
    assert len(allocated) == 3
    result.flags.writeable = False
    del result
    check(warper(a), a)  # a read-only array is not written: the other spare
    assert len(allocated) == 3
    result = warper(b)
    ref = weakref.ref(result)
    del result
    kept = warper(a)  # nor one with a weak reference: a new one
    assert len(allocated) == 4 and kept.flags.writeable
    assert ref() is not None and ref() is not kept
    check(ref(), b)
    check(kept, a)
    np.testing.assert_array_equal(held, first)


def test_device_choice(monkeypatch, opencl_backend):
    from fpiwarp.backends.opencl import backend as ocl

    devices = ocl.list_devices()
    assert devices == ocl.list_devices()  # deterministic order
    label, _ = ocl.choose_device()
    assert label == devices[0][0]
    last_label = devices[-1][0]
    monkeypatch.setenv(ocl.ENV_DEVICE, last_label.upper())
    assert ocl.choose_device()[0] == last_label
    monkeypatch.setenv(ocl.ENV_DEVICE, "no such device 1234")
    with pytest.raises(RuntimeError, match="no OpenCL device matches 'no such device 1234'"):
        ocl.choose_device()
    assert "no OpenCL device matches" in ocl.probe()
    with pytest.raises(RuntimeError, match="found: "):
        ocl.Backend()
    assert ocl.Backend(device=last_label.lower()).device_label == last_label


def test_program_source_inlines_header():
    from fpiwarp.backends.opencl import backend as ocl

    text = ocl.program_source()
    assert '#include "' not in text and "fw_stage_kind" in text
    assert "void warp_image(" in text and "void map_points(" in text
