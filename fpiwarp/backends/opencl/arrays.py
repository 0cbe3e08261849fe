"""warp_image and map_points on ``pyopencl.array.Array`` s, on the device.

The arrays must live in the opencl backend's context (make them with the
queue :func:`opencl_queue` returns); the kernel reads the source buffer
and writes the output buffer in place. Copies made on the device, never
through the host: (C, H, W) arrays are permuted to (H, W, C) and back by
a small kernel, and a uint8/uint16 source in a buffer of under
:data:`~fpiwarp.backends.opencl.backend.IMAGE_SLACK` bytes (the sampler
reads pixels as 32-bit words; in larger images it never reads past the
last pixel) is copied into a buffer with that slack (:func:`to_opencl`
makes arrays with it).
"""

import threading

import numpy as np

from ...arrays.kinds import array_info
from ...arrays.outputs import overlap_error
from ...errors import ArgumentError, DeviceMismatchError

_CTYPES = {np.dtype(np.uint8): "uchar", np.dtype(np.uint16): "ushort", np.dtype(np.float32): "float",
           np.dtype(np.float64): "double"}
#: index of the source element read for destination element i
_permute_kernels = {}  # (context, direction, dtype) -> ElementwiseKernel
_kept = {}  # (context, role) -> array kept across calls (see kept)
#: held while a call uses the kept arrays
lock = threading.Lock()
_PERMUTE = {  # for N images of (C, H, W) <-> (H, W, C); dst[i] = src[...]
    "to_last": "dst[i] = src[((i / (C * W * H) * C + i % C) * H + i / (C * W) % H) * W + i / C % W]",
    "to_first": "dst[i] = src[((i / (W * H * C) * H + i / W % H) * W + i % W) * C + i / (W * H) % C]",
}


def backend():
    """The registry's opencl backend."""
    from .. import get_backend  # noqa: PLC0415

    return get_backend("opencl")


def opencl_queue():
    """The command queue of the opencl backend: make ``pyopencl.array``
    arrays with it (``pyopencl.array.to_device(opencl_queue(), image)``)
    to warp them in place.

    Returns
    -------
    pyopencl.CommandQueue
    """
    return backend().queue


def check_array(arr, be, what):
    """Refuse an array of another context, with an offset, or not contiguous."""
    if arr.context != be.context:
        raise DeviceMismatchError(
            f"{what} is a pyopencl array of another OpenCL context than the opencl backend's "
            f"({be.device_label}); make it with fpiwarp.arrays.opencl_queue()")
    if arr.offset or not arr.flags.c_contiguous:
        raise ArgumentError(f"{what} must be a C-contiguous pyopencl array without offset; pass {what}.copy()")


def sync_before(arr, be):
    """Let the backend's queue see ``arr``'s pending writes (another queue's)."""
    arr.finish()
    if arr.queue is not None and arr.queue != be.queue:
        arr.queue.finish()


def permute(be, arr, to, dst=None):
    """``arr`` with its axes moved (``to``: "to_last" for (C, H, W) ->
    (H, W, C), "to_first" back; an (N, ...) stack image by image), on the
    device, into ``dst`` or a new array with slack; returns it."""
    from pyopencl.elementwise import ElementwiseKernel  # noqa: PLC0415

    lead = tuple(arr.shape[:-3])
    if to == "to_last":
        c, h, w = arr.shape[-3:]
        shape = (*lead, h, w, c)
    else:
        h, w, c = arr.shape[-3:]
        shape = (*lead, c, h, w)
    out = with_slack(be, shape, arr.dtype) if dst is None else dst
    key = (be.context.int_ptr, to, arr.dtype)
    kernels = _permute_kernels
    if key not in kernels:
        t = _CTYPES[arr.dtype]
        kernels[key] = ElementwiseKernel(be.context, f"{t} *dst, const {t} *src, int H, int W, int C", _PERMUTE[to],
                                         "fpiwarp_permute")
    kernels[key](out, arr, np.int32(h), np.int32(w), np.int32(c), queue=be.queue)
    return out


def with_slack(be, shape, dtype):
    """A new array of ``shape`` on the backend's queue, its buffer
    IMAGE_SLACK bytes longer (safe as a sampled source)."""
    import pyopencl as cl  # noqa: PLC0415
    from pyopencl import array as cla  # noqa: PLC0415

    from .backend import IMAGE_SLACK  # noqa: PLC0415

    nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
    buf = cl.Buffer(be.context, cl.mem_flags.READ_WRITE, nbytes + IMAGE_SLACK)
    return cla.Array(be.queue, shape, dtype, data=buf)


def kept(be, role, shape, dtype):
    """An array with slack of ``role`` kept across calls while its shape and
    dtype hold (a new OpenCL buffer costs about a millisecond on PoCL)."""
    key = (be.context.int_ptr, role)
    arr = _kept.get(key)
    if arr is None or arr.shape != tuple(shape) or arr.dtype != dtype:
        arr = _kept[key] = with_slack(be, tuple(shape), np.dtype(dtype))
    return arr


def to_opencl(image: np.ndarray):
    """``image`` copied once to the opencl backend's device, in a buffer
    with the slack its sampler needs: warping it later copies nothing.

    Parameters
    ----------
    image : ndarray
        Any shape and dtype.

    Returns
    -------
    pyopencl.array.Array
        On the queue of :func:`opencl_queue`.
    """
    be = backend()
    arr = with_slack(be, image.shape, image.dtype)
    arr.set(np.ascontiguousarray(image), queue=be.queue)
    return arr


def image_source(image, channels):
    """(backend, the image as an (H, W, C) array the kernel can read in place,
    its dtype, its shape as given) for a pyopencl array."""
    from .backend import IMAGE_SLACK  # noqa: PLC0415

    be = backend()
    check_array(image, be, "image")
    sync_before(image, be)
    shape = tuple(image.shape)
    if image.ndim not in (2, 3):
        raise ArgumentError(f"image must be 2-D or 3-D, got shape {shape}")
    if image.ndim == 3 and channels == "first":
        c, h, w = shape
        return be, permute(be, image, "to_last", dst=kept(be, "source", (h, w, c), image.dtype)), image.dtype, shape
    src = image.reshape(*shape[:2], 1) if image.ndim == 2 else image
    pixel = src.dtype.itemsize * src.shape[2]
    if pixel < 4 and image.base_data.size < IMAGE_SLACK:  # the sampler's 32-bit word would read past the end
        padded = kept(be, "source", src.shape, src.dtype)
        copy_device(be, padded, src)
        src = padded
    return be, src, image.dtype, shape


def copy_device(be, dst, src):
    import pyopencl as cl  # noqa: PLC0415

    cl.enqueue_copy(be.queue, dst.data, src.data, byte_count=src.nbytes)


def output_target(be, dtype, shape, out):
    """(what to return, the array the kernel writes): a new array on the
    backend's queue, or ``out`` checked."""
    from pyopencl import array as cla  # noqa: PLC0415

    if out is None:
        arr = cla.empty(be.queue, shape, dtype)
        return arr, arr
    if array_info(out).kind != "opencl":
        raise DeviceMismatchError(f"out= is a {type(out).__name__}; for a pyopencl image pass a pyopencl array")
    check_array(out, be, "out")
    if tuple(out.shape) != tuple(shape) or out.dtype != dtype:
        raise ArgumentError(f"out= must be {tuple(shape)} {dtype}, got {tuple(out.shape)} {out.dtype}")
    sync_before(out, be)
    return out, out


def shares_buffer(a, b):
    """Whether two pyopencl arrays use one buffer."""
    return a.base_data.int_ptr == b.base_data.int_ptr


def finish_output(be, result):
    """``result``, after waiting for the backend's queue where ``result``
    belongs to another queue (on its own queue it is ordered already)."""
    if result.queue is not None and result.queue != be.queue:
        be.queue.finish()
    return result


def map_points(transform, points, info, out):
    """Map an (..., 2) pyopencl array of the device's point dtype in place."""
    be = backend()
    check_array(points, be, "points")
    if points.ndim < 1 or points.shape[-1] != 2 or points.dtype != be.point_dtype:
        raise ArgumentError(f"device points on this OpenCL device must be ({'...'}, 2) {be.point_dtype}, got "
                            f"{tuple(points.shape)} {points.dtype}")
    sync_before(points, be)
    result, target = output_target(be, points.dtype, tuple(points.shape), out)
    if shares_buffer(points, target):
        raise overlap_error("points")
    n = int(np.prod(points.shape[:-1]))
    be.map_points_into(transform, points.reshape(n, 2), target.reshape(n, 2))
    return finish_output(be, result)


# --- The registry's array calls of the opencl backend (its entry's ``arrays``).


def writes_host_out():
    """Whether warp_image writes a numpy ``out=`` in place: no (host calls copy into it)."""
    return False


def warp_image(image, info, transform, call):
    """warp_image on a pyopencl array (``call``: :class:`fpiwarp.arrays.dispatch.WarpCall`)."""
    with lock:  # the kept source and output arrays
        return _warp_image_locked(image, transform, call)


def _warp_image_locked(image, transform, call):
    from ...arrays.dispatch import check_device_warp, hwc_shape, output_layout  # noqa: PLC0415

    channels, out = call.channels, call.out
    be, src, dtype, given = image_source(image, channels)
    shape, squeeze = hwc_shape(given, channels)
    oshape, order, mode, cval, options, inverted = check_device_warp(shape, dtype, transform, call, "opencl")
    layout = output_layout(oshape, shape[2], squeeze, channels)
    result, target = output_target(be, dtype, layout, out)
    if shares_buffer(image, target):
        raise overlap_error("the image")
    c = shape[2]
    if channels == "first" and not squeeze:  # (rows, cols, C) on the device, then permuted into the result
        written = kept(be, "written", (*oshape, c), dtype)
        be.warp_into(src, inverted, oshape, written, order=order, mode=mode, cval=cval, **options)
        permute(be, written, "to_first", dst=target)
    else:
        be.warp_into(src, inverted, oshape, target.reshape(*oshape, c), order=order, mode=mode, cval=cval,
                     **options)
    return finish_output(be, result)


def warp_batch(images, info, transforms, call):
    """warp_batch on an (N, H, W[, C]) pyopencl stack, one launch per kind of map."""
    from ...arrays.dispatch import output_layout  # noqa: PLC0415
    from ...batch.arrays import check_maps, map_list, stack_shape  # noqa: PLC0415
    from . import batch as opencl_batch  # noqa: PLC0415

    channels, out = call.channels, call.out
    with lock:  # the kept source and output arrays
        be = backend()
        check_array(images, be, "images")
        sync_before(images, be)
        n, (h, w, c), squeeze = stack_shape(tuple(images.shape), channels)
        maps = map_list(transforms, n)
        oshape, order, mode, cval, options, inverted = check_maps(maps, (h, w, c), images.dtype, call,
                                                                   "opencl")
        result, target = output_target(be, images.dtype, (n, *output_layout(oshape, c, squeeze, channels)), out)
        if shares_buffer(images, target):
            raise overlap_error("images")
        src = _stack_source(be, images, (n, h, w, c), channels)
        first = channels == "first" and not squeeze
        written = kept(be, "batch_written", (n, *oshape, c), images.dtype) if first else target.reshape(n, *oshape, c)
        opencl_batch.warp_arrays(be, src, written, inverted, order=order, mode=mode, cval=cval, **options)
        if first:
            permute(be, written, "to_first", dst=target)
        return finish_output(be, result)


def _stack_source(be, images, shape, channels):
    """The stack as an (N, H, W, C) array the kernels read in place: the
    caller's, or a kept copy on the device (permuted from channels-first,
    or with the sampler's slack past the end)."""
    if images.ndim == 4 and channels == "first":
        return permute(be, images, "to_last", dst=kept(be, "batch_source", shape, images.dtype))
    src = images.reshape(shape)
    if shape[3] * images.dtype.itemsize < 4 and images.base_data.size < images.nbytes + be.image_slack:
        padded = kept(be, "batch_source", shape, images.dtype)
        copy_device(be, padded, src)
        return padded
    return src


def map_points_batch(transforms, points, info, out):
    """map_points_batch on an (N, ..., 2) pyopencl array of the device's point dtype."""
    from ...batch.arrays import check_point_maps  # noqa: PLC0415
    from . import batch as opencl_batch  # noqa: PLC0415

    be = backend()
    check_array(points, be, "points")
    n, p, maps = check_point_maps(transforms, tuple(points.shape), "opencl")
    if points.dtype != be.point_dtype:
        raise ArgumentError(f"device points on this OpenCL device must be (N, ..., 2) {be.point_dtype}, got "
                            f"{points.dtype}")
    sync_before(points, be)
    result, target = output_target(be, points.dtype, tuple(points.shape), out)
    if shares_buffer(points, target):
        raise overlap_error("points")
    opencl_batch.map_points_arrays(be, maps, points.reshape(n, p, 2), target.reshape(n, p, 2))
    return finish_output(be, result)
