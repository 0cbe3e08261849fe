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

import dataclasses

import numpy as np

from ..arrays import convert
from ..arrays.dispatch import (
    Inverted,
    check_channels,
    check_device_warp,
    hwc_shape,
    in_place_call,
    refuse_immutable_out,
    route,
)
from ..arrays.kinds import HOST_KINDS, IMAGE_ONLY_KINDS, array_info, choose_backend
from ..arrays.outputs import check_host_out, copy_host_out, copy_points_out
from ..backends import backend_capabilities, check_backend_name
from ..block.many import is_many_maps
from ..errors import ArgumentError, ArgumentTypeError
from ..maps.transform import Transform
from ..validation import check_map_size, check_transform


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


def check_maps(maps, hwc, dtype, call, backend):
    """Everything checked as warp_image checks it for each image (nothing
    is read; what does not depend on the map once), with the options of
    ``call`` (a :class:`~fpiwarp.arrays.dispatch.WarpCall`): (output shape,
    order, mode, cval, options, the maps as the backend reads them)."""
    *first, inverted = check_device_warp(hwc, dtype, maps[0], dataclasses.replace(call, backend_options=None),
                                         backend, "images")
    if is_many_maps(maps):  # an FPIStack: FPIs of one stage, checked when built; its blocks packed in one pass
        return (*first, maps)
    caps = backend_capabilities(backend)
    rest = []
    for t in maps[1:]:
        check_transform(t, "transforms")
        rest.append(Inverted(t))
        check_map_size(rest[-1].inverse, caps, backend)
    return (*first, [inverted, *rest])


def warp_batch(images, transforms, call, backend, host_batch):
    """See :func:`fpiwarp.warp_batch` (``call``: a
    :class:`~fpiwarp.arrays.dispatch.WarpCall`); ``host_batch`` is its numpy path."""
    check_channels(call.channels)
    info = array_info(images)
    refuse_immutable_out(call.out)
    if info.kind in IMAGE_ONLY_KINDS:
        raise ArgumentTypeError("warp_batch takes stacks, not textures: warp textures one by one with warp_image")
    if backend is None and info.kind in HOST_KINDS:  # the fast default, chosen by the host path
        return _host(np.asarray(images), transforms, call, None, host_batch)
    name = check_backend_name(choose_backend(info, backend))
    how = route(info, name, call.out)
    if how == "host":
        return _host(np.asarray(images), transforms, call, name, host_batch)
    if how == "in_place":
        return in_place_call(name, "warp_batch", info)(images, info, transforms, call)
    out = call.out
    host_out = None if out is None else convert.host_view(out, array_info(out))
    result = _host(convert.host_view(images, info), transforms, dataclasses.replace(call, out=host_out), name,
                   host_batch)
    return out if out is not None else convert.from_host(result, info)


def _host(stack, transforms, call, name, host_batch):
    out = call.out
    first = call.channels == "first" and stack.ndim == 4
    if out is not None:
        check_host_out(out, stack, "images")
    result = host_batch(np.moveaxis(stack, 1, 3) if first else stack, transforms, call.output_shape,
                        order=call.order, mode=call.mode, cval=call.cval, backend=name, antialias=call.antialias)
    if first:
        result = np.moveaxis(result, 3, 1)
    if out is None:
        return np.ascontiguousarray(result)
    return copy_host_out(result, out)


def map_points_batch(transforms, points, backend, out, host_batch):
    """See :func:`fpiwarp.map_points_batch`; ``host_batch`` is its numpy path."""
    info = array_info(points)
    name = check_backend_name(choose_backend(info, backend))
    refuse_immutable_out(out)
    how = route(info, name)
    if how == "host":
        return copy_points_out(host_batch(transforms, np.asarray(points), backend=name), out, np.asarray(points))
    if how == "in_place":
        return in_place_call(name, "map_points_batch", info)(transforms, points, info, out)
    result = host_batch(transforms, convert.host_view(points, info), backend=name)
    return convert.from_host(result, info)


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
