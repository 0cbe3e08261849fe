"""Warping many images with one map: arrays, stacks and folders.

* :func:`warp_images` is a generator: arrays or file paths in, warped
  arrays out, one at a time (bounded memory).
* :func:`warp_batch` warps an (N, H, W[, C]) stack with one map for all or
  one map per image.
* :func:`run_batch` (in :mod:`fpiwarp.batch.folders`, re-exported here)
  warps every image of a folder into another folder.

The map is solved once and bound to the backend (``bind``): the numpy
backend computes the source position of every output pixel once per
output size and shares it among the images of that size. A backend whose
capabilities say ``batches`` warps a whole stack in one call
(``warp_batch``): "numpy" (one map: one pass for all images), "opencl"
(one kernel launch per kind of map, ``fpiwarp.backends.opencl.batch``),
"warp" (likewise, ``fpiwarp.backends.nvwarp.batch``) and "gl" (one
instanced draw per kind of map, ``fpiwarp.backends.gl.batch``); a
backend that does not batch gets one ``warp_image`` call per image.
Either way the result equals the loop of :func:`fpiwarp.warp_image` bit
for bit.
"""

import os
from collections.abc import Iterable, Iterator, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import labels
from ..arrays.dispatch import WarpCall
from ..backends import backend_entry, get_backend
from ..backends.default import stage_count
from ..block.many import is_many_maps
from ..errors import ArgumentError
from ..io.images import read_image
from ..maps.transform import Transform
from ..validation import check_image, check_map_size, check_transform, check_warp_arguments, refuse_masked
from ..warping import Warper, on_default_backend
from .folders import BatchSummary, list_inputs, run_batch
from .progress import Progress

__all__ = ["BatchSummary", "Progress", "Warper", "list_inputs", "run_batch", "warp_batch", "warp_images"]


def _as_image(item):
    if isinstance(item, (str, os.PathLike)):
        return read_image(item)
    refuse_masked(item)
    return item


def warp_images(
    images: Iterable[np.ndarray | str | os.PathLike],
    transform: Transform,
    output_shape: tuple[int, int] | None = None,
    *,
    order: int = 1,
    mode: str = "constant",
    cval: float | Sequence[float] = 0,
    backend: str | None = None,
    backend_options: Mapping[str, object] | None = None,
    antialias: bool = False,
) -> Iterator[np.ndarray]:
    """Warp each of ``images`` by ``transform``; yield the warped arrays in
    order, one at a time (bounded memory).

    The map is solved and bound to the backend once; images of the same
    size share its evaluation (on "numpy", the source positions).

    Parameters
    ----------
    images : iterable of ndarray or path-like
        Arrays as :func:`fpiwarp.warp_image` takes them, or paths of image
        files (read with :func:`fpiwarp.read_image`, one at a time).
    transform : Transform
        The map, from source to output coordinates (x = column, y = row).
    output_shape, order, mode, cval, backend, backend_options, antialias
        As in :func:`fpiwarp.warp_image`; checked before the first image
        is read.

    Yields
    ------
    ndarray
        Each warped image, of its input's dtype and channels.

    Raises
    ------
    ArgumentError, ArgumentTypeError, BackendUnavailableError
        For bad options, when the generator is created.
    ImageError, FileNotFoundError
        For a path that cannot be read, when that image's turn comes.

    See Also
    --------
    warp_batch : a stack in one call.
    fpiwarp.batch.run_batch : a folder of files into another.

    Examples
    --------
    >>> import numpy as np
    >>> import fpiwarp
    >>> shift = fpiwarp.RLinear(1, 0, 1j)                 # y -> y + 1: content moves down
    >>> frames = [np.full((2, 3), v, np.uint8) for v in (10, 20)]
    >>> [out.tolist() for out in fpiwarp.warp_images(frames, shift, order=0)]
    [[[0, 0, 0], [10, 10, 10]], [[0, 0, 0], [20, 20, 20]]]
    """
    warper = Warper(transform, output_shape, order=order, mode=mode, cval=cval, backend=backend,
                    backend_options=backend_options, antialias=antialias)
    if isinstance(images, (list, tuple)):  # refused now, not at the first next()
        for item in images:
            refuse_masked(item)
    return (warper(_as_image(item)) for item in images)


def warp_batch(
    images: ArrayLike,
    transforms: Transform | Sequence[Transform],
    output_shape: tuple[int, int] | None = None,
    *,
    order: int = 1,
    mode: str = "constant",
    cval: float | Sequence[float] = 0,
    backend: str | None = None,
    antialias: bool = False,
    out: object | None = None,
    channels: str = "last",
) -> object:
    """Warp a stack of same-size images, with one map for all or one each.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, C)
        N images of one size, uint8, uint16 or float32: a numpy array, or
        a stack on a device as :func:`fpiwarp.warp_image` takes images
        (a Warp, DLPack or CUDA array: torch, CuPy, JAX; a
        ``pyopencl.array.Array``), warped where it lives without a host
        copy, in one launch per kind of map (:mod:`fpiwarp.arrays`).
    transforms : Transform or sequence of Transform
        One map for all images, or N maps, one per image (source to output
        coordinates, x = column, y = row).
    output_shape, order, mode, cval, antialias
        As in :func:`fpiwarp.warp_image`.
    backend : str or None, optional
        As in :func:`fpiwarp.warp_image`; None (default) follows the data
        (for numpy stacks the fast default of :func:`fpiwarp.warp_image`,
        "warp" for Warp/DLPack/CUDA arrays, "opencl" for pyopencl arrays).
    out : array, optional
        An array of the result's shape and dtype, of the input's kind and
        device, written in place and returned (numpy: one host copy).
    channels : {"last", "first"}, optional
        "first" reads 4-D stacks as (N, C, H, W) (torch's layout) and
        returns that layout; on "warp" it is a strided view (zero-copy),
        on "opencl" a permute on the device.

    Returns
    -------
    array, shape (N, rows, cols) or (N, rows, cols, C)
        The warped stack, of the input's dtype and library (on its
        device), equal bit for bit to the
        loop of :func:`fpiwarp.warp_image` over the images. On a backend
        that batches the stack goes in one call (numpy: one map evaluated
        once for all N images; opencl: one kernel launch per kind of map;
        warp: one launch; gl: one instanced draw per kind of map), in
        launches of bounded size for large stacks.

    Raises
    ------
    ArgumentError
        An empty stack, a shape other than 3-D or 4-D, or a number of maps
        other than 1 or N; a bad ``out=``; and as :func:`fpiwarp.warp_image`.
    DeviceMismatchError
        A stack the backend cannot read in place (a CUDA tensor on "opencl").

    Examples
    --------
    >>> import numpy as np
    >>> import fpiwarp
    >>> stack = np.zeros((3, 4, 5, 3), np.float32)
    >>> maps = [fpiwarp.RLinear(1, 0, k) for k in range(3)]   # one shift per image
    >>> fpiwarp.warp_batch(stack, maps).shape
    (3, 4, 5, 3)
    """
    refuse_masked(images, "images")
    if labels.label_dtype(images) is not None:  # bool and integer labels: order 0 through a carrier
        return labels.warp_labels(warp_batch, images, transforms, output_shape, batch=True, order=order, mode=mode,
                                  cval=cval, backend=backend, antialias=antialias, out=out, channels=channels)
    if not isinstance(images, np.ndarray) or out is not None or channels != "last":
        from . import arrays as batch_path  # noqa: PLC0415 - device arrays, out= and layouts

        call = WarpCall(output_shape, order, mode, cval, None, antialias, out, channels)
        return batch_path.warp_batch(images, transforms, call, backend, host_batch=warp_batch)
    if backend is None:  # the fast default, as warp_image's
        return on_default_backend(lambda name: warp_batch(images, transforms, output_shape, order=order, mode=mode,
                                                          cval=cval, backend=name, antialias=antialias),
                                  images.dtype, order, mode, antialias, None,
                                  stage_count(transforms if isinstance(transforms, Transform) else transforms[0]))
    stack = images
    if stack.ndim not in (3, 4) or stack.shape[0] == 0:
        raise ArgumentError(f"images must be a non-empty (N, H, W) or (N, H, W, C) array, got shape {stack.shape}")
    first, squeeze = check_image(stack[0], name="images")
    n, (h, w, c) = stack.shape[0], first.shape
    many = is_many_maps(transforms)  # an FPIStack: one object, its blocks packed in one pass
    maps = [transforms] if isinstance(transforms, Transform) else transforms if many else list(transforms)
    if not isinstance(transforms, Transform) and len(maps) != n:
        raise ArgumentError(f"got {len(maps)} maps for {n} images; give one map or one per image")
    lead = Warper(maps[0], output_shape, order=order, mode=mode, cval=cval, backend=backend, antialias=antialias)
    if lead.capabilities.batches:
        # What does not depend on the map is checked once, as warp_image checks it; each map's type, inverse and
        # stage count per map (a Warper per map cost ~40 % of a batch of small images).
        checked = check_warp_arguments(first, maps[0], output_shape, order, mode, cval, lead.capabilities, backend,
                                       antialias=antialias)
        for t in () if many else maps[1:]:
            check_transform(t, "transforms")
        if many:  # FPIs of one stage each, checked when the stack was built
            pass
        elif backend_entry(backend).block_maps:
            # Each further map's inverse and its stages computed once, for the check and the block alike.
            from ..arrays.dispatch import Inverted  # noqa: PLC0415 - loaded with the first batch

            maps = [maps[0], *(Inverted(t) for t in maps[1:])]
        for t in () if many else maps[1:]:
            check_map_size(t.inverse, lead.capabilities, backend)
        out = get_backend(backend).warp_batch(
            np.ascontiguousarray(stack.reshape(n, h, w, c)),
            maps,
            checked.output_shape,
            order=checked.order,
            mode=checked.mode,
            cval=checked.cval,
            **checked.options,
        )
    else:
        warpers = [lead] + [Warper(t, output_shape, order=order, mode=mode, cval=cval, backend=backend,
                                   antialias=antialias) for t in maps[1:]]
        chosen = warpers * n if len(warpers) == 1 else warpers
        out = np.stack([chosen[i](stack[i].reshape(h, w, c)) for i in range(n)])
    out = np.ascontiguousarray(out)
    return out[..., 0] if squeeze else out
