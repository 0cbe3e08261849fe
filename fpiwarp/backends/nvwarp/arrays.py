"""warp_image and map_points on Warp's device arrays, without host copies.

Warp arrays are used as they are; DLPack arrays (torch, CuPy, JAX, numpy)
and ``__cuda_array_interface__`` ones are viewed as Warp arrays
(``wp.from_dlpack``, ``wp.array(copy=False)``) on their device, "cpu" or
"cuda:N", and the kernels of :mod:`fpiwarp.backends.nvwarp.backend` read
and write them in place. Warp's kernels index arrays through their
strides, so (C, H, W) arrays are warped through a transposed view: no
layout is copied.
"""

import threading

import numpy as np

from ...arrays import convert
from ...arrays.kinds import array_info
from ...arrays.outputs import overlap_error
from ...errors import ArgumentError, ArgumentTypeError, DeviceMismatchError

_lock = threading.Lock()
_backends = {}  # Warp device name -> Backend for devices other than the default one
_module = []  # warp, once initialized


def warp_module():
    """Warp, imported and initialized quietly by the warp backend (once:
    initializing probes the CUDA driver, ~0.1 ms a call)."""
    if not _module:
        from . import backend as warp_backend  # noqa: PLC0415 - optional dependency

        _module.append(warp_backend.warp_module())
    return _module[0]


def backend_on(device: str):
    """The warp backend for Warp device ``device`` ("cpu", "cuda:0", ...):
    the registry's when it runs there, else one made for it, once."""
    from .. import get_backend
    from . import backend as warp_backend  # noqa: PLC0415

    default = get_backend("warp")
    if str(default.device) == device:
        return default
    with _lock:
        if device not in _backends:
            try:
                _backends[device] = warp_backend.Backend(device=device)
            except ValueError as exc:
                raise DeviceMismatchError(f"the warp backend cannot run on {device}: {exc}") from None
        return _backends[device]


def numpy_dtype(wp, arr):
    """The numpy dtype of a Warp array of scalars, else ArgumentTypeError."""
    try:
        return np.dtype(wp.dtype_to_numpy(arr.dtype))
    except (TypeError, KeyError):
        raise ArgumentTypeError(f"image must be an array of scalars, got Warp dtype {arr.dtype}") from None


def as_hwc(wp, arr, channels):
    """An (H, W, C) view of an (H, W), (H, W, C) or, channels first, (C, H, W)
    Warp array; a 2-D array gains a channel axis of stride one element."""
    if arr.ndim == 2:
        item = wp.types.type_size_in_bytes(arr.dtype)
        return wp.array(ptr=arr.ptr, dtype=arr.dtype, shape=(*arr.shape, 1), strides=(*arr.strides, item),
                        device=arr.device)
    if arr.ndim == 3 and channels == "first":
        return arr.transpose((1, 2, 0))
    return arr


def image_source(image, info, channels):
    """(backend, the image as an (H, W, C) Warp view, its numpy dtype, its shape
    as given) for an image of kind warp, dlpack or cuda_array_interface."""
    wp = warp_module()
    arr = convert.to_warp(wp, image, info)
    if arr.ndim not in (2, 3):
        raise ArgumentError(f"image must be 2-D or 3-D, got shape {tuple(arr.shape)}")
    backend = backend_on("cpu" if arr.device.is_cpu else str(arr.device.alias))
    return backend, as_hwc(wp, arr, channels), numpy_dtype(wp, arr), tuple(arr.shape)


def _span(arr):
    """[first, last) bytes an array's elements may touch."""
    wp = warp_module()
    item = wp.types.type_size_in_bytes(arr.dtype)
    extent = sum((n - 1) * abs(s) for n, s in zip(arr.shape, arr.strides)) + item
    return arr.ptr, arr.ptr + extent


def overlaps(a, b):
    """Whether two Warp arrays on one device may share memory."""
    (a0, a1), (b0, b1) = _span(a), _span(b)
    return a.device == b.device and a0 < b1 and b0 < a1


def output_target(backend, src_info, dtype, shape, out):
    """(what to return, the (rows, cols, C) Warp view the kernel writes): a
    new array in the caller's library, or ``out`` checked."""
    wp = warp_module()
    if out is None:
        arr = wp.empty(shape, dtype=wp.dtype_from_numpy(dtype), device=backend.device)
        return convert.from_warp(arr, src_info), arr
    info = array_info(out)
    if info.library in ("jax", "jaxlib"):
        raise ArgumentError("out= cannot be a JAX array (JAX arrays are immutable); leave out=None")
    if info.kind not in ("warp", "dlpack", "cuda_array_interface", "numpy"):
        raise DeviceMismatchError(f"out= is a {info.kind} array; the warp backend writes Warp, DLPack or CUDA "
                                  "arrays on its device")
    arr = convert.to_warp(wp, out, info)
    if arr.device != backend.device:
        raise DeviceMismatchError(f"out= is on {arr.device}, the image on {backend.device}: allocate out on the "
                                  "image's device")
    if tuple(arr.shape) != tuple(shape) or numpy_dtype(wp, arr) != dtype:
        raise ArgumentError(f"out= must be {tuple(shape)} {dtype}, got {tuple(arr.shape)} "
                            f"{numpy_dtype(wp, arr)}")
    return out, arr


def settle(backend, out):
    """Wait for the kernel on CUDA when it wrote a caller's ``out`` of another
    library: that library reads it on its own stream, which DLPack's stream
    handshake does not order here (a new result is ordered by it when the
    library imports it)."""
    if out is not None and not backend.device.is_cpu and array_info(out).kind != "warp":
        warp_module().synchronize_device(backend.device)


def map_points(transform, points, info, out):
    """Map an (..., 2) float64 or float32 device array; returns an array of
    the caller's library (or ``out``) of the same shape and dtype. float32
    points are widened on the device (the kernel reads float64 points)."""
    wp = warp_module()
    arr = convert.to_warp(wp, points, info)
    dtype = numpy_dtype(wp, arr) if arr.ndim >= 1 else None
    if arr.ndim < 1 or arr.shape[-1] != 2 or dtype not in (np.float32, np.float64) or not arr.is_contiguous:
        raise ArgumentError("device points for map_points must be a contiguous float32 or float64 (..., 2) array, "
                            f"got {tuple(arr.shape)} {wp.types.type_repr(arr.dtype)}")
    backend = backend_on("cpu" if arr.device.is_cpu else str(arr.device.alias))
    count = int(np.prod(arr.shape[:-1]))
    result, target = output_target(backend, info, dtype, tuple(arr.shape), out)
    if overlaps(arr, target):
        raise overlap_error("points")
    if not target.is_contiguous:
        raise ArgumentError("out= must be contiguous for map_points")
    if dtype == np.float64:
        flat = wp.array(ptr=arr.ptr, dtype=wp.vec2d, shape=(count,), device=arr.device)
        dst = wp.array(ptr=target.ptr, dtype=wp.vec2d, shape=(count,), device=target.device)
        backend.map_points_into(transform, flat, dst)
        settle(backend, out)
        return result
    from fpiwarp.kernels.nvwarp import points as warp_kernels  # noqa: PLC0415 - compiled on first float32 points

    flat = wp.empty(count, dtype=wp.vec2d, device=arr.device)
    pairs = (wp.array(ptr=p.ptr, dtype=wp.float32, shape=(count, 2), device=p.device) for p in (arr, target))
    src2, dst2 = pairs
    if count:
        wp.launch(warp_kernels.widen_points, dim=count, inputs=[src2, flat], device=arr.device)
    backend.map_points_into(transform, flat, flat)
    if count:
        wp.launch(warp_kernels.narrow_points, dim=count, inputs=[flat, dst2], device=arr.device)
    settle(backend, out)
    return result
