"""Label images: integer and boolean dtypes warped at order 0, values kept exactly.

A label image (a segmentation mask, an instance map) is warped by copying
for each output pixel the value of one source pixel: interpolating labels
would invent values between them. The samplers of every backend take
uint8, uint16 and float32; a label of another dtype is warped by viewing
its bytes as uint8 or uint16 channels (a bool or 1-byte integer as one
uint8 channel, a 2-, 4- or 8-byte integer as 1, 2 or 4 uint16 channels),
warping that carrier at order 0, which copies each channel's value of the
chosen source pixel, and viewing the result back. All channels of a pixel
come from the same source pixel, so the bytes of a label stay together
and the result holds only labels of the input and ``cval``.

This is the one place where that happens: :func:`fpiwarp.warp_image` and
:func:`fpiwarp.warp_batch` hand every label image here, for every backend
and every kind of array (numpy; Warp, DLPack and CUDA arrays through
Warp views; ``pyopencl.array.Array`` s through views of their buffer).

Label dtypes: bool and every integer dtype of 1, 2, 4 or 8 bytes except
uint8 and uint16 (those are images, interpolated at any order; warp them
at ``order=0`` to keep their values). A label image holds at most four
carrier channels (int32: two label channels, int64: one).
"""

import sys

import numpy as np

from ..errors import ArgumentError, ArgumentTypeError
from ..validation import check_order, check_output_shape
from .kinds import array_info

#: dtypes that are images (interpolated), never labels.
IMAGE_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))
#: Most carrier channels the samplers hold.
MAX_CARRIER_CHANNELS = 4
_TORCH_NAMES = ("bool", "int8", "int16", "int32", "int64", "uint32", "uint64")


def label_dtype(obj):
    """The numpy dtype of ``obj`` when it is a label image (bool, or an
    integer dtype other than uint8 and uint16), else None. Reads only
    ``obj.dtype`` (numpy, torch, CuPy, Warp, pyopencl alike)."""
    dt = getattr(obj, "dtype", None)
    if dt is None:
        return None
    if not isinstance(dt, np.dtype):
        dt = _foreign_dtype(dt)
        if dt is None:
            return None
    if dt.kind == "b" or (dt.kind in "iu" and dt not in IMAGE_DTYPES and dt.itemsize in (1, 2, 4, 8)):
        return dt
    return None


def _foreign_dtype(dt):
    name = str(dt)
    if name.startswith("torch."):
        name = name[len("torch."):]
        return np.dtype(name) if name in _TORCH_NAMES else None
    wp = sys.modules.get("warp")
    if wp is not None and isinstance(dt, type):
        try:
            return np.dtype(wp.dtype_to_numpy(dt))
        except (TypeError, KeyError):
            return None
    try:
        return np.dtype(dt)
    except TypeError:
        return None


def carrier_of(dtype):
    """(carrier dtype, carrier channels per label channel) of a label dtype."""
    return (np.dtype(np.uint8), 1) if dtype.itemsize == 1 else (np.dtype(np.uint16), dtype.itemsize // 2)


def check_label_options(dtype, order, antialias, cval, channels, name):
    """The carrier's cval (float64, one per carrier channel) of a label
    warp of ``channels`` label channels, after refusing what would mix labels."""
    order = check_order(order)
    if order != 0:
        raise ArgumentError(f"{name} is a {dtype} label image: it warps at order 0 only (interpolating labels "
                            f"would invent values between them), got order={order}")
    if antialias is not False and not (isinstance(antialias, np.bool_) and not antialias):
        raise ArgumentError(f"{name} is a {dtype} label image: antialias=True would average labels; leave it False")
    carrier, k = carrier_of(dtype)
    if channels * k > MAX_CARRIER_CHANNELS:
        most = MAX_CARRIER_CHANNELS // k
        raise ArgumentError(f"{name} is a {dtype} label image of {channels} channels; {dtype} labels warp with at "
                            f"most {most} channel{'s' if most > 1 else ''} (warp the channels separately)")
    return _carrier_cval(cval, dtype, channels, carrier, name)


def _carrier_cval(cval, dtype, channels, carrier, name):
    problem = (f"cval of the {dtype} label {name} must be one value of its dtype or one per channel "
               f"({channels}), got {cval!r}")
    try:
        raw = np.asarray(cval)
    except (TypeError, ValueError):
        raise ArgumentError(problem) from None
    if raw.ndim > 1 or (raw.ndim == 1 and raw.shape[0] != channels) or raw.dtype.kind not in "biuf":
        raise ArgumentError(problem)
    if dtype.kind == "b":
        if not np.all((raw == 0) | (raw == 1)):
            raise ArgumentError(f"cval of the bool label {name} must be False or True (0 or 1), got {cval!r}")
        values = raw.astype(dtype)
    else:
        info = np.iinfo(dtype)
        if raw.dtype.kind == "f" and not np.all(np.isfinite(raw) & (raw == np.round(raw))):
            raise ArgumentError(f"cval of the {dtype} label {name} must be an integer, got {cval!r}")
        exact = [int(v) for v in np.atleast_1d(raw).tolist()]
        if any(not info.min <= v <= info.max for v in exact):
            raise ArgumentError(f"cval {cval!r} is outside the range of the {dtype} label {name} "
                                f"({info.min}..{info.max})")
        if raw.dtype.kind == "f" and any(abs(v) > 2**53 for v in exact):
            raise ArgumentError(f"cval {cval!r} of the {dtype} label {name} is a float beyond 2**53, which "
                                "cannot name one integer; give it as a Python or numpy integer")
        values = np.array(exact, dtype=dtype)
    values = np.broadcast_to(values, (channels,)).copy()
    return values.view(carrier).astype(np.float64)


def _shape_hwc(shape, batch, channels, name):
    """(lead shape, (H, W, C), whether 2-D images) of a label array's shape."""
    lead, rest = tuple(shape[:batch]), tuple(shape[batch:])
    if len(rest) not in (2, 3) or (batch and lead[0] == 0):
        what = "a non-empty (N, H, W) or (N, H, W, C)" if batch else "an (H, W) or (H, W, C)"
        raise ArgumentError(f"{name} must be {what} array, got shape {tuple(shape)}")
    if len(rest) == 2:
        return lead, (*rest, 1), True
    if channels == "first":
        c, h, w = rest
        return lead, (h, w, c), False
    return lead, rest, False


def warp_labels(call, image, transform, output_shape, *, batch, order, mode, cval, backend, antialias, out,
                channels, backend_options=None):
    """Warp the label image (``batch``: stack) ``image`` by ``transform``
    through its carrier; ``call`` is :func:`fpiwarp.warp_image` or
    :func:`fpiwarp.warp_batch`. Returns what they return for images: the
    input's dtype, layout and kind of array, ``out`` if given."""
    from .dispatch import check_channels  # noqa: PLC0415 - dispatch imports the backends

    name = "images" if batch else "image"
    check_channels(channels)
    dtype = label_dtype(image)
    info = array_info(image)
    lead, (h, w, c), squeeze = _shape_hwc(tuple(image.shape), int(batch), channels, name)
    carrier_cval = check_label_options(dtype, order, antialias, cval, c, name)
    extra = {} if batch else {"backend_options": backend_options}
    kwargs = {"order": 0, "mode": mode, "cval": carrier_cval, "backend": backend, **extra}
    if out is not None and label_dtype(out) != dtype:
        raise ArgumentError(f"out= must have the label image's dtype {dtype}, got {getattr(out, 'dtype', None)}")
    if info.kind in ("numpy", "host"):
        return _host(call, np.asarray(image), transform, output_shape, lead, (h, w, c), squeeze, channels, dtype,
                     out, kwargs)
    if info.kind == "opencl":
        return _opencl(call, image, transform, output_shape, lead, (h, w, c), squeeze, channels, dtype, out,
                       kwargs)
    if info.kind in ("warp", "dlpack", "cuda_array_interface"):
        return _warp(call, image, info, transform, output_shape, lead, (h, w, c), squeeze, channels, dtype, out,
                     kwargs)
    raise ArgumentTypeError(f"{name}: {dtype} labels warp as numpy, Warp, DLPack, CUDA or pyopencl arrays, "
                            f"not as {info.kind} ({info.library})")


def _output_shape(output_shape, h, w):
    return check_output_shape(output_shape, np.broadcast_to(np.zeros((), np.uint8), (h, w, 1)))


def _layout(lead, oshape, c, squeeze, channels):
    if squeeze:
        return (*lead, *oshape)
    return (*lead, c, *oshape) if channels == "first" else (*lead, *oshape, c)


def _host(call, arr, transform, output_shape, lead, hwc, squeeze, channels, dtype, out, kwargs):
    b = len(lead)
    if squeeze:
        arr = arr[..., None]
    elif channels == "first":
        arr = np.moveaxis(arr, b, -1)
    carrier_dtype, _ = carrier_of(dtype)
    carrier = np.ascontiguousarray(arr).view(carrier_dtype)
    result = np.ascontiguousarray(call(carrier, transform, output_shape, **kwargs)).view(dtype)
    if squeeze:
        result = result[..., 0]
    elif channels == "first":
        result = np.ascontiguousarray(np.moveaxis(result, -1, b))
    if out is None:
        return result
    out_arr = np.asarray(out) if not isinstance(out, np.ndarray) else out
    if out_arr.shape != result.shape:
        raise ArgumentError(f"out= must be {result.shape} {dtype}, got {out_arr.shape} {out_arr.dtype}")
    np.copyto(out_arr, result)
    return out


def _carrier_strides(strides, itemsize, c, squeeze, k, name):
    """Strides of the carrier view of (..., H, W, C) label strides."""
    if not squeeze and c > 1 and strides[-1] != itemsize:
        raise ArgumentError(f"{name}: a label image's channels must be adjacent in memory to be warped in place "
                            "(channels='last' and a contiguous channel axis); make it contiguous")
    return (*strides[:-1], itemsize // k)


def _warp(call, image, info, transform, output_shape, lead, hwc, squeeze, channels, dtype, out, kwargs):
    from ..backends.nvwarp import arrays as warp_path  # noqa: PLC0415
    from . import convert  # noqa: PLC0415

    wp = warp_path.warp_module()
    name = "images" if lead else "image"
    (h, w, c), b = hwc, len(lead)
    carrier_dtype, k = carrier_of(dtype)
    wcarrier = wp.uint8 if k == 1 and dtype.itemsize == 1 else wp.uint16
    arr = convert.to_warp(wp, image, info)
    src = _warp_hwc(wp, arr, b, squeeze, channels)
    src_carrier = wp.array(ptr=src.ptr, dtype=wcarrier, shape=(*src.shape[:-1], c * k),
                           strides=_carrier_strides(src.strides, dtype.itemsize, c, squeeze, k, name),
                           device=src.device)
    oshape = _output_shape(output_shape, h, w)
    layout = _layout(lead, oshape, c, squeeze, channels)
    if out is None:
        target = wp.empty(layout, dtype=wp.dtype_from_numpy(dtype), device=arr.device)
    else:
        target = convert.to_warp(wp, out, array_info(out))
        if tuple(target.shape) != layout:
            raise ArgumentError(f"out= must be {layout} {dtype}, got {tuple(target.shape)}")
    dst = _warp_hwc(wp, target, b, squeeze, channels)
    dst_carrier = wp.array(ptr=dst.ptr, dtype=wcarrier, shape=(*dst.shape[:-1], c * k),
                           strides=_carrier_strides(dst.strides, dtype.itemsize, c, squeeze, k, "out="),
                           device=dst.device)
    call(src_carrier, transform, output_shape, out=dst_carrier, **{**kwargs, "backend": kwargs["backend"] or "warp"})
    if out is not None:
        return out
    return convert.from_warp(target, info)


def _warp_hwc(wp, arr, b, squeeze, channels):
    """An (..., H, W, C) view of a Warp label array as given."""
    if squeeze:
        item = wp.types.type_size_in_bytes(arr.dtype)
        return wp.array(ptr=arr.ptr, dtype=arr.dtype, shape=(*arr.shape, 1), strides=(*arr.strides, item),
                        device=arr.device)
    if channels == "first":
        return arr.transpose((*range(b), b + 1, b + 2, b))
    return arr


def _opencl(call, image, transform, output_shape, lead, hwc, squeeze, channels, dtype, out, kwargs):
    import pyopencl.array as cla  # noqa: PLC0415

    name = "images" if lead else "image"
    (h, w, c) = hwc
    carrier_dtype, k = carrier_of(dtype)
    if not image.flags.c_contiguous or (channels == "first" and not squeeze and c > 1):
        raise ArgumentError(f"{name}: a pyopencl label image is warped in place when C-contiguous with its "
                            "channels last (or one channel); make it so")
    oshape = _output_shape(output_shape, h, w)
    layout = _layout(lead, oshape, c, squeeze, channels)

    def carrier_view(a, shape):
        return cla.Array(a.queue, (*shape, c * k), carrier_dtype, data=a.base_data, offset=a.offset)

    src = carrier_view(image, (*lead, h, w))
    if out is None:
        target = cla.empty(image.queue, layout, dtype)
    else:
        target = out
        if tuple(target.shape) != layout or not target.flags.c_contiguous:
            raise ArgumentError(f"out= must be a C-contiguous {layout} {dtype} array, got {tuple(target.shape)}")
    call(src, transform, output_shape, out=carrier_view(target, (*lead, *oshape)),
         **{**kwargs, "backend": kwargs["backend"] or "opencl"})
    return target
