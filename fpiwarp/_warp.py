"""The user-facing entry points: ``warp_image`` and ``map_points``.

They validate input once, then hand normalized arrays to a backend from
:mod:`fpiwarp.backends`, so every backend sees the same contract.
"""

import numpy as np

from ._sampling import DTYPES, MODES, ORDERS
from ._transform import Transform
from .backends import get_backend


def _check_transform(transform):
    if not isinstance(transform, Transform):
        raise TypeError(
            f"transform must be an fpiwarp map (FPI, Mobius, RLinear, ...), "
            f"got {type(transform).__name__}"
        )


def map_points(transform, points, backend="numpy"):
    """Map (..., 2) points through ``transform`` on a backend (per vertex).

    Returns float64 (..., 2). Points sent to the pole come out non-finite.
    """
    _check_transform(transform)
    pts = np.asarray(points)
    if pts.ndim == 0 or pts.shape[-1] != 2:
        raise ValueError(f"points must have shape (..., 2), got {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number) or np.iscomplexobj(pts):
        raise TypeError(f"points must be real numbers, got dtype {pts.dtype}")
    return get_backend(backend).map_points(transform, pts.astype(np.float64, copy=False))


def check_image(image):
    """Validate an image; return it as (H, W, C) and whether it was 2-D."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image must be a numpy array, got {type(image).__name__}")
    if image.dtype not in DTYPES:
        raise TypeError(
            f"image dtype must be uint8, uint16 or float32, got {image.dtype} "
            "(convert with image.astype(np.float32))"
        )
    if image.ndim not in (2, 3) or (image.ndim == 3 and not 1 <= image.shape[2] <= 4):
        raise ValueError(f"image must be (H, W) or (H, W, C) with C in 1..4, got shape {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"image is empty: shape {image.shape}")
    if image.ndim == 2:
        return image[:, :, None], True
    return image, False


def check_output_shape(output_shape, image):
    if output_shape is None:
        return image.shape[:2]
    try:
        oh, ow = output_shape
        if int(oh) != oh or int(ow) != ow:
            raise ValueError
        oh, ow = int(oh), int(ow)
    except (TypeError, ValueError):
        raise ValueError(f"output_shape must be (rows, cols) integers, got {output_shape!r}") from None
    if oh <= 0 or ow <= 0:
        raise ValueError(f"output_shape must be positive, got {output_shape!r}")
    return oh, ow


def check_cval(cval, channels):
    """cval as float64 (channels,): a finite number or one per channel."""
    try:
        arr = np.asarray(cval, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"cval must be a finite number or one per channel ({channels}), got {cval!r}") from None
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != channels) or not np.all(np.isfinite(arr)):
        raise ValueError(f"cval must be a finite number or one per channel ({channels}), got {cval!r}")
    return np.broadcast_to(arr, (channels,)).copy()


def warp_image(image, transform, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy"):
    """Warp ``image`` by ``transform``, which maps source to output coordinates.

    Each output pixel samples the source at ``transform.inverse`` of its
    position (backward warping; exact for the FPI). Pixel centers are at
    integer coordinates, x = column, y = row.

    Parameters
    ----------
    image : ndarray, uint8, uint16 or float32, (H, W) or (H, W, C), C in 1..4
    transform : an fpiwarp map (FPI, Mobius, RLinear, Compound, ...)
    output_shape : (rows, cols), default the input's
    order : 0 (nearest), 1 (bilinear) or 3 (cubic convolution)
    mode : 'constant', 'edge', 'reflect' or 'wrap'
    cval : value (or one per channel) outside the image in 'constant' mode,
        and wherever the source position is not finite (near the pole)
    backend : name from :func:`fpiwarp.backends.backend_status`

    Returns an array of the input's dtype and channel layout.
    """
    _check_transform(transform)
    img, squeeze = check_image(image)
    if order not in ORDERS:
        raise ValueError(f"order must be one of {ORDERS}, got {order!r}")
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    cval = check_cval(cval, img.shape[2])
    shape = check_output_shape(output_shape, img)
    out = get_backend(backend).warp_image(
        np.ascontiguousarray(img), transform, shape, order=order, mode=mode, cval=cval
    )
    return out[:, :, 0] if squeeze else out
