"""warp_image and map_points for every kind of array: the backend chosen
from where the data lives, the result of the input's kind, ``out=`` and
the channel layout. numpy in, numpy out stays the path of
:mod:`fpiwarp.warping`; everything else comes here.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..backends import array_calls, backend_capabilities, backend_entry, check_backend_name, readers_of
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
from .kinds import HOST_KINDS, HOST_VIEW_KINDS, TO_HOST, array_info, choose_backend
from .outputs import check_host_out, copy_host_out, copy_points_out

CHANNELS = ("last", "first")


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


@dataclass(frozen=True)
class WarpCall:
    """The options of one warp_image or warp_batch call, as the caller gave
    them (checked by the path that runs them)."""

    output_shape: object = None
    order: object = 1
    mode: object = "constant"
    cval: object = 0
    backend_options: object = None
    antialias: object = False
    out: object = None
    channels: str = "last"


def check_device_warp(shape, dtype, transform, call, backend, name="image"):
    """:func:`fpiwarp.validation.check_warp_arguments` for an image known by
    (H, W, C) ``shape`` and ``dtype`` only, with the options of ``call``
    (a :class:`WarpCall`): nothing is read or copied.
    Returns (output_shape, order, mode, cval, options, the map as an
    :class:`Inverted` for the backend); errors name the argument ``name``."""
    caps = backend_capabilities(backend)
    order, mode = check_warp_options(transform, call.order, call.mode)
    proxy, _ = check_image(np.broadcast_to(np.zeros((), dtype), shape), name=name)
    cval = check_cval(call.cval, shape[2], proxy.dtype)
    out_shape = check_output_shape(call.output_shape, proxy)
    options = check_backend_call(shape, out_shape, proxy.dtype, order, mode, caps, backend, call.backend_options,
                                 call.antialias)
    inverted = Inverted(transform)
    check_map_size(inverted.inverse, caps, backend)
    return out_shape, order, mode, cval, options, inverted


def mismatch(info, backend):
    """The DeviceMismatchError for an array the backend cannot read in place,
    naming the backends that can (from the registry)."""
    readers = readers_of(info.kind)
    use = " or ".join(f"backend={name!r}" for name in readers)
    to_host = TO_HOST.get(info.kind, "copy it to the host")
    if not readers:
        hint = to_host
    elif info.kind in TO_HOST:
        hint = f"use {use} (or None), or {to_host}"
    else:
        hint = f"use {use} (or None) for {info.device} arrays, or {to_host}"
    return DeviceMismatchError(f"the {backend} backend cannot read a {info.library} array on {info.device} in "
                               f"place; {hint}")


def route(info, name, out=None):
    """How backend ``name`` takes an array described by ``info``, from its
    registry entry: "host" (numpy memory, the entry points' host path),
    "in_place" (the entry's array calls) or "host_view" (a numpy view of
    host memory); DeviceMismatchError where it cannot."""
    entry = backend_entry(name)
    if info.kind in HOST_KINDS:
        if out is not None and entry.arrays and array_calls(name).writes_host_out():
            return "in_place"
        return "host"
    if info.kind in entry.reads:
        return "in_place"
    if info.kind in HOST_VIEW_KINDS and info.on_host:
        return "host_view"
    raise mismatch(info, name)


def refuse_immutable_out(out):
    """ArgumentError for a JAX ``out=`` (JAX arrays cannot be written)."""
    if out is not None and array_info(out).library in ("jax", "jaxlib"):
        raise ArgumentError("out= cannot be a JAX array (JAX arrays are immutable); leave out=None")


def in_place_call(name, what, info):
    """Backend ``name``'s in-place function ``what`` for arrays of ``info``'s
    kind, or DeviceMismatchError where its array calls do not take it."""
    calls = array_calls(name)
    fn = getattr(calls, what, None) if calls is not None else None
    if fn is None:
        raise mismatch(info, name)
    return fn


def warp_image(image, transform, call, backend, host_warp):
    """See :func:`fpiwarp.warp_image` (``call``: a :class:`WarpCall`);
    ``host_warp`` is its numpy path."""
    check_channels(call.channels)
    info = array_info(image)
    refuse_immutable_out(call.out)
    if backend is None and info.kind in HOST_KINDS:  # the fast default, chosen by the host path per call
        return _host(image, transform, call, None, host_warp)
    name = check_backend_name(choose_backend(info, backend))
    how = route(info, name, call.out)
    if how == "host":
        return _host(image, transform, call, name, host_warp)
    if how == "in_place":
        return in_place_call(name, "warp_image", info)(image, info, transform, call)
    out = call.out
    result = _host(convert.host_view(image, info), transform, dataclasses.replace(
        call, out=None if out is None else convert.host_view(out, array_info(out))), name, host_warp)
    return out if out is not None else convert.from_host(result, info)


def _host(image, transform, call, name, host_warp):
    img, out = np.asarray(image), call.out
    first = call.channels == "first" and img.ndim == 3
    if out is not None:
        check_host_out(out, img, "the image")
    result = host_warp(np.moveaxis(img, 0, 2) if first else img, transform, call.output_shape, order=call.order,
                       mode=call.mode, cval=call.cval, backend=name, backend_options=call.backend_options,
                       antialias=call.antialias)
    if first:
        result = np.moveaxis(result, 2, 0)
    if out is None:
        return np.ascontiguousarray(result) if first else result
    return copy_host_out(result, out)


def map_points(transform, points, backend, out, host_map):
    """See :func:`fpiwarp.map_points`; ``host_map`` is its numpy path."""
    info = array_info(points)
    name = check_backend_name(choose_backend(info, backend))
    how = route(info, name)
    if how == "host":
        return copy_points_out(host_map(transform, points, backend=name), out, np.asarray(points))
    if how == "in_place":
        return in_place_call(name, "map_points", info)(transform, points, info, out)
    result = host_map(transform, convert.host_view(points, info), backend=name)
    return convert.from_host(result, info)
