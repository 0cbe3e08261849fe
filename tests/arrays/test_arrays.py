"""Device arrays (fpiwarp.arrays): recognition, backend choice from the
data, out= and channels on the host path, mismatch errors, JAX (CPU)."""

import numpy as np
import pytest
from support.array_cases import FPI, FakeCudaArray, fails, make_image, require_library

import fpiwarp
from fpiwarp.arrays import array_info


def test_kinds_and_default_backends():
    assert array_info(np.zeros(3)).default_backend == "numpy"
    assert array_info([[1.0, 2.0]]).kind == "host"
    info = array_info(FakeCudaArray())
    assert (info.kind, info.device, info.default_backend) == ("dlpack", "cuda:0", "warp")
    assert not info.on_host


def test_numpy_default_is_unchanged(rng):
    img = make_image(rng, (20, 30, 3), np.uint8)
    a = fpiwarp.warp_image(img, FPI)
    b = fpiwarp.warp_image(img, FPI, backend="numpy")
    assert type(a) is np.ndarray and np.array_equal(a, b)
    pts = rng.random((5, 2)) * 40
    assert np.array_equal(fpiwarp.map_points(FPI, pts), fpiwarp.map_points(FPI, pts, backend="numpy"))
    with pytest.raises(fpiwarp.ArgumentTypeError):  # lists are still refused as images
        fpiwarp.warp_image([[1, 2]], FPI)


def test_host_out_is_written_and_returned(rng):
    img = make_image(rng, (20, 30, 2), np.float32)
    out = np.full((20, 30, 2), -1, np.float32)
    res = fpiwarp.warp_image(img, FPI, out=out)
    assert res is out and np.shares_memory(res, out)
    assert np.array_equal(out, fpiwarp.warp_image(img, FPI))
    pts_out = np.empty((4, 2))
    pts = rng.random((4, 2)) * 30
    assert fpiwarp.map_points(FPI, pts, out=pts_out) is pts_out
    assert np.array_equal(pts_out, fpiwarp.map_points(FPI, pts))


@pytest.mark.parametrize("bad, message", [
    (lambda img: np.empty((20, 31, 2), np.float32), "out= must be"),
    (lambda img: np.empty((20, 30, 2), np.uint8), "out= must be"),
    (lambda img: img, "shares memory"),
])
def test_host_out_errors(rng, bad, message):
    img = make_image(rng, (20, 30, 2), np.float32)
    keep = img.copy()
    with pytest.raises(fpiwarp.ArgumentError, match=message):
        fpiwarp.warp_image(img, FPI, out=bad(img))
    assert np.array_equal(img, keep)  # nothing overwritten


def test_channels_first_on_the_host(rng):
    img = make_image(rng, (3, 20, 30), np.uint16)
    res = fpiwarp.warp_image(img, FPI, channels="first", output_shape=(25, 35))
    ref = fpiwarp.warp_image(np.moveaxis(img, 0, 2), FPI, output_shape=(25, 35))
    assert res.shape == (3, 25, 35) and res.flags.c_contiguous
    assert np.array_equal(res, np.moveaxis(ref, 2, 0))
    with pytest.raises(fpiwarp.ArgumentError, match="channels must be"):
        fpiwarp.warp_image(img, FPI, channels="middle")


@pytest.mark.parametrize("backend", ["numpy", "opencl", "gl"])
def test_cuda_arrays_do_not_meet_host_backends(backend):
    with pytest.raises(fpiwarp.DeviceMismatchError, match="backend='warp'") as err:
        fpiwarp.warp_image(FakeCudaArray(), FPI, backend=backend)
    assert "\n" not in str(err.value)
    with pytest.raises(fpiwarp.DeviceMismatchError):
        fpiwarp.map_points(FPI, FakeCudaArray(), backend=backend)


def test_jax_cpu_arrays(rng, warp_backend):
    jnp = require_library("jax.numpy")
    from fpiwarp.backends.nvwarp import backend as warp_backend

    img = make_image(rng, (24, 32, 3), np.uint8)
    arr = jnp.asarray(img)
    wp = warp_backend.warp_module()
    assert wp.from_dlpack(arr).ptr == arr.unsafe_buffer_pointer()  # the view the warp path reads: no copy
    with pytest.MonkeyPatch.context() as patch:  # no upload, no readback on the device path
        patch.setattr(warp_backend.Backend, "_to_device", fails)
        patch.setattr(warp_backend.DeviceWarp, "read", fails)
        fpiwarp.warp_image(arr, FPI)
    for backend in (None, "numpy"):
        res = fpiwarp.warp_image(arr, FPI, backend=backend, output_shape=(20, 40))
        assert isinstance(res, type(arr))
        ref = fpiwarp.warp_image(img, FPI, backend=backend or "warp", output_shape=(20, 40))
        assert np.array_equal(np.asarray(res), ref)
    chw = jnp.asarray(np.ascontiguousarray(np.moveaxis(img, 2, 0)))
    res = fpiwarp.warp_image(chw, FPI, channels="first")
    assert res.shape == (3, 24, 32)
    assert np.array_equal(np.moveaxis(np.asarray(res), 0, 2), fpiwarp.warp_image(img, FPI, backend="warp"))
    pts = jnp.asarray((rng.random((6, 2)) * 40).astype(np.float32))
    mapped = fpiwarp.map_points(FPI, pts)
    assert isinstance(mapped, type(pts)) and mapped.dtype == pts.dtype
    np.testing.assert_allclose(np.asarray(mapped), FPI(np.asarray(pts, np.float64)), rtol=1e-5, atol=1e-4)
    with pytest.raises(fpiwarp.ArgumentError, match="immutable"):
        fpiwarp.warp_image(arr, FPI, out=jnp.zeros_like(arr))
