"""The opencl backend's source pyramid (backends/opencl/pyramid.py): the
levels built on the device against the numpy reference's, their reuse by
prepared jobs and batches, the level estimate and the kernel's request
for more levels, and the antialiased paths against each other."""

import numpy as np
import pytest
from support import kernel_cases

import fpiwarp
from fpiwarp import RLinear
from fpiwarp.backends import get_backend
from fpiwarp.sampling.pyramid import Pyramid

SHRINK_8 = RLinear(0.125, 0, 0.3 + 0.2j)
MIXED = fpiwarp.FPI([[0, 0], [159, 0], [159, 119], [0, 119]], [[1, 2], [38, 0], [9, 6], [0, 20]])
KW = {"order": 1, "mode": "reflect", "cval": np.array([9.0, 99.0, 200.0])}


@pytest.fixture
def backend(opencl_backend):
    return get_backend(opencl_backend)


def _levels(backend, image):
    """The device pyramid of ``image`` read back: [level 1, level 2, ...]."""
    from fpiwarp.backends.opencl.pyramid import DevicePyramid

    h, w, c = image.shape
    _, options, _ = backend.image_program(image.dtype, c, 1, "edge", 64, True, ())
    src = backend._cl.Buffer(backend.context, backend._cl.mem_flags.READ_ONLY | backend._cl.mem_flags.COPY_HOST_PTR,
                             hostbuf=image)
    pyramid = DevicePyramid(backend, h, w, c)
    pyramid.build(options, src)
    flat = np.empty(pyramid.items, np.float32)
    backend._cl.enqueue_copy(backend.queue, flat, pyramid.buffer)
    return [flat[off:off + lh * lw * c].reshape(lh, lw, c) for (off, lw, lh, _) in pyramid.table[1:]]


@pytest.mark.parametrize("dtype", kernel_cases.DTYPES)
@pytest.mark.parametrize("shape", [(37, 50, 3), (8, 1, 1), (5, 8, 4)])
def test_device_levels_equal_the_reference(backend, dtype, shape):
    image = kernel_cases.make_image(shape, dtype, seed=3)
    want = Pyramid(image).levels[1:]
    got = _levels(backend, image)
    assert [g.shape for g in got] == [w.shape for w in want]
    top = np.iinfo(dtype).max if np.dtype(dtype).kind == "u" else None
    for k, (g, w) in enumerate(zip(got, want), start=1):
        if top is not None and 4**k * top < 2**24:  # means of 4**k integers: exact in float32
            np.testing.assert_array_equal(g, w)
        else:
            np.testing.assert_allclose(g, w, rtol=1e-6, atol=1e-7)


def test_a_batch_equals_the_loop_bit_for_bit(opencl_backend):
    stack = np.stack([kernel_cases.make_image((120, 160, 3), np.uint8, seed=s) for s in range(3)])
    maps = [SHRINK_8, MIXED, RLinear(1 / 3, 0, 1j)]
    got = fpiwarp.warp_batch(stack, maps, (24, 40), antialias=True, backend=opencl_backend, **KW)
    for i, m in enumerate(maps):
        want = fpiwarp.warp_image(stack[i], m, (24, 40), antialias=True, backend=opencl_backend, **KW)
        np.testing.assert_array_equal(got[i], want)


def test_a_prepared_job_builds_its_pyramid_once(backend, monkeypatch):
    from fpiwarp.backends.opencl.pyramid import DevicePyramid

    image = kernel_cases.make_image((120, 160, 3), np.float32, seed=5)
    builds = []
    real = DevicePyramid.build
    monkeypatch.setattr(DevicePyramid, "build", lambda self, *a, **k: builds.append(1) or real(self, *a, **k))
    job = backend.prepare_warp(image, (24, 40), antialias=True, **KW)
    for m in (SHRINK_8, MIXED, SHRINK_8):
        job.set_map(m)
        job.launch()
        got = job.read().copy()
        want = fpiwarp.warp_image(image, m, (24, 40), antialias=True, backend="numpy", **KW)
        kernel_cases.assert_images_agree(got, want, np.float32)
    assert len(builds) == 1


def test_a_footprint_past_the_estimate_gets_its_levels(backend, monkeypatch):
    from fpiwarp.backends.opencl import prepared

    image = kernel_cases.make_image((120, 160, 3), np.uint8, seed=7)
    want = backend.warp_image(image, MIXED, (24, 40), antialias=True, **KW)
    backend.host_pyramids.clear()  # else the first call's levels are kept
    monkeypatch.setattr(prepared, "levels_needed", lambda *a: 0)  # an estimate that misses every level
    got = backend.warp_image(image, MIXED, (24, 40), antialias=True, **KW)
    np.testing.assert_array_equal(got, want)
    assert prepared.levels_needed is not None


def test_a_complete_kept_pyramid_needs_no_estimate_nor_flag(backend, monkeypatch):
    """Once the kept pyramid has every level, a call neither estimates the
    levels nor reads the kernel's flag (no footprint reads past the top),
    and gives the picture of a fresh pyramid."""
    from fpiwarp.backends.opencl import prepared
    from fpiwarp.backends.opencl.pyramid import DevicePyramid

    image = kernel_cases.make_image((120, 160, 3), np.uint8, seed=5)
    backend.host_pyramids.clear()
    want = backend.warp_image(image, MIXED, (24, 40), antialias=True, **KW)
    backend.warp_image(image, RLinear(1e-4, 0, 0), (24, 40), antialias=True, **KW)  # builds to the top
    (pyramid,) = backend.host_pyramids.values()
    assert pyramid.complete

    def refused(*args):
        raise AssertionError("called for a complete pyramid")

    monkeypatch.setattr(prepared, "levels_needed", refused)
    monkeypatch.setattr(DevicePyramid, "needs_more", refused)
    monkeypatch.setattr(DevicePyramid, "read_need", refused)
    for _ in range(2):
        np.testing.assert_array_equal(backend.warp_image(image, MIXED, (24, 40), antialias=True, **KW), want)


def test_calls_and_bound_maps_reuse_the_kept_device_pyramid(backend, monkeypatch):
    """warp_image calls and bound maps over one host image read one device
    pyramid: a call needing more levels than the kept pyramid has builds
    only those, and every picture is that of a freshly built pyramid."""
    from fpiwarp.backends.opencl import prepared

    image = kernel_cases.make_image((120, 160, 3), np.uint8, seed=12)
    mild, strong = RLinear(0.5, 0, 0.3j), SHRINK_8  # levels 0..1 and 0..3 or more
    fresh = {}
    for m in (mild, strong):
        backend.host_pyramids.clear()
        fresh[m] = backend.warp_image(image, m, (24, 40), antialias=True, **KW)
    backend.host_pyramids.clear()
    builds = backend.host_pyramids.builds
    estimates = []
    real = prepared.levels_needed
    monkeypatch.setattr(prepared, "levels_needed", lambda *a: estimates.append(real(*a)) or estimates[-1])
    np.testing.assert_array_equal(backend.warp_image(image, mild, (24, 40), antialias=True, **KW), fresh[mild])
    (pyramid,) = backend.host_pyramids.values()
    assert pyramid.built == estimates[0] < pyramid.top
    bound = backend.bind(strong)
    np.testing.assert_array_equal(bound.warp_image(image.copy(), (24, 40), antialias=True, **KW), fresh[strong])
    assert backend.host_pyramids.values() == [pyramid] and pyramid.built == estimates[1] > estimates[0]
    np.testing.assert_array_equal(backend.warp_image(image, mild, (24, 40), antialias=True, **KW), fresh[mild])
    assert backend.host_pyramids.builds == builds + 1


def test_the_estimate_covers_uniform_shrinks():
    from fpiwarp.backends.opencl.pyramid import levels_needed

    assert levels_needed(RLinear(1.0, 0, 0), (30, 40), 8) == 0  # identity: no level
    assert levels_needed(RLinear(8.0, 0, 0), (30, 40), 8) == 2  # 8 px footprints (10 with the margin): level 2
    assert levels_needed(RLinear(14.0, 0, 0), (30, 40), 8) == 3  # 17.5 px with the margin: level 3
    assert levels_needed(RLinear(1e6, 0, 0), (30, 40), 8) == 8  # clamped to the top


@pytest.mark.parametrize("dtype", kernel_cases.DTYPES)
def test_magnification_is_the_plain_warp_bit_for_bit(opencl_backend, dtype):
    image = kernel_cases.make_image((48, 64, 3), dtype, seed=2)
    grow = RLinear(1.7 + 0.2j, 0.1, 3 + 2j)
    for order in kernel_cases.ORDERS:
        plain = fpiwarp.warp_image(image, grow, (60, 80), order=order, mode="wrap", backend=opencl_backend)
        smooth = fpiwarp.warp_image(image, grow, (60, 80), order=order, mode="wrap", antialias=True,
                                    backend=opencl_backend)
        np.testing.assert_array_equal(smooth, plain)


def test_device_arrays_rebuild_their_pyramid_after_a_change(opencl_backend):
    from pyopencl import array as cla

    from fpiwarp.arrays import opencl_queue

    image = kernel_cases.make_image((120, 160, 3), np.uint8, seed=9)
    arr = cla.to_device(opencl_queue(), image)
    first = fpiwarp.warp_image(arr, SHRINK_8, (24, 40), antialias=True, **KW).get()
    np.testing.assert_array_equal(first, fpiwarp.warp_image(image, SHRINK_8, (24, 40), antialias=True,
                                                             backend=opencl_backend, **KW))
    arr.fill(np.uint8(17))  # in place, on the device
    again = fpiwarp.warp_image(arr, SHRINK_8, (24, 40), antialias=True, **KW).get()
    inside = again[4:-4, 4:-4]
    np.testing.assert_array_equal(inside, np.full_like(inside, 17))
