"""The numpy backend: the float64 reference every other backend matches."""

import numpy as np

from .._sampling import sample, to_dtype
from .._transform import unsolved_as_nan

#: Output pixels processed per chunk, to bound memory on large images.
CHUNK_PIXELS = 1 << 19


def source_positions(inverse, grid):
    """Where output pixels sample the source: ``inverse(grid)``, with points
    a numerical inverse cannot solve coming out NaN (cval), as on devices."""
    with unsolved_as_nan():
        return inverse(grid)


def probe():
    return None


class Backend:
    name = "numpy"

    def map_points(self, transform, points):
        return transform(points)

    def warp_image(self, image, transform, output_shape, *, order, mode, cval):
        inverse = transform.inverse
        oh, ow = output_shape
        out = np.empty((oh, ow, image.shape[2]), dtype=image.dtype)
        rows_per_chunk = max(1, CHUNK_PIXELS // ow)
        xs = np.arange(ow, dtype=np.float64)
        for r0 in range(0, oh, rows_per_chunk):
            r1 = min(oh, r0 + rows_per_chunk)
            grid = np.empty((r1 - r0, ow, 2))
            grid[..., 0] = xs
            grid[..., 1] = np.arange(r0, r1, dtype=np.float64)[:, None]
            src = source_positions(inverse, grid)
            values = sample(image, src[..., 0], src[..., 1], order, mode, cval)
            out[r0:r1] = to_dtype(values, image.dtype)
        return out
