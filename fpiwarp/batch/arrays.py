"""warp_batch and map_points_batch for every kind of array.

A stack (N, H, W[, C]) or, with ``channels="first"``, (N, C, H, W) (a
torch batch) is warped where it lives, as :func:`fpiwarp.warp_image`
warps one image (:mod:`fpiwarp.arrays.dispatch`): Warp, DLPack and CUDA
arrays on the "warp" backend (channels-first as a transposed view: no
copy), ``pyopencl.array.Array`` s on "opencl" (channels-first permuted on
the device), one launch per kind of map either way, into a new array of
the input's library on its device or into the caller's ``out=``. numpy
stacks keep :func:`fpiwarp.warp_batch`'s host path (``host_batch``).
"""

import numpy as np

from ..arrays import convert
from ..arrays.dispatch import (
    HOST_BACKENDS,
    Inverted,
    check_channels,
    check_device_warp,
    hwc_shape,
    mismatch,
    output_layout,
)
from ..arrays.kinds import array_info, choose_backend
from ..arrays.outputs import check_host_out, copy_points_out, overlap_error
from ..backends import backend_capabilities, check_backend_name
from ..block.many import is_many_maps
from ..errors import ArgumentError, ArgumentTypeError
from ..maps.transform import Transform
from ..validation import check_map_size, check_transform

DEVICE_KINDS = ("warp", "dlpack", "cuda_array_interface")


def map_list(transforms, n, what="images"):
    """The maps as a list of 1 or ``n``, else ArgumentError naming ``transforms``."""
    if isinstance(transforms, Transform):
        return [transforms]
    maps = transforms if is_many_maps(transforms) else list(transforms)
    if len(maps) != n:
        raise ArgumentError(f"got {len(maps)} maps in transforms for {n} {what}; give one map or one per image")
    return maps


def stack_shape(shape, channels):
    """(N, (H, W, C), whether 2-D images) of a stack's shape as given."""
    if len(shape) not in (3, 4) or shape[0] == 0:
        raise ArgumentError(f"images must be a non-empty (N, H, W), (N, H, W, C) or, channels='first', (N, C, H, W) "
                            f"array, got shape {tuple(shape)}")
    hwc, squeeze = hwc_shape(tuple(shape[1:]), channels)
    return shape[0], hwc, squeeze


def check_maps(maps, hwc, dtype, output_shape, order, mode, cval, backend, antialias):
    """Everything checked as warp_image checks it for each image (nothing
    is read; what does not depend on the map once): (output shape, order,
    mode, cval, options, the maps as the backend reads them)."""
    *first, inverted = check_device_warp(hwc, dtype, maps[0], output_shape, order, mode, cval, backend, None,
                                         antialias, "images")
    if is_many_maps(maps):  # an FPIStack: FPIs of one stage, checked when built; its blocks packed in one pass
        return (*first, maps)
    caps = backend_capabilities(backend)
    rest = []
    for t in maps[1:]:
        check_transform(t, "transforms")
        rest.append(Inverted(t))
        check_map_size(rest[-1].inverse, caps, backend)
    return (*first, [inverted, *rest])


def warp_batch(images, transforms, output_shape, *, order, mode, cval, backend, antialias, out, channels, host_batch):
    """See :func:`fpiwarp.warp_batch`; ``host_batch`` is its numpy path."""
    check_channels(channels)
    info = array_info(images)
    name = check_backend_name(choose_backend(info, backend))
    if out is not None and array_info(out).library in ("jax", "jaxlib"):
        raise ArgumentError("out= cannot be a JAX array (JAX arrays are immutable); leave out=None")
    args = (transforms, output_shape, order, mode, cval, antialias, out, channels)
    if info.kind in ("numpy", "host"):
        return _host(np.asarray(images), name, *args, host_batch)
    if info.kind == "opencl" and name == "opencl":
        return _opencl(images, *args)
    if info.kind in DEVICE_KINDS and name == "warp":
        return _warp(images, info, *args)
    if info.kind in ("warp", "dlpack") and info.on_host and name in HOST_BACKENDS:
        host_out = None if out is None else convert.host_view(out, array_info(out))
        result = _host(convert.host_view(images, info), name, *args[:6], host_out, channels, host_batch)
        return out if out is not None else convert.from_host(result, info)
    if info.kind == "texture":
        raise ArgumentTypeError("warp_batch takes stacks, not textures: warp textures one by one with warp_image")
    raise mismatch(info, name)


def _host(stack, name, transforms, output_shape, order, mode, cval, antialias, out, channels, host_batch):
    first = channels == "first" and stack.ndim == 4
    if out is not None:
        check_host_out(out, stack, "images")
    result = host_batch(np.moveaxis(stack, 1, 3) if first else stack, transforms, output_shape, order=order,
                        mode=mode, cval=cval, backend=name, antialias=antialias)
    if first:
        result = np.moveaxis(result, 3, 1)
    if out is None:
        return np.ascontiguousarray(result)
    if out.shape != result.shape or out.dtype != result.dtype:
        raise ArgumentError(f"out= must be {result.shape} {result.dtype}, got {out.shape} {out.dtype}")
    np.copyto(out, result)
    return out


def _warp(images, info, transforms, output_shape, order, mode, cval, antialias, out, channels):
    from ..backends.nvwarp import arrays as warp_path  # noqa: PLC0415

    wp = warp_path.warp_module()
    arr = convert.to_warp(wp, images, info)
    n, hwc, squeeze = stack_shape(tuple(arr.shape), channels)
    dtype = warp_path.numpy_dtype(wp, arr)
    maps = map_list(transforms, n)
    oshape, order, mode, cval, options, inverted = check_maps(maps, hwc, dtype, output_shape, order, mode, cval,
                                                               "warp", antialias)
    backend = warp_path.backend_on("cpu" if arr.device.is_cpu else str(arr.device.alias))
    layout = (n, *output_layout(oshape, hwc[2], squeeze, channels))
    result, target = warp_path.output_target(backend, info, dtype, layout, out)
    if warp_path.overlaps(arr, target):
        raise overlap_error("images")
    backend.warp_batch_into(as_nhwc(wp, arr, channels), inverted, oshape, as_nhwc(wp, target, channels),
                            order=order, mode=mode, cval=cval, **options)
    warp_path.settle(backend, out)
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


def _opencl(images, transforms, output_shape, order, mode, cval, antialias, out, channels):
    from ..backends.opencl import arrays as opencl_path  # noqa: PLC0415
    from ..backends.opencl import batch as opencl_batch  # noqa: PLC0415

    with opencl_path.lock:  # the kept source and output arrays
        be = opencl_path.backend()
        opencl_path.check_array(images, be, "images")
        opencl_path.sync_before(images, be)
        n, (h, w, c), squeeze = stack_shape(tuple(images.shape), channels)
        maps = map_list(transforms, n)
        oshape, order, mode, cval, options, inverted = check_maps(maps, (h, w, c), images.dtype, output_shape, order,
                                                                   mode, cval, "opencl", antialias)
        result, target = opencl_path.output_target(be, images.dtype, (n, *output_layout(oshape, c, squeeze,
                                                                                         channels)), out)
        if opencl_path.shares_buffer(images, target):
            raise overlap_error("images")
        src = _opencl_source(opencl_path, be, images, (n, h, w, c), channels)
        first = channels == "first" and not squeeze
        written = opencl_path.kept(be, "batch_written", (n, *oshape, c), images.dtype) if first else \
            target.reshape(n, *oshape, c)
        opencl_batch.warp_arrays(be, src, written, inverted, order=order, mode=mode, cval=cval, **options)
        if first:
            opencl_path.permute(be, written, "to_first", dst=target)
        return opencl_path.finish_output(be, result)


def _opencl_source(opencl_path, be, images, shape, channels):
    """The stack as an (N, H, W, C) array the kernels read in place: the
    caller's, or a kept copy on the device (permuted from channels-first,
    or with the sampler's slack past the end)."""
    if images.ndim == 4 and channels == "first":
        return opencl_path.permute(be, images, "to_last", dst=opencl_path.kept(be, "batch_source", shape,
                                                                              images.dtype))
    src = images.reshape(shape)
    if shape[3] * images.dtype.itemsize < 4 and images.base_data.size < images.nbytes + be.image_slack:
        padded = opencl_path.kept(be, "batch_source", shape, images.dtype)
        opencl_path.copy_device(be, padded, src)
        return padded
    return src


def map_points_batch(transforms, points, backend, out, host_batch):
    """See :func:`fpiwarp.map_points_batch`; ``host_batch`` is its numpy path."""
    info = array_info(points)
    name = check_backend_name(choose_backend(info, backend))
    if out is not None and array_info(out).library in ("jax", "jaxlib"):
        raise ArgumentError("out= cannot be a JAX array (JAX arrays are immutable); leave out=None")
    if info.kind in ("numpy", "host"):
        return _host_points(transforms, np.asarray(points), name, out, host_batch)
    if info.kind in ("warp", "dlpack") and info.on_host and name in HOST_BACKENDS:
        result = host_batch(transforms, convert.host_view(points, info), backend=name)
        return convert.from_host(result, info)
    if info.kind == "opencl" and name == "opencl":
        return _opencl_points(transforms, points, out)
    if info.kind in DEVICE_KINDS and name == "warp":
        return _warp_points(transforms, points, info, out)
    raise mismatch(info, name)


def _host_points(transforms, points, name, out, host_batch):
    return copy_points_out(host_batch(transforms, points, backend=name), out, points)


def check_point_maps(transforms, shape, backend):
    """(N, P, the maps) of a device batch of points of ``shape``, each map
    checked as map_points checks it."""
    from ..validation import check_point_count  # noqa: PLC0415

    if len(shape) < 2 or shape[-1] != 2:
        raise ArgumentError(f"points must have shape (N, ..., 2), got {tuple(shape)}")
    n, p = shape[0], int(np.prod(shape[1:-1]))
    maps = map_list(transforms, n, "point sets")
    caps = backend_capabilities(backend)
    check_point_count(np.broadcast_to(np.zeros(()), (p, 2)), caps, backend)
    for t in maps:
        check_map_size(check_transform(t, "transforms"), caps, backend)
    return n, p, maps


def _warp_points(transforms, points, info, out):
    from fpiwarp.kernels.nvwarp import points as warp_kernels

    from ..backends.nvwarp import arrays as warp_path  # noqa: PLC0415

    wp = warp_path.warp_module()
    arr = convert.to_warp(wp, points, info)
    dtype = warp_path.numpy_dtype(wp, arr)
    n, p, maps = check_point_maps(transforms, tuple(arr.shape), "warp")
    if dtype not in (np.float32, np.float64) or not arr.is_contiguous:
        raise ArgumentError(f"device points must be a contiguous float32 or float64 (N, ..., 2) array, got "
                            f"{wp.types.type_repr(arr.dtype)}{'' if arr.is_contiguous else ' (not contiguous)'}")
    backend = warp_path.backend_on("cpu" if arr.device.is_cpu else str(arr.device.alias))
    result, target = warp_path.output_target(backend, info, dtype, tuple(arr.shape), out)
    if warp_path.overlaps(arr, target):
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
    warp_path.settle(backend, out)
    return result


def _opencl_points(transforms, points, out):
    from ..backends.opencl import arrays as opencl_path  # noqa: PLC0415
    from ..backends.opencl import batch as opencl_batch  # noqa: PLC0415

    be = opencl_path.backend()
    opencl_path.check_array(points, be, "points")
    n, p, maps = check_point_maps(transforms, tuple(points.shape), "opencl")
    if points.dtype != be.point_dtype:
        raise ArgumentError(f"device points on this OpenCL device must be (N, ..., 2) {be.point_dtype}, got "
                            f"{points.dtype}")
    opencl_path.sync_before(points, be)
    result, target = opencl_path.output_target(be, points.dtype, tuple(points.shape), out)
    if opencl_path.shares_buffer(points, target):
        raise overlap_error("points")
    opencl_batch.map_points_arrays(be, maps, points.reshape(n, p, 2), target.reshape(n, p, 2))
    return opencl_path.finish_output(be, result)
