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


# --- The registry's array calls of the warp backend (its entry's ``arrays``).


def writes_host_out():
    """Whether warp_image writes a numpy ``out=`` in place: where the backend
    runs on the CPU, numpy memory is its own device's."""
    from .. import get_backend  # noqa: PLC0415

    return get_backend("warp").device.is_cpu


def warp_image(image, info, transform, call):
    """warp_image on a Warp, DLPack or CUDA array (or numpy with a numpy
    ``out=`` on the CPU), in place (``call``: :class:`fpiwarp.arrays.dispatch.WarpCall`)."""
    from ...arrays.dispatch import check_device_warp, hwc_shape, output_layout  # noqa: PLC0415

    channels, out = call.channels, call.out
    backend, src, dtype, given = image_source(image, info, channels)
    shape, squeeze = hwc_shape(given, channels)
    oshape, order, mode, cval, options, inverted = check_device_warp(shape, dtype, transform, call, "warp")
    layout = output_layout(oshape, shape[2], squeeze, channels)
    result, target = output_target(backend, info, dtype, layout, out)
    if overlaps(src, target):
        raise overlap_error("the image")
    wp = warp_module()
    backend.warp_into(src, inverted, oshape, as_hwc(wp, target, channels), order=order, mode=mode, cval=cval,
                      **options)
    settle(backend, out)
    return result


def as_nhwc(wp, arr, channels):
    """An (N, H, W, C) view of an (N, H, W), (N, H, W, C) or, channels
    first, (N, C, H, W) Warp array (no copy)."""
    if arr.ndim == 3:
        item = wp.types.type_size_in_bytes(arr.dtype)
        return wp.array(ptr=arr.ptr, dtype=arr.dtype, shape=(*arr.shape, 1), strides=(*arr.strides, item),
                        device=arr.device)
    if channels == "first":
        return arr.transpose((0, 2, 3, 1))
    return arr


def warp_batch(images, info, transforms, call):
    """warp_batch on a Warp, DLPack or CUDA stack, in one launch."""
    from ...arrays.dispatch import output_layout  # noqa: PLC0415
    from ...batch.arrays import check_maps, map_list, stack_shape  # noqa: PLC0415

    channels, out = call.channels, call.out
    wp = warp_module()
    arr = convert.to_warp(wp, images, info)
    n, hwc, squeeze = stack_shape(tuple(arr.shape), channels)
    dtype = numpy_dtype(wp, arr)
    maps = map_list(transforms, n)
    oshape, order, mode, cval, options, inverted = check_maps(maps, hwc, dtype, call, "warp")
    backend = backend_on("cpu" if arr.device.is_cpu else str(arr.device.alias))
    layout = (n, *output_layout(oshape, hwc[2], squeeze, channels))
    result, target = output_target(backend, info, dtype, layout, out)
    if overlaps(arr, target):
        raise overlap_error("images")
    backend.warp_batch_into(as_nhwc(wp, arr, channels), inverted, oshape, as_nhwc(wp, target, channels),
                            order=order, mode=mode, cval=cval, **options)
    settle(backend, out)
    return result


def map_points_batch(transforms, points, info, out):
    """map_points_batch on a Warp, DLPack or CUDA array of (N, ..., 2) float32 or float64 points."""
    from fpiwarp.kernels.nvwarp import points as warp_kernels  # noqa: PLC0415

    from ...batch.arrays import check_point_maps  # noqa: PLC0415

    wp = warp_module()
    arr = convert.to_warp(wp, points, info)
    dtype = numpy_dtype(wp, arr)
    n, p, maps = check_point_maps(transforms, tuple(arr.shape), "warp")
    if dtype not in (np.float32, np.float64) or not arr.is_contiguous:
        raise ArgumentError(f"device points must be a contiguous float32 or float64 (N, ..., 2) array, got "
                            f"{wp.types.type_repr(arr.dtype)}{'' if arr.is_contiguous else ' (not contiguous)'}")
    backend = backend_on("cpu" if arr.device.is_cpu else str(arr.device.alias))
    result, target = output_target(backend, info, dtype, tuple(arr.shape), out)
    if overlaps(arr, target):
        raise overlap_error("points")
    if not target.is_contiguous:
        raise ArgumentError("out= must be contiguous for map_points_batch")
    if dtype == np.float64:
        src, dst = (wp.array(ptr=a.ptr, dtype=wp.vec2d, shape=(n, p), device=a.device) for a in (arr, target))
        backend.map_points_batch_into(maps, src, dst)
    elif n * p:  # float32 widened on the device, mapped, narrowed back
        flat = wp.empty((n, p), dtype=wp.vec2d, device=arr.device)
        src, dst = (wp.array(ptr=a.ptr, dtype=wp.float32, shape=(n * p, 2), device=a.device) for a in (arr, target))
        wide = wp.array(ptr=flat.ptr, dtype=wp.vec2d, shape=(n * p,), device=flat.device)
        wp.launch(warp_kernels.widen_points, dim=n * p, inputs=[src, wide], device=arr.device)
        backend.map_points_batch_into(maps, flat, flat)
        wp.launch(warp_kernels.narrow_points, dim=n * p, inputs=[wide, dst], device=arr.device)
    settle(backend, out)
    return result
