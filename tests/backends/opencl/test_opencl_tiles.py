"""The OpenCL kernels' CPU launch shapes and fast paths (issue 14).

- warp_image in 64 x 8 tiles (fpiwarp/backends/opencl_tiles.py) gives the
  one-row groups' output bit for bit, over odd sizes, images narrower than
  a tile, 1-4 channels, every dtype, orders 0/1/3 and every mode;
- the interior sampling path (fpiwarp_map.h, fw_sample) gives the general
  path's values bit for bit (built with FW_INTERIOR=0 for the comparison),
  and the stores of whole work-items the clamped per-lane stores';
- map_points reading and writing 8 points per work-item as vectors
  (FW_POINT_VN=8) gives the one-point-per-work-item kernel's points bit for
  bit, for counts around the vector and group widths.

Each kernel is also checked against the numpy reference with the parity
rules of tests/test_backend_parity.py.
"""

import contextlib
import ctypes
import math
import mmap
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.kernel_cases import assert_images_agree, make_image, region_map, takes_coarse_pass, tps_map

import fpiwarp
from fpiwarp import FPI, RLinear
from fpiwarp.backends.opencl.tuning import CANDIDATES

MODES = ["constant", "edge", "reflect", "wrap"]


def backend():
    from fpiwarp.backends import get_backend

    return get_backend("opencl")


def maps(w, h):
    """Maps of several kinds over a w x h frame: FPIs (mild and strong), a
    sub-pixel shift (every tap inside: the interior path), a compound, a
    TPS with a Newton inverse, a map with regions."""
    w, h = (w, h) if min(w, h) >= 32 else (64, 48)  # quads of small images: a 64 x 48 frame's
    quad = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    return {
        "fpi": FPI(quad, [[0.5, 0.7], [w - 1.3, -0.4], [w + 0.2, h - 0.8], [-0.6, h - 1.1]]),
        "fpi_strong": FPI(quad, [[0.1 * w, 0.2 * h], [0.8 * w, -0.1 * h], [1.2 * w, 1.1 * h], [-0.2 * w, 0.7 * h]]),
        "shift": RLinear(1, 0, complex(0.37, -0.61)),
        "compound": RLinear(1.05, 0.02, 0.3) @ FPI(quad, [[1, 0], [w - 2, 1], [w, h - 1], [0, h - 2]]),
        "tps": tps_map(),
        "regions": region_map(),
    }


def run_kernel(image, transform, output_shape, order, mode, cval, *, tile=None, extra=(), lanes=None):
    """warp_image's kernel launched by hand: the backend's build options for
    this kind of call, with the work-group ``tile`` (local_x, local_y; None:
    the backend's one-row width), ``lanes`` pixels per work-item (None: the
    backend's) and ``extra`` options."""
    import pyopencl as cl

    be = backend()
    h, w, c = image.shape
    oh, ow = output_shape
    block = np.ascontiguousarray(transform.inverse.params(), dtype=np.float32)
    name, options, local_x = be.image_program(image.dtype, c, order, mode, ow, False, be.block_kind(block))
    local = (local_x, 1)
    if lanes is not None:
        options = (*(o for o in options if not o.startswith("-DFW_VN=")), f"-DFW_VN={lanes}")
    if tile is not None:
        local = tile
        options = tuple(o for o in options if not o.startswith("-DFW_LOCAL_X="))
        options += (f"-DFW_LOCAL_X={tile[0]}", f"-DFW_LOCAL_Y={tile[1]}")
    kern = be.kernel(name, (*options, *extra))
    mf = cl.mem_flags
    src = cl.Buffer(be.context, mf.READ_ONLY, image.nbytes + be.image_slack)
    cl.enqueue_copy(be.queue, src, np.ascontiguousarray(image))
    out = np.empty((oh, ow, c), dtype=image.dtype)
    dst = cl.Buffer(be.context, mf.WRITE_ONLY, out.nbytes)
    blk = cl.Buffer(be.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=block)
    cval4 = cl.cltypes.make_float4(*(list(cval) + [0.0] * (4 - c)))
    kern.set_args(blk, src, np.int32(w), np.int32(h), dst, np.int32(ow), np.int32(oh), cval4)
    glob = (-(-ow // local[0]) * local[0], -(-oh // local[1]) * local[1])
    cl.enqueue_nd_range_kernel(be.queue, kern, glob, local)
    cl.enqueue_copy(be.queue, out, dst)
    return out


@st.composite
def cases(draw):
    h, w = draw(st.integers(1, 30)), draw(st.sampled_from([1, 5, 8, 9, 17, 63, 64, 65, 100, 131]))
    c = draw(st.integers(1, 4))
    dtype = draw(st.sampled_from([np.uint8, np.uint16, np.float32]))
    image = make_image((h, w, c), dtype, draw(st.integers(0, 2**16)))
    kind = draw(st.sampled_from(sorted(maps(w, h))))
    oh, ow = draw(st.sampled_from([(h, w), (h + 3, w + 11), (max(1, h - 2), 70)]))
    order, mode = draw(st.sampled_from([0, 1, 3])), draw(st.sampled_from(MODES))
    top = 1.0 if dtype == np.float32 else float(np.iinfo(dtype).max)
    cval = [top * (k + 1) / 5 for k in range(c)]
    return image, maps(w, h)[kind], (oh, ow), order, mode, cval


def test_tiles_only_on_cpus_without_antialiasing_or_newton(opencl_backend):
    from fpiwarp.backends.opencl import tiles as opencl_tiles

    be = backend()
    fpi_kind = ("-DFW_KIND_0=0,0,0,0",)
    newton_kind = ("-DFW_KIND_0=0,0,0,0", "-DFW_KIND_1=2,3,0,12")
    assert not opencl_tiles.has_newton(fpi_kind) and opencl_tiles.has_newton(newton_kind)
    assert not opencl_tiles.tiled(be, True, fpi_kind)
    assert not opencl_tiles.tiled(be, False, newton_kind)
    assert opencl_tiles.tiled(be, False, fpi_kind) == (be.lanes > 1)
    name, options, local = opencl_tiles.tiled_program(be, np.uint8, 3, 1, "edge", 1000, False, fpi_kind)
    assert name == "warp_image" and sum(o.startswith("-DFW_LOCAL_X=") for o in options) == 1
    if be.lanes > 1:
        from fpiwarp.backends.opencl.tuning import tile_for

        assert local == tile_for(be)
        assert f"-DFW_LOCAL_Y={local[1]}" in options
    assert opencl_tiles.global_size((64, 8), (17, 130)) == (192, 24)


#: The launch shapes and widths a device may run (tuning.py), each against the
#: one-row general kernel, as (tile, lanes; None: the backend's): 64 x 8,
#: 128 x 4, the tuner's tall tiles, and 16 pixels per work-item (which
#: tune() may choose) in one row, 64 x 8 and 16 x 16.
#: Each example checks one, drawn, so every example builds three programs
#: instead of nine (the test cost a seventh of the suite) while the
#: derandomized examples still cover every variant several times.
TILE_VARIANTS = [((64, 8), None), ((128, 4), None), *((t, None) for t in CANDIDATES[1:3]),
                 (None, 16), ((64, 8), 16), ((16, 16), 16)]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=cases(), variant=st.sampled_from(TILE_VARIANTS))
def test_tiles_and_the_interior_path_give_the_one_row_general_output_bit_for_bit(opencl_backend, case, variant):
    image, transform, shape, order, mode, cval = case
    general = run_kernel(image, transform, shape, order, mode, cval, extra=("-DFW_INTERIOR=0",))
    interior = run_kernel(image, transform, shape, order, mode, cval)
    np.testing.assert_array_equal(interior, general)
    if backend().lanes > 1:
        tile, lanes = variant
        np.testing.assert_array_equal(run_kernel(image, transform, shape, order, mode, cval, tile=tile, lanes=lanes),
                                      general)
    got = fpiwarp.warp_image(image, transform, shape, order=order, mode=mode, cval=cval, backend="opencl")
    if takes_coarse_pass(transform, "opencl", shape):  # the coarse pass: nearer positions than a per-pixel solve
        assert_images_agree(got, general, image.dtype.type)
    else:
        np.testing.assert_array_equal(got, general)
    want = fpiwarp.warp_image(image, transform, shape, order=order, mode=mode, cval=cval, backend="numpy")
    if np.isfinite(fpiwarp.source_positions(transform, shape)).all():  # Newton misses may differ at its edge
        assert_images_agree(got, want, image.dtype.type)


@pytest.mark.parametrize("shape", [(2160 // 8, 3840 // 8), (300, 257)])
def test_tiled_fpi_warp_of_a_frame_matches_the_reference(opencl_backend, shape):
    """A larger frame: many tiles, the interior path on most of it."""
    h, w = shape
    image = make_image((h, w, 3), np.uint8, 3)
    fpi = maps(w, h)["fpi_strong"]
    for order in (0, 1, 3):
        got = fpiwarp.warp_image(image, fpi, order=order, mode="constant", backend="opencl")
        assert_images_agree(got, fpiwarp.warp_image(image, fpi, order=order, mode="constant", backend="numpy"),
                            np.uint8)


@pytest.mark.parametrize("n", [1, 7, 8, 9, 1023, 1024, 1025, 3000])
def test_vector_map_points_equal_one_point_per_work_item(opencl_backend, n):
    import pyopencl as cl

    be = backend()
    rng = np.random.default_rng(n)
    fpi = maps(64, 48)["fpi_strong"]
    pts = np.ascontiguousarray(rng.uniform(-10, 70, (n, 2)), dtype=be.point_dtype)
    block = np.ascontiguousarray(fpi.params(), dtype=np.float32)
    kind = be.block_kind(block)
    mf = cl.mem_flags
    blk = cl.Buffer(be.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=block)
    src = cl.Buffer(be.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=pts)
    results = []
    for vn in (1, 8):
        options = tuple(o for o in be.point_options if not o.startswith("-DFW_POINT_VN"))
        kern = be.kernel("map_points", (*kind, *options, f"-DFW_LOCAL_X={be.local_x}", f"-DFW_POINT_VN={vn}"))
        out = np.full_like(pts, -7.0)
        dst = cl.Buffer(be.context, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=out)
        kern.set_args(blk, src, dst, np.int32(n))
        cl.enqueue_nd_range_kernel(be.queue, kern, (-(-n // be.local_x) * be.local_x,), (be.local_x,))
        cl.enqueue_copy(be.queue, out, dst)
        results.append(out)
    np.testing.assert_array_equal(results[1], results[0])
    got = fpiwarp.map_points(fpi, pts.astype(np.float64), backend="opencl")
    np.testing.assert_array_equal(got, results[1].astype(np.float64))
    np.testing.assert_allclose(got, fpiwarp.map_points(fpi, pts.astype(np.float64), backend="numpy"),
                               rtol=1e-4, atol=1e-3)


IN_PLACE_CASES = [(np.float32, 3), (np.float32, 1), (np.uint16, 2), (np.uint16, 1), (np.uint16, 3),
                  (np.uint8, 1), (np.uint8, 2), (np.uint8, 3), (np.uint8, 4)]


def assert_in_place_warp_is_the_uploaded_one(image, transform, mode):
    """``image`` (1 MiB or more) goes to the kernel in place on a CPU
    (opencl_prepared.ClJob); its warp equals a batch of one (an uploaded
    copy with slack) bit for bit and the numpy reference by the parity rules."""
    from fpiwarp.backends.opencl import prepared as opencl_prepared

    c = image.shape[2]
    kind = backend().block_kind(np.ascontiguousarray(transform.inverse.params(), np.float32))
    job = opencl_prepared.ClJob(backend(), image, image.shape[:2], 1, mode, [0.0] * c, False, kind)
    assert job._src_in_place == backend().zero_copy
    got = fpiwarp.warp_image(image, transform, order=1, mode=mode, backend="opencl")
    batch = fpiwarp.warp_batch(image[None], transform, order=1, mode=mode, backend="opencl")[0]
    np.testing.assert_array_equal(got, batch)
    assert_images_agree(got, fpiwarp.warp_image(image, transform, order=1, mode=mode, backend="numpy"),
                        image.dtype.type)


@pytest.mark.parametrize("dtype, channels", IN_PLACE_CASES)
def test_large_sources_read_in_place_give_the_uploaded_output(opencl_backend, dtype, channels):
    """Sources of 1 MiB or more are read in place whatever their pixel size
    (the kernel never reads past the last byte, FW_WORD_TAIL): the same
    output as the uploaded copy, for two different images in turn (no stale
    source) and a read-only one."""
    h, w = 1000, 1100 // channels
    fpi = maps(w, h)["fpi_strong"]
    for seed in (1, 2):
        image = make_image((h, w, channels), dtype, seed)
        image.flags.writeable = seed == 1
        assert_in_place_warp_is_the_uploaded_one(image, fpi, "edge")


@contextlib.contextmanager
def array_before_a_guard_page(shape, dtype):
    """A C-contiguous array of ``shape`` (a whole number of pages) filling
    anonymous mmap'd pages up to a PROT_NONE page: a read past its last
    byte faults (the test process dies) instead of reading garbage."""
    nbytes = math.prod(shape) * np.dtype(dtype).itemsize
    assert nbytes % mmap.PAGESIZE == 0
    mem = mmap.mmap(-1, nbytes + mmap.PAGESIZE)
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mprotect.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    array = np.frombuffer(mem, dtype=dtype, count=math.prod(shape)).reshape(shape)
    end = array.ctypes.data + nbytes
    assert libc.mprotect(end, mmap.PAGESIZE, 0) == 0, ctypes.get_errno()  # PROT_NONE
    try:
        yield array
    finally:  # the pages go with the last reference to the array
        libc.mprotect(end, mmap.PAGESIZE, mmap.PROT_READ | mmap.PROT_WRITE)


@pytest.mark.skipif(not hasattr(mmap, "PROT_READ") or sys.platform != "linux", reason="needs mprotect")
@pytest.mark.parametrize("mode", ["edge", "constant"])
@pytest.mark.parametrize("dtype, channels", IN_PLACE_CASES)
def test_sources_read_in_place_are_not_read_past_their_last_byte(opencl_backend, dtype, channels, mode):
    """A source whose last pixel ends at a page boundary followed by a
    PROT_NONE page, read in place: a load of the last pixel(s) that ran
    past the end (a 32-bit word, a 64-bit gather or a vector load of a
    row's two taps, FW_PAIR) would fault; every case of IN_PLACE_CASES.
    The warps reach that pixel through the general path (taps clamped to the corner, edge mode, or replaced by
    cval) and next to the last row through the interior path (a sub-pixel
    shift), and equal the uploaded copy's."""
    h, w = 1024, 1032 // (channels * np.dtype(dtype).itemsize)  # 1032 KiB: whole pages
    with array_before_a_guard_page((h, w, channels), dtype) as image:
        image[...] = make_image((h, w, channels), dtype, 3)
        for transform in (maps(w, h)["fpi_strong"], maps(w, h)["shift"], RLinear(1, 0, complex(0.5, 0.5))):
            assert_in_place_warp_is_the_uploaded_one(image, transform, mode)


def test_the_tile_is_measured_once_per_device_and_kept(opencl_backend, monkeypatch, tmp_path):
    from fpiwarp.backends.opencl import tuning

    monkeypatch.setenv("FPIWARP_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv(tuning.ENV_TILE, raising=False)
    be = backend()
    monkeypatch.setattr(be, "_tile", None, raising=False)
    monkeypatch.setattr(be, "lanes", be.lanes)  # tune() sets the measured width
    if be.lanes == 1:
        assert tuning.tune(be)["tile"] is None
        return
    assert not tuning.tuned(be) and tuning.tile_for(be) == tuning.DEFAULT_TILE
    assert tuning.lanes_for(be) == tuning.DEFAULT_LANES
    monkeypatch.setattr(tuning, "TUNING_SHAPE", (96, 128, 3))
    monkeypatch.delenv(tuning.ENV_LANES, raising=False)
    plain = tuning.tune(be, candidates=((64, 8), (16, 16)), wide=False)
    assert set(plain["seconds"]) == {"64x8", "16x16"} and plain["lanes"] == tuning.DEFAULT_LANES
    result = tuning.tune(be, candidates=((64, 8), (16, 16), (4096, 4096)))  # the last does not fit
    # the tiles at 8 lanes, then the fastest of them at 16 where the device's vectors are 16 wide
    wide = set(result["seconds"]) - {"64x8", "16x16"}
    assert result["tile"] in ((64, 8), (16, 16)) and {"64x8", "16x16"} <= set(result["seconds"])
    assert wide <= {"64x8x16", "16x16x16"} and len(wide) == (tuning.WIDE_LANES in tuning.candidate_lanes(be))
    assert result["lanes"] in tuning.candidate_lanes(be) and be.lanes == result["lanes"]
    assert tuning.tuned(be) and tuning.tile_for(be) == result["tile"]
    monkeypatch.setattr(be, "_tile", None)  # a new process: read back from the disk
    assert tuning.tile_for(be) == result["tile"] and tuning.lanes_for(be) == result["lanes"] and be.tune() is None
    monkeypatch.setenv(tuning.ENV_LANES, "8")
    assert tuning.lanes_for(be) == 8
    monkeypatch.setenv(tuning.ENV_LANES, "12")
    with pytest.raises(fpiwarp.ArgumentError, match="FPIWARP_OPENCL_LANES must be one of"):
        tuning.lanes_for(be)
    monkeypatch.setenv(tuning.ENV_LANES, "8")  # a fixed width: tune measures tiles only, and keeps it
    fixed = tuning.tune(be, candidates=((64, 8), (16, 16)))
    assert set(fixed["seconds"]) == {"64x8", "16x16"} and be.lanes == 8
    monkeypatch.delenv(tuning.ENV_LANES)
    monkeypatch.setattr(be, "_tile", None)
    monkeypatch.setenv(tuning.ENV_TILE, "32,16")
    assert tuning.tile_for(be) == (32, 16)
    img = make_image((40, 70, 3), np.uint8, 5)
    f = maps(70, 40)["fpi_strong"]
    assert_images_agree(fpiwarp.warp_image(img, f, backend="opencl"), fpiwarp.warp_image(img, f, backend="numpy"),
                        np.uint8)
    monkeypatch.setattr(be, "_tile", None)
    monkeypatch.setenv(tuning.ENV_TILE, "abc")
    with pytest.raises(fpiwarp.ArgumentError, match="FPIWARP_OPENCL_TILE must be X,Y"):
        tuning.tile_for(be)
    monkeypatch.setattr(be, "_tile", None)


@pytest.mark.parametrize("antialias", [False, True])
@pytest.mark.parametrize("kind", ["fpi_strong", "tps", "regions"])
def test_sixteen_lanes_give_the_eight_lane_output_bit_for_bit(opencl_backend, monkeypatch, kind, antialias):
    """Every warp_image program at 16 pixels per work-item (tiled, one-row
    Newton groups, antialiased), which tune() may choose, as at 8."""
    from fpiwarp.backends.opencl.prepared import JobCache

    be = backend()
    if be.lanes == 1:
        pytest.skip("the device runs one pixel per work-item")
    image = make_image((37, 83, 3), np.uint8, 11)
    transform = maps(83, 37)[kind]
    got = {}
    for lanes in (8, 16):
        monkeypatch.setattr(be, "lanes", lanes)
        monkeypatch.setattr(be, "_jobs", JobCache())
        block = np.ascontiguousarray(transform.inverse.params(), dtype=np.float32)
        assert f"-DFW_VN={lanes}" in be.image_program(np.uint8, 3, 1, "reflect", 90, antialias, be.block_kind(block))[1]
        got[lanes] = fpiwarp.warp_image(image, transform, (41, 90), order=1, mode="reflect", antialias=antialias,
                                        backend="opencl")
    np.testing.assert_array_equal(got[16], got[8])
