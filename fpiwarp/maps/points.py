"""Conversions between the API's (..., 2) float arrays and complex numbers.

Points are (x, y) at the API, with x = column and y = row in images;
inside the host math they are complex128 z = x + iy.
"""

import numpy as np

from ..errors import ArgumentError, ArgumentTypeError


def as_complex(points, name="points"):
    """Return a complex128 array of shape (...) from an array-like (..., 2)."""
    arr = np.asarray(points)
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.number) or arr.dtype == bool
    ):
        raise ArgumentTypeError(f"{name} must be numeric, got dtype {arr.dtype}")
    if np.iscomplexobj(arr):
        raise ArgumentTypeError(f"{name} must be real (x, y) pairs, not complex numbers")
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ArgumentError(f"{name} must have shape (..., 2), got {arr.shape}")
    arr = arr.astype(np.float64, copy=False)
    return arr[..., 0] + 1j * arr[..., 1]


def as_xy(z):
    """Return a float64 array (..., 2) of (x, y) from complex numbers."""
    z = np.asarray(z)
    out = np.empty(z.shape + (2,), dtype=np.float64)
    out[..., 0] = z.real
    out[..., 1] = z.imag
    return out
