"""Where each output pixel samples the source: the backward-warp map.

:func:`source_positions` gives, for every output pixel, the float64 source
position ``transform.inverse(x, y)`` it samples, as an array of shape
(rows, cols, 2) holding (x, y) = (column, row) of the source, pixel
centers at integers. That is what other resamplers take:

* ``cv2.remap(image, pos[..., 0].astype(np.float32), pos[..., 1].astype(np.float32), ...)``;
* ``scipy.ndimage.map_coordinates(channel, [pos[..., 1], pos[..., 0]])``
  (row first).

Pixels that a numerical inverse cannot solve, and pixels at the pole,
come out NaN or inf: a sampler treats them as "outside" (cval), as the
kernels do.
"""

import numpy as np

from ..backends.capabilities import NUMPY
from ..maps.transform import Transform, unsolved_as_nan
from ..validation import check_output_shape, check_sizes, check_transform

__all__ = ["CHUNK_PIXELS", "iter_source_positions", "pixel_grid", "source_positions"]

#: Output pixels evaluated per chunk, to bound memory on large outputs.
CHUNK_PIXELS = 1 << 19


def pixel_grid(row_start, row_stop, cols):
    """float64 (rows, cols, 2) of the (x, y) pixel centers of output rows
    ``row_start`` to ``row_stop`` (excluded)."""
    grid = np.empty((row_stop - row_start, cols, 2))
    grid[..., 0] = np.arange(cols, dtype=np.float64)
    grid[..., 1] = np.arange(row_start, row_stop, dtype=np.float64)[:, None]
    return grid


def iter_source_positions(transform, output_shape, chunk_pixels=CHUNK_PIXELS):
    """Yield (row_start, row_stop, positions) over bands of about
    ``chunk_pixels`` output pixels; ``positions`` is float64
    (row_stop - row_start, cols, 2). The inverse is built once."""
    inverse = transform.inverse
    rows, cols = output_shape
    band = max(1, chunk_pixels // cols)
    for r0 in range(0, rows, band):
        r1 = min(rows, r0 + band)
        with unsolved_as_nan():
            yield r0, r1, inverse(pixel_grid(r0, r1, cols))


def source_positions(transform: Transform, output_shape: tuple[int, int]) -> np.ndarray:
    """The source position that each output pixel samples: the backward map.

    Parameters
    ----------
    transform : Transform
        The map from source to output coordinates, as
        :func:`fpiwarp.warp_image` takes it.
    output_shape : tuple of int (rows, cols)
        The size of the output.

    Returns
    -------
    ndarray, float64, shape (rows, cols, 2)
        ``out[r, c]`` is the source ``(x, y)`` = (column, row) that output
        pixel ``(r, c)`` samples, ``transform.inverse((c, r))``, pixel
        centers at integers. Pixels a numerical inverse cannot solve, and
        pixels at the pole, are NaN or inf: treat them as outside.

    Raises
    ------
    ArgumentError
        A bad ``output_shape``.
    SizeLimitError
        An output too large for this machine's memory.

    Notes
    -----
    Other resamplers take it directly: ``cv2.remap(image,
    pos[..., 0].astype(np.float32), pos[..., 1].astype(np.float32), ...)``;
    ``scipy.ndimage.map_coordinates(channel, [pos[..., 1], pos[..., 0]])``
    (row first).

    Examples
    --------
    >>> import numpy as np
    >>> import fpiwarp
    >>> shift = fpiwarp.RLinear(1, 0, 1 + 2j)             # moves content by (1, 2)
    >>> pos = fpiwarp.source_positions(shift, (2, 3))
    >>> (pos[1, 2].round(9) + 0.0).tolist()               # output pixel row 1, column 2
    [1.0, -1.0]
    """
    check_transform(transform)
    rows, cols = check_output_shape(output_shape, None)
    check_sizes((1, 1, 2), (rows, cols), np.float64, NUMPY, "numpy")
    out = np.empty((rows, cols, 2))
    for r0, r1, pos in iter_source_positions(transform, (rows, cols)):
        out[r0:r1] = pos
    return out
