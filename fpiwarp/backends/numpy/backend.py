"""The numpy backend: the float64 reference every other backend matches.

It samples with :mod:`fpiwarp.sampling.sampler` at the positions of
:mod:`fpiwarp.sampling.positions`, in bands of rows to bound memory. It batches
(:meth:`Backend.warp_batch`: a stack warped by one map is sampled in one
pass over the map, as one image of N·C channels) and binds maps
(:meth:`Backend.bind`: the source positions of one map are computed once
per output size and shared by the images warped after).

Antialiased warps read a source pyramid (:mod:`fpiwarp.sampling.pyramid`),
built once per call (its levels when first needed), once per batch for
images that are one source (a stack warped by one map is one wide image; a
stack of equal images with one map each shares the pyramid of consecutive
equal images), and kept across calls for the last few sources by
:class:`~fpiwarp.sampling.pyramid.SourcePyramids` (every backend's rule: a
kept pyramid serves a source only while its pixels equal the copy kept
with it, so an array changed in place is never served stale levels).
"""

import collections
import threading

import numpy as np

from ...sampling.antialias import iter_footprints, sample_antialiased
from ...sampling.positions import CHUNK_PIXELS, iter_source_positions, source_positions
from ...sampling.pyramid import Pyramid, SourcePyramids
from ...sampling.sampler import sample, to_dtype

#: Source-position maps a bound map keeps (one per output size).
MAP_CACHE_SIZE = 2
#: The kept pyramids (see the module docstring; each holds a copy of its
#: source and float64 levels of about 2/3 of its samples); ``PYRAMIDS.clear()``
#: frees them.
PYRAMIDS = SourcePyramids(Pyramid)


def probe():
    return None


def sample_bands(image, bands, output_shape, order, mode, cval):
    """Sample (H, W, C) ``image`` at (row_start, row_stop, positions) bands
    covering ``output_shape``; an array of the image's dtype."""
    oh, ow = output_shape
    out = np.empty((oh, ow, image.shape[2]), dtype=image.dtype)
    for r0, r1, pos in bands:
        values = sample(image, pos[..., 0], pos[..., 1], order, mode, cval)
        out[r0:r1] = to_dtype(values, image.dtype)
    return out


def sample_footprints(image, bands, output_shape, order, mode, cval, pyramid=None):
    """Like :func:`sample_bands` with antialiasing: (row_start, row_stop,
    positions, ex, ey) bands (see :mod:`fpiwarp.sampling.antialias`), all
    reading one ``pyramid`` of ``image`` (from :data:`PYRAMIDS` when None)."""
    oh, ow = output_shape
    out = np.empty((oh, ow, image.shape[2]), dtype=image.dtype)
    pyramid = PYRAMIDS.get(image) if pyramid is None else pyramid
    for r0, r1, pos, ex, ey in bands:
        out[r0:r1] = to_dtype(sample_antialiased(image, pos, ex, ey, order, mode, cval, pyramid), image.dtype)
    return out


def _bands_of(positions):
    """(row_start, row_stop, positions) bands of a precomputed (rows, cols, 2) map."""
    oh, ow = positions.shape[:2]
    rows = max(1, CHUNK_PIXELS // ow)
    for r0 in range(0, oh, rows):
        r1 = min(oh, r0 + rows)
        yield r0, r1, positions[r0:r1]


class BoundMap:
    """One map on the numpy backend, its source positions computed once per
    output size (the last :data:`MAP_CACHE_SIZE` sizes kept; thread-safe)."""

    def __init__(self, transform):
        self.transform = transform
        self._lock = threading.Lock()
        self._positions = collections.OrderedDict()

    def positions(self, output_shape):
        """Read-only float64 (rows, cols, 2) source positions (see fpiwarp.source_positions)."""
        shape = tuple(output_shape)
        with self._lock:
            if shape in self._positions:
                self._positions.move_to_end(shape)
                return self._positions[shape]
        pos = source_positions(self.transform, shape)
        pos.flags.writeable = False
        with self._lock:
            self._positions[shape] = pos
            while len(self._positions) > MAP_CACHE_SIZE:
                self._positions.popitem(last=False)
        return pos

    def warp_image(self, image, output_shape, *, order, mode, cval, antialias=False, pyramid=None):
        """Like :meth:`Backend.warp_image` with this map (antialiased warps'
        footprints are evaluated per call; their pyramid as described in the
        module docstring)."""
        if antialias:
            return sample_footprints(image, iter_footprints(self.transform, output_shape), output_shape, order, mode,
                                     cval, pyramid)
        return sample_bands(image, _bands_of(self.positions(output_shape)), output_shape, order, mode, cval)


class Backend:
    """The float64 reference (see the module docstring)."""

    name = "numpy"
    #: antialiasing's pyramids of recent host sources (every backend has one)
    host_pyramids = PYRAMIDS

    def map_points(self, transform, points):
        return transform(points)

    def warp_image(self, image, transform, output_shape, *, order, mode, cval, antialias=False, pyramid=None):
        if antialias:
            return sample_footprints(image, iter_footprints(transform, output_shape), output_shape, order, mode, cval,
                                     pyramid)
        bands = iter_source_positions(transform, output_shape)
        return sample_bands(image, bands, output_shape, order, mode, cval)

    def bind(self, transform):
        """A :class:`BoundMap`: ``transform`` ready to warp many images."""
        return BoundMap(transform)

    def warp_batch(self, stack, transforms, output_shape, *, order, mode, cval, antialias=False):
        """Warp a validated (N, H, W, C) stack; ``transforms`` holds one map
        for all images or one per image. One map: all N images are sampled
        in one pass over it, as one (H, W, N·C) image. One map each:
        consecutive equal images share one pyramid when antialiasing."""
        n, h, w, c = stack.shape
        if len(transforms) == 1:
            wide = np.ascontiguousarray(stack.transpose(1, 2, 0, 3)).reshape(h, w, n * c)
            flat = self.warp_image(wide, transforms[0], output_shape, order=order, mode=mode, cval=np.tile(cval, n),
                                   antialias=antialias)
            return flat.reshape(output_shape[0], output_shape[1], n, c).transpose(2, 0, 1, 3)
        out, pyramid = [], None
        for i, (image, t) in enumerate(zip(stack, transforms, strict=True)):
            if antialias and (pyramid is None or not np.array_equal(image, stack[i - 1])):
                pyramid = PYRAMIDS.get(image)
            out.append(self.warp_image(image, t, output_shape, order=order, mode=mode, cval=cval, antialias=antialias,
                                       pyramid=pyramid))
        return np.stack(out)
