"""warp_image and map_points for every kind of array: the backend chosen
from where the data lives, the result of the input's kind, ``out=`` and
the channel layout. numpy in, numpy out stays the path of
:mod:`fpiwarp.warping`; everything else comes here.
"""

import numpy as np

from ..backends import backend_capabilities, check_backend_name
from ..block import pack
from ..errors import ArgumentError, DeviceMismatchError
from ..validation import (
    check_backend_call,
    check_cval,
    check_image,
    check_map_size,
    check_output_shape,
    check_warp_options,
)
from . import convert
from .kinds import array_info, choose_backend
from .outputs import check_host_out, copy_points_out, overlap_error

CHANNELS = ("last", "first")
HOST_BACKENDS = ("numpy", "opencl", "gl")


def check_channels(channels):
    """``channels`` if it is "last" or "first", else ArgumentError."""
    if channels not in CHANNELS:
        raise ArgumentError(f"channels must be 'last' (H, W, C) or 'first' (C, H, W), got {channels!r}")
    return channels


def hwc_shape(shape, channels):
    """(H, W, C) and whether the image was 2-D, from a shape as given."""
    if len(shape) == 3 and channels == "first":
        c, h, w = shape
        return (h, w, c), False
    if len(shape) == 2:
        return (*shape, 1), True
    return tuple(shape), False


def output_layout(output_shape, c, squeeze, channels):
    """The output's shape in the caller's layout."""
    oh, ow = output_shape
    if squeeze:
        return (oh, ow)
    return (c, oh, ow) if channels == "first" else (oh, ow, c)


class InverseBlock:
    """A map's inverse as the kernels read it, its stages computed once per
    call (``transform.inverse.stages()`` costs ~0.1 ms for an FPI; the size
    check and the upload would each compute it)."""

    def __init__(self, stages):
        self._stages, self._block = stages, None

    def stages(self):
        return self._stages

    def params(self):
        if self._block is None:
            self._block = pack(self._stages)
        return self._block


class Inverted:
    """What device paths hand a backend: ``.inverse`` is an :class:`InverseBlock`."""

    def __init__(self, transform):
        self.inverse = InverseBlock(transform.inverse.stages())


def check_device_warp(shape, dtype, transform, output_shape, order, mode, cval, backend, backend_options, antialias,
                      name="image"):
    """:func:`fpiwarp.validation.check_warp_arguments` for an image known by
    (H, W, C) ``shape`` and ``dtype`` only: nothing is read or copied.
    Returns (output_shape, order, mode, cval, options, the map as an
    :class:`Inverted` for the backend); errors name the argument ``name``."""
    caps = backend_capabilities(backend)
    order, mode = check_warp_options(transform, order, mode)
    proxy, _ = check_image(np.broadcast_to(np.zeros((), dtype), shape), name=name)
    cval = check_cval(cval, shape[2], proxy.dtype)
    out_shape = check_output_shape(output_shape, proxy)
    options = check_backend_call(shape, out_shape, proxy.dtype, order, mode, caps, backend, backend_options, antialias)
    inverted = Inverted(transform)
    check_map_size(inverted.inverse, caps, backend)
    return out_shape, order, mode, cval, options, inverted


def mismatch(info, backend):
    """The DeviceMismatchError for an array the backend cannot read in place."""
    hint = {"opencl": "use backend='opencl' (or None), or .get() it into numpy",
            "texture": "use backend='gl' (or None), or .read() it into numpy"}.get(
        info.kind, f"use backend='warp' (or None) for {info.device} arrays, or copy it to the host")
    return DeviceMismatchError(f"the {backend} backend cannot read a {info.library} array on {info.device} in "
                               f"place; {hint}")


def warp_image(image, transform, output_shape, *, order, mode, cval, backend, backend_options, antialias, out,
               channels, host_warp):
    """See :func:`fpiwarp.warp_image`; ``host_warp`` is its numpy path."""
    check_channels(channels)
    info = array_info(image)
    name = check_backend_name(choose_backend(info, backend))
    if out is not None and array_info(out).library in ("jax", "jaxlib"):
        raise ArgumentError("out= cannot be a JAX array (JAX arrays are immutable); leave out=None")
    if info.kind in ("numpy", "host") and not (name == "warp" and out is not None and _warp_on_cpu()):
        return _host(image, info, transform, output_shape, order, mode, cval, name, backend_options, antialias,
                     out, channels, host_warp)
    if info.kind == "opencl" and name == "opencl":
        return _opencl(image, transform, output_shape, order, mode, cval, backend_options, antialias, out, channels)
    if info.kind == "texture" and name == "gl":
        if channels != "last" or out is not None and array_info(out).kind != "texture":
            raise ArgumentError("a texture is warped into a texture of its channels: leave channels='last' and "
                                "give a moderngl.Texture as out=")
        return _texture(image, transform, output_shape, order, mode, cval, backend_options, antialias, out)
    if info.kind in ("warp", "dlpack", "cuda_array_interface", "numpy", "host") and name == "warp":
        return _warp(image, info, transform, output_shape, order, mode, cval, backend_options, antialias, out,
                     channels)
    if info.kind in ("warp", "dlpack") and info.on_host and name in HOST_BACKENDS:
        result = _host(convert.host_view(image, info), array_info(np.empty(0)), transform, output_shape, order, mode,
                       cval, name, backend_options, antialias, None if out is None else convert.host_view(
                           out, array_info(out)), channels, host_warp)
        return out if out is not None else convert.from_host(result, info)
    raise mismatch(info, name)


def _warp_on_cpu():
    """Whether the registry's warp backend runs on the CPU (numpy memory is its own)."""
    from ..backends import get_backend  # noqa: PLC0415

    return get_backend("warp").device.is_cpu


def _host(image, info, transform, output_shape, order, mode, cval, name, backend_options, antialias, out, channels,
          host_warp):
    img = np.asarray(image)
    first = channels == "first" and img.ndim == 3
    if out is not None:
        check_host_out(out, img, "the image")
    result = host_warp(np.moveaxis(img, 0, 2) if first else img, transform, output_shape, order=order, mode=mode,
                       cval=cval, backend=name, backend_options=backend_options, antialias=antialias)
    if first:
        result = np.moveaxis(result, 2, 0)
    if out is None:
        return np.ascontiguousarray(result) if first else result
    if out.shape != result.shape or out.dtype != result.dtype:
        raise ArgumentError(f"out= must be {result.shape} {result.dtype}, got {out.shape} {out.dtype}")
    np.copyto(out, result)
    return out


def _warp(image, info, transform, output_shape, order, mode, cval, backend_options, antialias, out, channels):
    from ..backends.nvwarp import arrays as warp_path  # noqa: PLC0415

    backend, src, dtype, given = warp_path.image_source(image, info, channels)
    shape, squeeze = hwc_shape(given, channels)
    oshape, order, mode, cval, options, inverted = check_device_warp(
        shape, dtype, transform, output_shape, order, mode, cval, "warp", backend_options, antialias)
    layout = output_layout(oshape, shape[2], squeeze, channels)
    result, target = warp_path.output_target(backend, info, dtype, layout, out)
    if warp_path.overlaps(src, target):
        raise overlap_error("the image")
    wp = warp_path.warp_module()
    backend.warp_into(src, inverted, oshape, warp_path.as_hwc(wp, target, channels), order=order, mode=mode,
                      cval=cval, **options)
    warp_path.settle(backend, out)
    return result


def _opencl(image, transform, output_shape, order, mode, cval, backend_options, antialias, out, channels):
    from ..backends.opencl import arrays as opencl_path  # noqa: PLC0415

    with opencl_path.lock:  # the kept source and output arrays
        return _opencl_locked(image, transform, output_shape, order, mode, cval, backend_options, antialias, out,
                              channels)


def _opencl_locked(image, transform, output_shape, order, mode, cval, backend_options, antialias, out, channels):
    from ..backends.opencl import arrays as opencl_path  # noqa: PLC0415

    be, src, dtype, given = opencl_path.image_source(image, channels)
    shape, squeeze = hwc_shape(given, channels)
    oshape, order, mode, cval, options, inverted = check_device_warp(
        shape, dtype, transform, output_shape, order, mode, cval, "opencl", backend_options, antialias)
    layout = output_layout(oshape, shape[2], squeeze, channels)
    result, target = opencl_path.output_target(be, dtype, layout, out)
    if opencl_path.shares_buffer(image, target):
        raise overlap_error("the image")
    c = shape[2]
    if channels == "first" and not squeeze:  # (rows, cols, C) on the device, then permuted into the result
        written = opencl_path.kept(be, "written", (*oshape, c), dtype)
        be.warp_into(src, inverted, oshape, written, order=order, mode=mode, cval=cval, **options)
        opencl_path.permute(be, written, "to_first", dst=target)
    else:
        be.warp_into(src, inverted, oshape, target.reshape(*oshape, c), order=order, mode=mode, cval=cval,
                     **options)
    return opencl_path.finish_output(be, result)


def _texture(image, transform, output_shape, order, mode, cval, backend_options, antialias, out):
    from ..backends.gl import arrays as gl_path  # noqa: PLC0415

    dtype, shape = gl_path.texture_format(image)
    oshape, order, mode, cval, options, inverted = check_device_warp(
        shape, dtype, transform, output_shape, order, mode, cval, "gl", backend_options, antialias)
    if options.get("hardware_filter"):
        raise ArgumentError("hardware_filter is not available for textures warped in place")
    return gl_path.warp_texture(image, inverted, oshape, out, order=order, mode=mode, cval=cval,
                                antialias=bool(options.get("antialias")))


def map_points(transform, points, backend, out, host_map):
    """See :func:`fpiwarp.map_points`; ``host_map`` is its numpy path."""
    info = array_info(points)
    name = check_backend_name(choose_backend(info, backend))
    if info.kind in ("numpy", "host"):
        return copy_points_out(host_map(transform, points, backend=name), out, np.asarray(points))
    if info.kind == "opencl" and name == "opencl":
        from ..backends.opencl import arrays as opencl_path  # noqa: PLC0415

        return opencl_path.map_points(transform, points, out)
    if info.kind in ("warp", "dlpack", "cuda_array_interface") and name == "warp":
        from ..backends.nvwarp import arrays as warp_path  # noqa: PLC0415

        return warp_path.map_points(transform, points, info, out)
    if info.kind in ("warp", "dlpack") and info.on_host and name in HOST_BACKENDS:
        result = host_map(transform, convert.host_view(points, info), backend=name)
        return convert.from_host(result, info)
    raise mismatch(info, name)
