"""pyopencl arrays on the opencl backend (PoCL here): the kernel reads
and writes the device buffers in place, the result is a pyopencl array."""

import numpy as np
import pytest
from support.array_cases import DTYPES, FPI, fails, forbid_host_copies, make_image

import fpiwarp
from fpiwarp.arrays import opencl_queue


@pytest.fixture
def cla(opencl_backend):
    from pyopencl import array

    return array


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("shape", [(24, 32), (24, 32, 3), (24, 32, 4)])
def test_pyopencl_arrays_equal_the_numpy_path(cla, rng, monkeypatch, dtype, shape):
    img = make_image(rng, shape, dtype)
    kw = {"output_shape": (20, 40), "order": 1, "mode": "wrap"}
    ref = fpiwarp.warp_image(img, FPI, backend="opencl", **kw)
    arr = cla.to_device(opencl_queue(), img)  # an exact buffer, read in place (no slack needed)
    forbid_host_copies(monkeypatch, cla, min(img.nbytes, ref.nbytes))
    res = fpiwarp.warp_image(arr, FPI, **kw)
    assert isinstance(res, cla.Array) and res.context == arr.context and res.shape == ref.shape
    monkeypatch.undo()
    np.testing.assert_array_equal(res.get(), ref)


def test_out_and_channels_first(cla, rng, monkeypatch):
    img = make_image(rng, (3, 24, 32), np.uint8)
    ref = fpiwarp.warp_image(np.ascontiguousarray(np.moveaxis(img, 0, 2)), FPI, backend="opencl", order=3)
    queue = opencl_queue()
    arr = cla.to_device(queue, img)
    out = cla.zeros(queue, (3, 24, 32), np.uint8)
    ptr = out.data.int_ptr
    forbid_host_copies(monkeypatch, cla, img.nbytes)
    res = fpiwarp.warp_image(arr, FPI, order=3, channels="first", out=out)
    assert res is out and res.data.int_ptr == ptr
    monkeypatch.undo()
    np.testing.assert_array_equal(np.moveaxis(out.get(), 0, 2), ref)


def test_out_errors_and_other_contexts(cla, rng):
    import pyopencl as cl

    img = make_image(rng, (24, 32, 3), np.float32)
    queue = opencl_queue()
    arr = cla.to_device(queue, img)
    with pytest.raises(fpiwarp.ArgumentError, match="shares memory"):
        fpiwarp.warp_image(arr, FPI, out=arr)
    with pytest.raises(fpiwarp.ArgumentError, match="out= must be"):
        fpiwarp.warp_image(arr, FPI, out=cla.empty(queue, (24, 32, 3), np.uint8))
    with pytest.raises(fpiwarp.DeviceMismatchError, match="pyopencl array"):
        fpiwarp.warp_image(arr, FPI, out=np.empty((24, 32, 3), np.float32))
    with pytest.raises(fpiwarp.DeviceMismatchError, match="backend='opencl'"):
        fpiwarp.warp_image(arr, FPI, backend="warp")
    other = cl.CommandQueue(cl.Context([queue.device]))
    with pytest.raises(fpiwarp.DeviceMismatchError, match="opencl_queue"):
        fpiwarp.warp_image(cla.to_device(other, img), FPI)
    with pytest.raises(fpiwarp.ArgumentError, match="C-contiguous"):
        fpiwarp.warp_image(arr[:, ::2], FPI)
    np.testing.assert_array_equal(arr.get(), img)


def test_map_points_on_pyopencl_arrays(cla, rng):
    from fpiwarp.backends import get_backend

    dtype = get_backend("opencl").point_dtype
    pts = (rng.random((5, 4, 2)) * 60 - 5).astype(dtype)
    queue = opencl_queue()
    arr = cla.to_device(queue, pts)
    out = cla.empty(queue, pts.shape, dtype)
    res = fpiwarp.map_points(FPI, arr, out=out)
    assert res is out
    np.testing.assert_allclose(out.get(), FPI(pts.astype(np.float64)), rtol=1e-5, atol=1e-4)
    with pytest.raises(fpiwarp.ArgumentError, match="device points"):
        fpiwarp.map_points(FPI, cla.to_device(queue, pts.astype(np.float16)))


def test_to_opencl_arrays_are_read_in_place(cla, rng, monkeypatch):
    from fpiwarp.arrays import to_opencl
    from fpiwarp.backends.opencl import arrays as opencl_path

    img = make_image(rng, (24, 32, 3), np.uint8)  # 3-byte pixels: read as 32-bit words
    ref = fpiwarp.warp_image(img, FPI, backend="opencl")
    arr = to_opencl(img)
    monkeypatch.setattr(opencl_path, "kept", fails)  # no device copy of the source either
    res = fpiwarp.warp_image(arr, FPI)
    monkeypatch.undo()
    np.testing.assert_array_equal(res.get(), ref)


@pytest.mark.parametrize("shape", [(1, 1), (1, 1, 3), (1, 2), (3, 5, 3), (7, 9, 2)])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_exact_buffers_are_read_in_place_unless_under_a_word(cla, rng, monkeypatch, dtype, shape):
    """A uint8/uint16 source in an exact buffer is read in place (the
    sampler never reads past its last byte); only one of under 4 bytes
    (IMAGE_SLACK) is copied to a buffer with slack. Same output either way."""
    from fpiwarp.backends.opencl import arrays as opencl_path

    img = make_image(rng, shape, dtype)
    kw = {"output_shape": (6, 7), "order": 1, "mode": "edge"}
    ref = fpiwarp.warp_image(img, FPI, backend="opencl", **kw)
    copies = []
    monkeypatch.setattr(opencl_path, "copy_device", lambda be, dst, src: copies.append(src) or
                        cla.Array.set(dst, src.get(), queue=be.queue))
    res = fpiwarp.warp_image(cla.to_device(opencl_queue(), img), FPI, **kw)
    assert len(copies) == (img.nbytes < 4)
    np.testing.assert_array_equal(res.get(), ref)
