"""Batched :func:`fpiwarp.map_points`: N point sets, one map each or one for all."""

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..backends import backend_capabilities, backend_entry, get_backend
from ..errors import ArgumentError
from ..maps.transform import Transform
from ..validation import check_map_size, check_point_count, check_points, check_transform

__all__ = ["map_points_batch"]


def map_points_batch(
    transforms: Transform | Sequence[Transform], points: ArrayLike, backend: str | None = None, *,
    out: object | None = None
) -> object:
    """Map N point sets, ``points[i]`` by ``transforms[i]`` (or all by one map).

    On "opencl" the batch is one kernel launch per kind of map
    (``fpiwarp.backends.opencl.batch``), on "warp" one launch, on "gl"
    one transform-feedback pass per kind of map
    (``fpiwarp.backends.gl.batch_points``); each set's result equals
    :func:`fpiwarp.map_points` of that set on the same backend, bit for
    bit. "numpy" maps the sets one after the other.

    Parameters
    ----------
    transforms : Transform or sequence of Transform
        One map for all sets, or N maps.
    points : array_like, shape (N, ..., 2)
        N point sets of one shape; the first axis is the batch. Device
        arrays are mapped where they live, in one launch per kind of map,
        as :func:`fpiwarp.map_points` maps them: Warp/DLPack/CUDA arrays
        of float32 or float64 on "warp", pyopencl arrays of the device's
        point dtype on "opencl".
    backend : str or None, optional
        As in :func:`fpiwarp.map_points`; None (default) follows the data
        (numpy for numpy arrays).
    out : array, optional
        An array like the result (same kind, device, shape, dtype),
        written in place and returned.

    Returns
    -------
    array, shape (N, ..., 2)
        The mapped sets: float64 numpy for host input; for device arrays
        an array of their library, dtype and device.

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
    if not isinstance(points, np.ndarray) and not isinstance(points, (list, tuple)) or out is not None:
        from . import arrays as batch_path  # noqa: PLC0415 - device arrays and out=

        return batch_path.map_points_batch(transforms, points, backend, out, map_points_batch)
    backend = "numpy" if backend is None else backend
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
    if backend_entry(backend).block_maps and n:
        # Each map's stages computed once, for the check and the block alike.
        from ..arrays.dispatch import InverseBlock  # noqa: PLC0415 - loaded with the first batch

        maps = [InverseBlock(t.stages()) for t in maps]
    for t in maps:
        check_map_size(t, caps, backend)
    impl = get_backend(backend)
    if not hasattr(impl, "map_points_batch") or n == 0:
        chosen = maps * n if one else maps
        return np.stack([impl.map_points(t, s) for t, s in zip(chosen, pts, strict=True)]) if n else pts.copy()
    flat = np.ascontiguousarray(pts.reshape(n, -1, 2))
    return impl.map_points_batch(maps, flat).reshape(pts.shape)
