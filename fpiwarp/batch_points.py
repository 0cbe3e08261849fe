"""Batched :func:`fpiwarp.map_points`: N point sets, one map each or one for all."""

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ._errors import ArgumentError
from ._transform import Transform
from .backends import backend_capabilities, get_backend
from .validation import check_map_size, check_point_count, check_points, check_transform

__all__ = ["map_points_batch"]


def map_points_batch(
    transforms: Transform | Sequence[Transform], points: ArrayLike, backend: str = "numpy"
) -> np.ndarray:
    """Map N point sets, ``points[i]`` by ``transforms[i]`` (or all by one map).

    On the "opencl" and "warp" backends the whole batch is one kernel
    launch (opencl: one per kind of map, see
    :mod:`fpiwarp.backends.opencl_batch`); each set's result equals
    :func:`fpiwarp.map_points` of that set on the same backend, bit for
    bit. Other backends map the sets one after the other.

    Parameters
    ----------
    transforms : Transform or sequence of Transform
        One map for all sets, or N maps.
    points : array_like, shape (N, ..., 2)
        N point sets of one shape; the first axis is the batch.
    backend : str, optional
        As in :func:`fpiwarp.map_points`; default "numpy".

    Returns
    -------
    ndarray, float64, shape (N, ..., 2)
        The mapped sets.

    Raises
    ------
    ArgumentError
        ``points`` not of shape (N, ..., 2), or a number of maps other
        than 1 or N; and as :func:`fpiwarp.map_points` (per set).

    Examples
    --------
    >>> import numpy as np
    >>> import fpiwarp
    >>> shifts = [fpiwarp.RLinear(1, 0, k) for k in range(3)]      # z -> z + k
    >>> fpiwarp.map_points_batch(shifts, np.zeros((3, 1, 2))).tolist()
    [[[0.0, 0.0]], [[1.0, 0.0]], [[2.0, 0.0]]]
    """
    one = isinstance(transforms, Transform)
    maps = [transforms] if one else list(transforms)
    for t in maps:
        check_transform(t, "transforms")
    pts = check_points(points)
    if pts.ndim < 2:
        raise ArgumentError(f"points must have shape (N, ..., 2), got {pts.shape}")
    n = pts.shape[0]
    if not one and len(maps) != n:
        raise ArgumentError(f"got {len(maps)} maps for {n} point sets; give one map or one per set")
    caps = backend_capabilities(backend)
    check_point_count(pts[0] if n else pts, caps, backend)
    for t in maps:
        check_map_size(t, caps, backend)
    impl = get_backend(backend)
    if not hasattr(impl, "map_points_batch") or n == 0:
        chosen = maps * n if one else maps
        return np.stack([impl.map_points(t, s) for t, s in zip(chosen, pts, strict=True)]) if n else pts.copy()
    flat = np.ascontiguousarray(pts.reshape(n, -1, 2))
    return impl.map_points_batch(maps, flat).reshape(pts.shape)
