"""Warp arrays (and DLPack arrays viewed as Warp arrays) on Warp's CPU
device: warped in place by the warp backend, no host copies, out=."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.array_cases import DTYPES, FPI, fails, make_image

import fpiwarp
from fpiwarp.backends import get_backend
from fpiwarp.backends.nvwarp import backend as wb


@pytest.fixture
def wp(warp_backend):
    return wb.warp_module()


@pytest.fixture
def dev(warp_backend):
    """The warp backend's device ("cpu" here, cuda:0 on a GPU machine):
    arrays made there are warped by the kernel their numpy reference ran."""
    return str(get_backend("warp").device)


def forbid_host_copies(monkeypatch):
    """From here on, the warp backend's uploads and readbacks fail."""
    monkeypatch.setattr(wb.Backend, "_to_device", fails)
    monkeypatch.setattr(wb.DeviceWarp, "read", fails)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("shape", [(24, 32), (24, 32, 1), (24, 32, 3), (24, 32, 4)])
def test_warp_arrays_equal_the_numpy_path(wp, dev, rng, monkeypatch, dtype, shape):
    img = make_image(rng, shape, dtype)
    kw = {"output_shape": (20, 40), "order": 3, "mode": "reflect", "cval": 0.5}
    ref = fpiwarp.warp_image(img, FPI, backend="warp", **kw)
    arr = wp.array(img, device=dev)
    forbid_host_copies(monkeypatch)
    res = fpiwarp.warp_image(arr, FPI, **kw)
    assert isinstance(res, wp.array) and str(res.device) == dev and res.shape == ref.shape
    np.testing.assert_array_equal(res.numpy(), ref)


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_channels_first_is_a_strided_view(wp, dev, rng, monkeypatch, channels):
    img = make_image(rng, (channels, 24, 32), np.uint8)
    ref = fpiwarp.warp_image(np.ascontiguousarray(np.moveaxis(img, 0, 2)), FPI, backend="warp", order=0)
    arr = wp.array(img, device=dev)
    out = wp.empty((channels, 24, 32), dtype=wp.uint8, device=dev)
    forbid_host_copies(monkeypatch)
    res = fpiwarp.warp_image(arr, FPI, order=0, channels="first", out=out)
    assert res is out
    np.testing.assert_array_equal(np.moveaxis(out.numpy(), 0, 2), ref)


def test_out_is_written_in_place(wp, dev, rng, monkeypatch):
    img = make_image(rng, (24, 32, 3), np.float32)
    ref = fpiwarp.warp_image(img, FPI, backend="warp", output_shape=(30, 20))
    arr = wp.array(img, device=dev)
    out = wp.zeros((30, 20, 3), dtype=wp.float32, device=dev)
    ptr = out.ptr
    forbid_host_copies(monkeypatch)
    res = fpiwarp.warp_image(arr, FPI, output_shape=(30, 20), out=out)
    assert res is out and res.ptr == ptr
    np.testing.assert_array_equal(out.numpy(), ref)


def test_numpy_out_on_the_warp_backend_is_written_by_the_kernel(wp, rng, monkeypatch):
    img = make_image(rng, (24, 32, 2), np.uint16)
    ref = fpiwarp.warp_image(img, FPI, backend="warp")
    out = np.zeros_like(img)
    forbid_host_copies(monkeypatch)
    monkeypatch.setattr(np, "copyto", fails)
    res = fpiwarp.warp_image(img, FPI, backend="warp", out=out)
    assert res is out and np.array_equal(out, ref)


@pytest.mark.parametrize("make_out, error, message", [
    (lambda wp: wp.empty((24, 33, 3), dtype=wp.uint8, device="cpu"), fpiwarp.ArgumentError, "out= must be"),
    (lambda wp: wp.empty((24, 32, 3), dtype=wp.float32, device="cpu"), fpiwarp.ArgumentError, "out= must be"),
    (lambda wp: None, fpiwarp.ArgumentError, "shares memory"),
])
def test_out_errors(wp, rng, make_out, error, message):
    img = make_image(rng, (24, 32, 3), np.uint8)
    arr = wp.array(img, device="cpu")
    out = make_out(wp)
    with pytest.raises(error, match=message):
        fpiwarp.warp_image(arr, FPI, out=arr if out is None else out)
    np.testing.assert_array_equal(arr.numpy(), img)


def test_warp_arrays_on_host_backends_and_mismatches(wp, rng):
    img = make_image(rng, (24, 32, 3), np.uint8)
    arr = wp.array(img, device="cpu")
    res = fpiwarp.warp_image(arr, FPI, backend="numpy")  # CPU memory: a numpy view runs there
    assert isinstance(res, wp.array)
    np.testing.assert_array_equal(res.numpy(), fpiwarp.warp_image(img, FPI))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_map_points_on_warp_arrays(wp, dev, rng, monkeypatch, dtype):
    pts = (rng.random((7, 3, 2)) * 60 - 5).astype(dtype)
    arr = wp.array(pts, device=dev)
    out = wp.zeros(pts.shape, dtype=wp.dtype_from_numpy(np.dtype(dtype)), device=dev)
    monkeypatch.setattr(wb.Backend, "_to_device", fails)
    res = fpiwarp.map_points(FPI, arr, out=out)
    assert res is out
    np.testing.assert_allclose(out.numpy(), FPI(pts.astype(np.float64)), rtol=1e-5, atol=1e-4)
    with pytest.raises(fpiwarp.ArgumentError, match="shares memory"):
        fpiwarp.map_points(FPI, arr, out=arr)


def test_numpy_dlpack_capsules_are_viewed_in_place(wp, rng):
    """An array that only speaks DLPack (here numpy's own, wrapped) is read
    through wp.from_dlpack: the kernel sees the caller's memory."""
    img = make_image(rng, (16, 20, 3), np.uint8)

    class OnlyDLPack:
        def __dlpack__(self, **kw):
            return img.__dlpack__(**kw)

        def __dlpack_device__(self):
            return img.__dlpack_device__()

    view = wb.warp_module().from_dlpack(OnlyDLPack())
    assert view.ptr == img.ctypes.data  # zero copy
    res = fpiwarp.warp_image(OnlyDLPack(), FPI)
    cpu_ref = fpiwarp.warp_image(wp.array(img, device="cpu"), FPI).numpy()  # the CPU device's kernel, as here
    np.testing.assert_array_equal(np.asarray(res), cpu_ref)


def test_warper_takes_warp_arrays(wp, dev, rng):
    from fpiwarp.warping import Warper

    img = make_image(rng, (16, 20, 3), np.uint8)
    res = Warper(FPI, backend="warp", order=0)(wp.array(img, device=dev))
    assert isinstance(res, wp.array)
    np.testing.assert_array_equal(res.numpy(), fpiwarp.warp_image(img, FPI, backend="warp", order=0))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(h=st.integers(1, 12), w=st.integers(1, 12), c=st.integers(0, 4), dtype=st.sampled_from(DTYPES),
       order=st.sampled_from([0, 1, 3]), mode=st.sampled_from(["constant", "edge", "reflect", "wrap"]),
       first=st.booleans(), out_h=st.integers(1, 12), out_w=st.integers(1, 12), seed=st.integers(0, 2**16))
def test_any_warp_array_equals_its_numpy_warp(wp, dev, h, w, c, dtype, order, mode, first, out_h, out_w, seed):
    """Whatever the shape, layout and sampling, the in-place device path
    gives what the warp backend gives on the same numpy image."""
    shape = (h, w) if c == 0 else (h, w, c)
    img = make_image(np.random.default_rng(seed), shape, dtype)
    kw = {"output_shape": (out_h, out_w), "order": order, "mode": mode, "cval": 0.5}
    ref = fpiwarp.warp_image(img, FPI, backend="warp", **kw)
    if first and c:
        res = fpiwarp.warp_image(wp.array(np.ascontiguousarray(np.moveaxis(img, 2, 0)), device=dev), FPI,
                                 channels="first", **kw).numpy()
        res = np.moveaxis(res, 0, 2)
    else:
        res = fpiwarp.warp_image(wp.array(img, device=dev), FPI, **kw).numpy()
    np.testing.assert_array_equal(res, ref)


def test_antialiased_warp_arrays(wp, dev, rng):
    shrink = fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 3], [30, -2], [33, 25], [-3, 22]])
    img = make_image(rng, (48, 64, 3), np.float32)
    res = fpiwarp.warp_image(wp.array(img, device=dev), shrink, antialias=True)
    np.testing.assert_array_equal(res.numpy(), fpiwarp.warp_image(img, shrink, backend="warp", antialias=True))


@pytest.mark.parametrize("name", ["mobius", "compound", "tps", "tps_inverse", "tps_pairs"])
def test_every_kind_of_map_on_warp_arrays(wp, dev, rng, name):
    """The device path hands the kernels the same block as the numpy path
    (its inverse computed once per call) for every kind of map."""
    from support.kernel_cases import MAPS

    transform = MAPS[name]()
    img = make_image(rng, (48, 64, 3), np.uint8)
    ref = fpiwarp.warp_image(img, transform, backend="warp")
    res = fpiwarp.warp_image(wp.array(img, device=dev), transform)
    np.testing.assert_array_equal(res.numpy(), ref)
