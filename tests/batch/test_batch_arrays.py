"""Batches of device arrays (warp_batch, map_points_batch): stacks of Warp,
DLPack (JAX, numpy's own) and pyopencl arrays are warped where they live,
one launch per kind of map, into an array of their kind (or the caller's
out=), equal bit for bit to the per-image loop on the same backend, with
no host copy of the pixels. The CUDA variants are in test_arrays_cuda.py
(skipped without a GPU)."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.array_cases import FakeCudaArray, fails, forbid_host_copies, make_image, require_library
from support.batch_cases import batches, local_map, loop, make_map

import fpiwarp
from fpiwarp.backends import get_backend
from fpiwarp.backends.nvwarp import backend as wb

MAPS4 = ["fpi", "tps_inverse", "compound", "shift"]  # three kinds: fpi and shift share one


@pytest.fixture
def wp(warp_backend):
    return wb.warp_module()


@pytest.fixture
def dev(warp_backend):
    """The warp backend's device: stacks made there are compared with the
    loop on that backend (CPU here; cuda:0 on a GPU machine)."""
    return str(get_backend("warp").device)


def cpu_loop(wp, stack, maps, options):
    """The per-image loop for CPU arrays (JAX, DLPack): warp_image on CPU Warp arrays."""
    per = [maps] * len(stack) if isinstance(maps, fpiwarp.Transform) else maps
    return np.stack([fpiwarp.warp_image(wp.array(im, device="cpu"), t, **options).numpy()
                     for im, t in zip(stack, per)])


@pytest.fixture
def cla(opencl_backend):
    from pyopencl import array

    return array


def forbid_warp_host_copies(monkeypatch, wp):
    """From here on, every upload, readback or copy of the warp backend and
    of Warp arrays fails (the batch runner's host path included)."""
    from fpiwarp.backends.nvwarp import batch as warp_batches

    monkeypatch.setattr(wb.Backend, "_to_device", fails)
    monkeypatch.setattr(wb.DeviceWarp, "read", fails)
    monkeypatch.setattr(warp_batches.BatchRunner, "warp_batch", fails)
    monkeypatch.setattr(warp_batches.BatchRunner, "map_points_batch", fails)
    monkeypatch.setattr(type(wp.empty(1, device="cpu")), "numpy", fails)


def forbid_opencl_host_copies(monkeypatch, cla, limit):
    """Readbacks, Array.get and host arrays of ``limit`` bytes or more in
    enqueue_copy fail (support.array_cases' rule), and the host batch path."""

    from fpiwarp.backends.opencl import batch as opencl_batch

    forbid_host_copies(monkeypatch, cla, limit)
    monkeypatch.setattr(opencl_batch, "warp_batch", fails)
    monkeypatch.setattr(opencl_batch, "map_points_batch", fails)


def channels_first(stack):
    """(N, C, H, W) of an (N, H, W, C) stack; 3-D stacks as they are."""
    return np.ascontiguousarray(np.moveaxis(stack, 3, 1)) if stack.ndim == 4 else stack


def as_last(result, first):
    return np.moveaxis(result, 1, 3) if first and result.ndim == 4 else result


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=batches(), first=st.booleans(), give_out=st.booleans())
def test_warp_stacks_equal_the_loop_without_host_copies(wp, dev, monkeypatch, case, first, give_out):
    """Any stack, layout (channels first: a strided view), dtype, mix of
    kinds and sampling: the loop of warp_image on numpy, bit for bit."""
    stack, transforms, options = case
    expected = loop(stack, transforms, "warp", options)
    given_stack = channels_first(stack) if first else stack
    arr = wp.array(given_stack, device=dev)
    out = wp.zeros(channels_first(expected).shape if first else expected.shape, dtype=arr.dtype,
                   device=dev) if give_out else None
    ptr = None if out is None else out.ptr
    with monkeypatch.context() as patch:
        forbid_warp_host_copies(patch, wp)
        got = fpiwarp.warp_batch(arr, transforms, channels="first" if first else "last", out=out, **options)
    assert isinstance(got, wp.array) and str(got.device) == dev
    assert out is None or (got is out and got.ptr == ptr)
    np.testing.assert_array_equal(as_last(got.numpy(), first), expected)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=batches(), first=st.booleans(), give_out=st.booleans())
def test_pyopencl_stacks_equal_the_loop_without_host_copies(cla, monkeypatch, case, first, give_out):
    from fpiwarp.arrays import opencl_queue

    stack, transforms, options = case
    expected = loop(stack, transforms, "opencl", options)
    queue = opencl_queue()
    arr = cla.to_device(queue, channels_first(stack) if first else stack)  # exact buffers: slack added on device
    out = cla.zeros(queue, channels_first(expected).shape if first else expected.shape, stack.dtype) \
        if give_out else None
    with monkeypatch.context() as patch:
        forbid_opencl_host_copies(patch, cla, min(stack[0].nbytes, expected[0].nbytes))
        got = fpiwarp.warp_batch(arr, transforms, channels="first" if first else "last", out=out, **options)
    assert isinstance(got, cla.Array) and got.context == arr.context
    assert out is None or (got is out and got.data.int_ptr == out.data.int_ptr)
    np.testing.assert_array_equal(as_last(got.get(), first), expected)


def test_pyopencl_newton_warps_equal_the_host_warps(cla, rng):
    """Local deformations on pyopencl arrays take the coarse pass as host
    images do: one image and a stack, bit for bit."""
    from fpiwarp.arrays import opencl_queue

    stack = make_image(rng, (3, 40, 70, 3), np.uint8)
    maps = [local_map(k, 70, 40) for k in range(3)]
    queue = opencl_queue()
    one = fpiwarp.warp_image(cla.to_device(queue, stack[0]), maps[0])
    np.testing.assert_array_equal(one.get(), fpiwarp.warp_image(stack[0], maps[0], backend="opencl"))
    got = fpiwarp.warp_batch(cla.to_device(queue, stack), maps)
    np.testing.assert_array_equal(got.get(), loop(stack, maps, "opencl", {}))


@pytest.mark.parametrize("first", [False, True])
def test_warp_stacks_take_one_launch_per_kind(wp, dev, rng, monkeypatch, first):
    """Four maps of three kinds: three launches, contiguous stacks by row
    offsets, channels-first ones by the strided kernel (on the CPU: their
    thread-per-row variants)."""
    from fpiwarp.backends.nvwarp import batch as warp_batches

    stack = make_image(rng, (4, 12, 15, 3), np.uint8)
    maps = [make_map(kind, k, 15, 12) for k, kind in enumerate(MAPS4)]
    expected = loop(stack, maps, "warp", {"order": 1})
    be = get_backend("warp")
    runner = be.batches()
    launches, real = [], runner.launch
    monkeypatch.setattr(runner, "launch", lambda kernel, *args: launches.append(kernel) or real(kernel, *args))
    arr = wp.array(channels_first(stack) if first else stack, device=dev)
    got = fpiwarp.warp_batch(arr, maps, channels="first" if first else "last")
    np.testing.assert_array_equal(as_last(got.numpy(), first), expected)
    keys = [key for key, _, _ in warp_batches.kind_groups([m.inverse for m in maps], 4)]
    made = [be.kernels.image_kernel(be.image_spec(key, 1, 0, 3, np.uint8, strided=first)) for key in keys]
    assert launches == made and len(set(launches)) == 3
    assert all(k.key.endswith("_rows") == be.device.is_cpu for k in made)  # a thread per row on the CPU


def test_pyopencl_stacks_take_one_launch_per_kind(cla, rng, monkeypatch):
    import pyopencl as cl

    from fpiwarp.arrays import opencl_queue, to_opencl

    stack = make_image(rng, (4, 12, 15, 3), np.uint8)
    maps = [make_map(kind, k, 15, 12) for k, kind in enumerate(MAPS4)]
    expected = loop(stack, maps, "opencl", {"order": 3})
    arr = to_opencl(stack)  # with slack: read in place, no device copy
    launches, real = [], cl.enqueue_nd_range_kernel
    monkeypatch.setattr(cl, "enqueue_nd_range_kernel", lambda *a, **k: launches.append(a[2]) or real(*a, **k))
    got = fpiwarp.warp_batch(arr, maps, order=3)
    monkeypatch.undo()
    assert [len(g) for g in launches] == [3, 3, 3]  # three launches of (cols, rows, images)
    assert sorted(g[2] for g in launches) == [1, 1, 2] and got.queue == opencl_queue()
    np.testing.assert_array_equal(got.get(), expected)


def test_jax_stacks_are_read_in_place_and_come_back_as_jax(wp, rng, monkeypatch):
    jax = require_library("jax")
    jnp = jax.numpy
    stack = make_image(rng, (3, 10, 14, 4), np.float32)
    maps = [make_map(kind, k, 14, 10) for k, kind in enumerate(["fpi", "tps", "fpi"])]
    expected = cpu_loop(wp, stack, maps, {"order": 0, "mode": "edge"})
    arr = jnp.asarray(stack)
    seen = []
    real = wb.Backend.warp_batch_into
    monkeypatch.setattr(wb.Backend, "warp_batch_into", lambda self, src, *a, **k: seen.append(src.ptr) or
                        real(self, src, *a, **k))
    got = fpiwarp.warp_batch(arr, maps, order=0, mode="edge")
    assert seen == [arr.unsafe_buffer_pointer()]  # the kernels read the JAX buffer itself
    assert isinstance(got, jax.Array) and got.devices() == arr.devices()
    np.testing.assert_array_equal(np.asarray(got), expected)
    with pytest.raises(fpiwarp.ArgumentError, match="out= cannot be a JAX array"):
        fpiwarp.warp_batch(arr, maps, out=jnp.zeros_like(arr))


def test_numpy_dlpack_stacks_and_host_backends(wp, rng, monkeypatch):
    """A CPU array that only speaks DLPack (numpy's own, wrapped) runs on
    "warp" in place (its library has no from_dlpack: the result is a Warp
    array); a CPU Warp stack runs on a named host backend through a numpy
    view and comes back as a Warp array."""
    stack = make_image(rng, (2, 9, 11, 3), np.uint16)
    maps = [make_map("fpi", 0, 11, 9), make_map("tps", 1, 11, 9)]

    class OnlyDLPack:
        def __init__(self, a):
            self.a = a

        def __dlpack__(self, **kw):
            return self.a.__dlpack__(**kw)

        def __dlpack_device__(self):
            return self.a.__dlpack_device__()

    seen = []
    real = wb.Backend.warp_batch_into
    monkeypatch.setattr(wb.Backend, "warp_batch_into", lambda self, src, *a, **k: seen.append(src.ptr) or
                        real(self, src, *a, **k))
    got = fpiwarp.warp_batch(OnlyDLPack(stack), maps)
    monkeypatch.undo()
    assert seen == [stack.ctypes.data] and isinstance(got, wp.array)
    np.testing.assert_array_equal(got.numpy(), cpu_loop(wp, stack, maps, {}))
    for name in ("numpy", "opencl"):
        np.testing.assert_array_equal(fpiwarp.warp_batch(wp.array(stack, device="cpu"), maps, backend=name).numpy(),
                                      loop(stack, maps, name, {}))


def test_numpy_stacks_with_out_and_channels_first(rng):
    stack = make_image(rng, (3, 3, 8, 9), np.uint8)  # (N, C, H, W)
    maps = fpiwarp.RLinear(1, 0, 1j)
    expected = np.moveaxis(loop(np.moveaxis(stack, 1, 3), maps, "numpy", {}), 3, 1)
    out = np.zeros_like(stack)
    assert fpiwarp.warp_batch(stack, maps, channels="first", out=out) is out
    np.testing.assert_array_equal(out, expected)
    with pytest.raises(fpiwarp.ArgumentError, match="out= shares memory with images"):
        fpiwarp.warp_batch(stack, maps, out=stack)
    with pytest.raises(fpiwarp.DeviceMismatchError, match="out= is a list; a numpy input is written into a numpy"):
        fpiwarp.warp_batch(stack, maps, out=[0])  # as warp_image says it
    with pytest.raises(fpiwarp.DeviceMismatchError, match="out= is a list; a numpy input is written into a numpy"):
        fpiwarp.warp_image(stack[0], maps, channels="first", out=[0])
    with pytest.raises(fpiwarp.ArgumentError, match=r"out= must be \(3, 3, 8, 9\) uint8"):
        fpiwarp.warp_batch(stack, maps, channels="first", out=np.zeros((3, 8, 9, 3), np.uint8))


def test_stack_errors_name_the_argument(wp, dev, cla, rng):
    from fpiwarp.arrays import opencl_queue

    stack = make_image(rng, (2, 6, 7, 3), np.uint8)
    warp_stack = wp.array(stack, device=dev)
    cl_stack = cla.to_device(opencl_queue(), stack)
    shift = fpiwarp.RLinear(1, 0, 1)
    with pytest.raises(fpiwarp.DeviceMismatchError, match="the opencl backend cannot read a .* on cuda:0"):
        fpiwarp.warp_batch(FakeCudaArray(), shift, backend="opencl")
    with pytest.raises(fpiwarp.DeviceMismatchError, match="the warp backend cannot read a pyopencl"):
        fpiwarp.warp_batch(cl_stack, shift, backend="warp")
    with pytest.raises(fpiwarp.DeviceMismatchError, match="out= is a ndarray"):
        fpiwarp.warp_batch(cl_stack, shift, out=np.zeros_like(stack))
    with pytest.raises(fpiwarp.DeviceMismatchError, match="out= is a opencl array"):
        fpiwarp.warp_batch(warp_stack, shift, out=cl_stack)
    with pytest.raises(fpiwarp.ArgumentError, match=r"out= must be \(2, 6, 7, 3\) uint8, got \(2, 6, 7, 4\)"):
        fpiwarp.warp_batch(warp_stack, shift, out=wp.zeros((2, 6, 7, 4), dtype=wp.uint8, device=dev))
    with pytest.raises(fpiwarp.ArgumentError, match="out= must be"):
        fpiwarp.warp_batch(cl_stack, shift, out=cla.zeros(opencl_queue(), (2, 6, 7, 3), np.float32))
    with pytest.raises(fpiwarp.ArgumentError, match="out= shares memory with images"):
        fpiwarp.warp_batch(warp_stack, shift, out=warp_stack)
    with pytest.raises(fpiwarp.ArgumentError, match="out= shares memory with images"):
        fpiwarp.warp_batch(cl_stack, shift, out=cl_stack)
    with pytest.raises(fpiwarp.ArgumentError, match="got 3 maps in transforms for 2 images"):
        fpiwarp.warp_batch(warp_stack, [shift] * 3)
    with pytest.raises(fpiwarp.ArgumentError, match="images must be a non-empty"):
        fpiwarp.warp_batch(wp.array(stack[0, 0], device=dev), shift)
    with pytest.raises(fpiwarp.ArgumentError, match="images must be a non-empty"):
        fpiwarp.warp_batch(cla.to_device(opencl_queue(), stack[:0]), shift)
    with pytest.raises(fpiwarp.ArgumentError, match="channels must be 'last'"):
        fpiwarp.warp_batch(warp_stack, shift, channels="middle")
    with pytest.raises(fpiwarp.ArgumentTypeError, match="images dtype must be uint8, uint16 or float32, got float64"):
        fpiwarp.warp_batch(wp.zeros((2, 4, 4), dtype=wp.float64, device=dev), shift)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("one", [False, True])
def test_warp_point_batches_in_place(wp, dev, rng, monkeypatch, dtype, one):
    pts = rng.uniform(-3, 20, size=(4, 5, 3, 2)).astype(dtype)
    maps = [make_map(kind, k, 15, 12) for k, kind in enumerate(MAPS4)]
    transforms = maps[1] if one else maps
    chosen = [transforms] * 4 if one else maps
    expected = np.stack([fpiwarp.map_points(t, wp.array(p, device=dev)).numpy() for t, p in zip(chosen, pts)])
    arr = wp.array(pts, device=dev)
    out = wp.zeros_like(arr)
    runner = get_backend("warp").batches()
    launches, real = [], runner.launch
    monkeypatch.setattr(runner, "launch", lambda kernel, *args: launches.append(kernel) or real(kernel, *args))
    with monkeypatch.context() as patch:
        forbid_warp_host_copies(patch, wp)
        got = fpiwarp.map_points_batch(transforms, arr, out=out)
    assert got is out and len(launches) == 1
    np.testing.assert_array_equal(got.numpy(), expected)
    np.testing.assert_array_equal(fpiwarp.map_points_batch(transforms, arr).numpy(), expected)


def test_pyopencl_point_batches_in_place(cla, rng, monkeypatch):
    from fpiwarp.arrays import opencl_queue

    be = get_backend("opencl")
    pts = rng.uniform(-3, 20, size=(4, 6, 2)).astype(be.point_dtype)
    maps = [make_map(kind, k, 15, 12) for k, kind in enumerate(MAPS4)]
    expected = np.stack([fpiwarp.map_points(t, p, backend="opencl") for t, p in zip(maps, pts)])
    arr = cla.to_device(opencl_queue(), pts)
    out = cla.zeros_like(arr)
    with monkeypatch.context() as patch:
        forbid_opencl_host_copies(patch, cla, pts[0].nbytes)
        got = fpiwarp.map_points_batch(maps, arr, out=out)
    assert got is out
    np.testing.assert_array_equal(got.get(), expected.astype(be.point_dtype))
    with pytest.raises(fpiwarp.ArgumentError, match="got 2 maps in transforms for 4 point sets"):
        fpiwarp.map_points_batch(maps[:2], arr)
    with pytest.raises(fpiwarp.ArgumentError, match="points must have shape"):
        fpiwarp.map_points_batch(maps[0], cla.to_device(opencl_queue(), pts[..., :1].copy()))


def test_jax_point_batches(wp, rng):
    jax = require_library("jax")
    pts = rng.uniform(-3, 20, size=(3, 7, 2)).astype(np.float32)
    maps = [make_map(kind, k, 15, 12) for k, kind in enumerate(["fpi", "tps_inverse", "shift"])]
    expected = np.stack([np.asarray(fpiwarp.map_points(t, jax.numpy.asarray(p))) for t, p in zip(maps, pts)])
    got = fpiwarp.map_points_batch(maps, jax.numpy.asarray(pts))
    assert isinstance(got, jax.Array) and got.dtype == np.float32
    np.testing.assert_array_equal(np.asarray(got), expected)
    with pytest.raises(fpiwarp.DeviceMismatchError, match="the numpy backend cannot read"):
        fpiwarp.map_points_batch(maps[0], FakeCudaArray(), backend="numpy")
