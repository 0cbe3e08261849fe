"""Sampling an image at real (x, y) positions: the numpy reference.

Conventions shared by every backend:

* pixel centers at integer coordinates, x = column, y = row;
* order 0 takes the nearest pixel (floor(x + 0.5)); order 1 is bilinear
  over the four surrounding pixels; order 3 is Keys' cubic convolution
  (a = -0.5, Catmull-Rom) over 4×4 pixels;
* border modes act on each tap's integer index: ``constant`` gives taps
  outside the image the value ``cval``; ``edge`` clamps; ``reflect``
  mirrors about the edge pixels without repeating them (numpy.pad's
  'reflect', OpenCV's BORDER_REFLECT_101); ``wrap`` tiles the image;
* a source position that is not finite or lies beyond ``COORD_LIMIT``
  (2**24 px) in x or y gives ``cval`` in every mode, never NaN: such
  positions come from pixels at or next to the pole's image w∞, where the
  direction "outside" is meaningless;
* integer outputs are rounded with floor(v + 0.5) and clipped to the
  dtype's range; float32 outputs are neither rounded nor clipped.
"""

import numpy as np

# MODES (a mode's number in the kernels is its index), ORDERS and
# COORD_LIMIT are numbers of the kernel contract: defined once, there.
from ..block.sampling_rules import COORD_LIMIT, MODES, ORDERS  # noqa: F401 - MODES, ORDERS re-exported

DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))


def border_index(i, n, mode):
    """Map integer indices to valid ones; also return which were inside."""
    inside = (i >= 0) & (i < n)
    if mode == "edge" or mode == "constant":
        return np.clip(i, 0, n - 1), inside
    if mode == "wrap":
        return np.mod(i, n), inside
    if n == 1:
        return np.zeros_like(i), inside
    period = 2 * (n - 1)
    m = np.mod(i, period)
    return np.where(m >= n, period - m, m), inside


def _cubic_weights(t):
    """Keys' cubic convolution weights (a = -0.5) for offsets -1, 0, 1, 2."""
    t2, t3 = t * t, t * t * t
    return (
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    )


def _taps(coord, order):
    """Integer tap positions and their weights along one axis."""
    if order == 0:
        return [np.floor(coord + 0.5).astype(np.int64)], [np.ones_like(coord)]
    base = np.floor(coord)
    t = coord - base
    base = base.astype(np.int64)
    if order == 1:
        return [base, base + 1], [1.0 - t, t]
    return [base - 1, base, base + 1, base + 2], list(_cubic_weights(t))


def sample(image, x, y, order=1, mode="constant", cval=0.0):
    """Sample ``image`` (H, W, C) at positions x, y (same shape S).

    Returns float64 values of shape S + (C,), before rounding.
    """
    h, w, c = image.shape
    cval = np.broadcast_to(np.asarray(cval, dtype=np.float64), (c,))
    with np.errstate(invalid="ignore"):
        finite = (np.abs(x) <= COORD_LIMIT) & (np.abs(y) <= COORD_LIMIT)  # False for nan
    x = np.where(finite, x, 0.0)
    y = np.where(finite, y, 0.0)
    flat = image.reshape(h * w, c)
    xs, wx = _taps(x, order)
    ys, wy = _taps(y, order)
    out = np.zeros(x.shape + (c,), dtype=np.float64)
    cols = [border_index(xi, w, mode) for xi in xs]
    for yi, wyi in zip(ys, wy):
        row, row_in = border_index(yi, h, mode)
        for (col, col_in), wxi in zip(cols, wx):
            vals = flat[row * w + col].astype(np.float64)
            if mode == "constant":
                vals = np.where((row_in & col_in)[..., None], vals, cval)
            out += (wyi * wxi)[..., None] * vals
    return np.where(finite[..., None], out, cval)


def to_dtype(values, dtype):
    """Round and clip float values to an image dtype (see module docstring)."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return values.astype(dtype)
    top = np.iinfo(dtype).max
    return np.clip(np.floor(values + 0.5), 0, top).astype(dtype)
