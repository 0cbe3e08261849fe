"""Warping many images with one map: arrays, stacks and folders.

* :func:`warp_images` is a generator: arrays or file paths in, warped
  arrays out, one at a time (bounded memory).
* :func:`warp_batch` warps an (N, H, W[, C]) stack with one map for all or
  one map per image.
* :func:`run_batch` (in :mod:`fpiwarp.batch_folders`, re-exported here)
  warps every image of a folder into another folder.

The map is solved once and bound to the backend (``bind``): the numpy
backend computes the source position of every output pixel once per
output size and shares it among the images of that size. A backend whose
capabilities say ``batches`` warps a whole stack in one call
(``warp_batch``); the others get one ``warp_image`` call per image.
"""

import os

import numpy as np

from ._errors import ArgumentError
from ._transform import Transform
from .backends import get_backend
from .batch_folders import BatchSummary, list_inputs, run_batch
from .io import read_image
from .progress import Progress
from .validation import check_cval, check_image, check_output_shape, check_warp_arguments
from .warper import Warper

__all__ = ["BatchSummary", "Progress", "Warper", "list_inputs", "run_batch", "warp_batch", "warp_images"]


def _as_image(item):
    if isinstance(item, (str, os.PathLike)):
        return read_image(item)[0]
    return item


def warp_images(images, transform, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy",
                backend_options=None, antialias=False):
    """Warp each of ``images`` (arrays, or paths of image files) by
    ``transform``; yield the warped arrays in order, one at a time.

    Options as in :func:`fpiwarp.warp_image`; they are checked before the
    first image is read. Same-size images share the map's evaluation.
    """
    warper = Warper(transform, output_shape, order=order, mode=mode, cval=cval, backend=backend,
                    backend_options=backend_options, antialias=antialias)
    return (warper(_as_image(item)) for item in images)


def warp_batch(images, transforms, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy",
               antialias=False):
    """Warp a stack of same-size images, (N, H, W) or (N, H, W, C).

    ``transforms`` is one map for all images or a sequence of N maps, one
    per image. Returns an (N, rows, cols[, C]) array of the input's dtype.
    On a backend that batches (numpy: one map is evaluated once and all N
    images sampled in one pass) the stack goes in one call. ``antialias``
    as in :func:`fpiwarp.warp_image`.
    """
    stack = np.asarray(images) if not isinstance(images, np.ndarray) else images
    if stack.ndim not in (3, 4) or stack.shape[0] == 0:
        raise ArgumentError(f"images must be a non-empty (N, H, W) or (N, H, W, C) array, got shape {stack.shape}")
    first, squeeze = check_image(stack[0], name="images")
    n, (h, w, c) = stack.shape[0], first.shape
    maps = [transforms] if isinstance(transforms, Transform) else list(transforms)
    if not isinstance(transforms, Transform) and len(maps) != n:
        raise ArgumentError(f"got {len(maps)} maps for {n} images; give one map or one per image")
    warpers = [Warper(t, output_shape, order=order, mode=mode, cval=cval, backend=backend, antialias=antialias)
               for t in maps]
    if warpers[0].capabilities.batches:
        shape = check_output_shape(output_shape, first)
        for warper in warpers:  # sizes and stages, as warp_image checks them
            check_warp_arguments(first, warper.transform, shape, order, mode, cval, warper.capabilities, backend)
        out = get_backend(backend).warp_batch(
            np.ascontiguousarray(stack.reshape(n, h, w, c)),
            maps,
            shape,
            order=warpers[0].order,
            mode=mode,
            cval=check_cval(cval, c, stack.dtype),
            **({"antialias": True} if warpers[0].antialias else {}),
        )
    else:
        chosen = warpers * n if len(warpers) == 1 else warpers
        out = np.stack([chosen[i](stack[i].reshape(h, w, c)) for i in range(n)])
    out = np.ascontiguousarray(out)
    return out[..., 0] if squeeze else out
