"""The source pyramid antialiasing samples from: the numpy reference.

Level 0 is the source itself, sampled exactly as a plain warp samples it
(its dtype, the call's order). Level k >= 1 halves level k - 1: its size is
``ceil(h / 2) × ceil(w / 2)`` and its texel (i, j) is the mean of level
k - 1's texels (2i, 2j), (2i + 1, 2j), (2i, 2j + 1), (2i + 1, 2j + 1), an
index past the last row or column clamped to it (an odd edge averages its
last row or column with itself). Levels are built until both sides are 1
or :data:`~fpiwarp.block.sampling_rules.AA_MAX_LEVEL` is reached; kernels
hold levels >= 1 in float32 (exact for uint8 sources up to level 8, for
uint16 up to level 4: the means of 4^k integers), the reference in float64.

Level k's texel (i, j) is centred on the source position
((i + 0.5) · 2^k - 0.5, (j + 0.5) · 2^k - 0.5): a source position x is the
level coordinate ``(x + 0.5) / 2^k - 0.5`` (:func:`level_coordinate`).
Border modes act on a level's own indices and size as on the source's
(``wrap`` of an odd size tiles that level's size, a close approximation of
the source's period).

Levels >= 1 are interpolated bilinearly (they are already box-filtered;
the call's order applies to level 0).
"""

import threading

import numpy as np

from ..block.sampling_rules import AA_MAX_LEVEL
from .sampler import sample


def level_sizes(height, width):
    """[(h, w) of level 0, 1, ...] up to 1 × 1 or level AA_MAX_LEVEL.

    >>> level_sizes(5, 8)
    [(5, 8), (3, 4), (2, 2), (1, 1)]
    """
    sizes = [(int(height), int(width))]
    while len(sizes) <= AA_MAX_LEVEL and max(sizes[-1]) > 1:
        h, w = sizes[-1]
        sizes.append(((h + 1) // 2, (w + 1) // 2))
    return sizes


def halve(level):
    """The next level of an (h, w, c) level (float64), as described above."""
    h, w = level.shape[:2]
    r0 = np.arange(0, h, 2)
    r1 = np.minimum(r0 + 1, h - 1)
    c0 = np.arange(0, w, 2)
    c1 = np.minimum(c0 + 1, w - 1)
    top, bottom = level[r0], level[r1]
    return 0.25 * ((top[:, c0] + top[:, c1]) + (bottom[:, c0] + bottom[:, c1]))


def level_coordinate(x, k):
    """Level k's coordinate of source coordinate x (pixel centres at integers)."""
    if k == 0:
        return x
    scale = 2.0**k
    return (x + 0.5) / scale - 0.5


class Pyramid:
    """The levels of one (H, W, C) source, built once and reused by every
    antialiased warp of it (the numpy backend keeps one per call, per batch
    and across calls by :class:`SourcePyramids`; kernels keep theirs on the
    device). Levels >= 1 are built when first read (a shrink that stays at
    level 0 builds none); thread-safe."""

    def __init__(self, image):
        self.image = image
        self.sizes = level_sizes(*image.shape[:2])
        self._levels = [image]
        self._lock = threading.Lock()
        #: how many levels >= 1 this pyramid has built (tests count them)
        self.built = 0

    @property
    def top(self):
        """The index of the coarsest level."""
        return len(self.sizes) - 1

    def level(self, k):
        """Level k (0: the source itself; k >= 1: float64), built on first use."""
        if k >= len(self._levels):
            with self._lock:
                while len(self._levels) <= k:
                    self._levels.append(halve(np.asarray(self._levels[-1], dtype=np.float64)))
                    self.built += 1
        return self._levels[k]

    @property
    def levels(self):
        """Every level, 0 to top (builds the missing ones)."""
        self.level(self.top)
        return list(self._levels)

    def sample(self, k, x, y, order, mode, cval):
        """Sample level k at source positions x, y (float64, shape S + (C,)):
        level 0 with ``order``, coarser levels bilinearly."""
        if k == 0:
            return sample(self.image, x, y, order, mode, cval)
        return sample(self.level(k), level_coordinate(x, k), level_coordinate(y, k), 1, mode, cval)


#: Host sources whose pyramids a :class:`SourcePyramids` keeps across calls.
KEPT_SOURCES = 2
#: Larger host sources get a pyramid per call (keeping one means keeping a
#: copy of the source's pixels too).
KEPT_SOURCE_BYTES = 128 << 20


def _same_bytes(a, b):
    """Whether arrays ``a`` and ``b`` of one shape and dtype hold the same
    bytes, or None where they are not both C-contiguous. Compared as the
    widest unsigned words that divide their size: for a 1080p RGB picture
    less than half the time of ``np.array_equal`` element by element."""
    if not (a.flags.c_contiguous and b.flags.c_contiguous):
        return None
    word = next(np.dtype(f"u{n}") for n in (8, 4, 2, 1) if a.nbytes % n == 0)
    return np.array_equal(a.reshape(-1).view(word), b.reshape(-1).view(word))


def _same_pixels(kept, image):
    """Whether ``image`` has the shape, dtype and values of ``kept`` (NaNs
    equal to NaNs in float images). Equal bytes are equal values; unequal
    bytes of floats may still be (0.0 and -0.0, NaNs of other bits)."""
    if kept.shape != image.shape or kept.dtype != image.dtype:
        return False
    floats = image.dtype.kind in "fc"
    same = _same_bytes(kept, image)
    if same is None or (not same and floats):
        return np.array_equal(kept, image, equal_nan=floats)
    return same


class SourcePyramids:
    """The pyramids of the last ``size`` host (numpy) sources, kept across
    calls so that many maps over one image (the preview, a batch with one
    source, an animation, a :class:`fpiwarp.Warper` per frame) build its
    levels once: every backend's one rule for host sources.

    A kept pyramid is kept with a copy of the pixels it was built from and
    serves a call only while the source's shape, dtype and pixels equal
    that copy (``np.array_equal``, NaN equal to NaN): a writeable array
    changed in place gets new levels, never stale ones; another array of
    equal pixels is served the kept pyramid. (The comparison costs a
    fraction of a millisecond for a 1080p RGB picture, tens of times less
    than a build.) Sources over ``max_bytes`` are built for the call and
    not kept.

    ``build(pixels, *args)`` makes a pyramid: ``pixels`` is the kept copy
    (equal to the source and never written), ``args`` those given to
    :meth:`get` (a backend's device copy of the source, say). Thread-safe;
    :meth:`clear` frees every kept pyramid; :attr:`builds` counts the
    pyramids built (tests count reuse with it).
    """

    def __init__(self, build, size=KEPT_SOURCES, max_bytes=KEPT_SOURCE_BYTES, on_clear=None):
        self.build = build
        self.size = size
        self.max_bytes = max_bytes
        #: called (no arguments) after :meth:`clear`: a backend's other
        #: references to the kept pyramids go with them
        self.on_clear = on_clear
        #: pyramids built so far
        self.builds = 0
        self._lock = threading.Lock()
        self._entries = []  # [(copy of the pixels, pyramid)], most recent last

    def get(self, image, *args):
        """The pyramid of numpy ``image``: a kept one of equal pixels, else
        ``build(copy of image, *args)`` (kept when ``image`` is small enough)."""
        image = np.asarray(image)
        if image.nbytes > self.max_bytes:
            with self._lock:
                self.builds += 1
            return self.build(image, *args)
        with self._lock:
            for i in range(len(self._entries) - 1, -1, -1):
                pixels, pyramid = self._entries[i]
                if _same_pixels(pixels, image):
                    self._entries.append(self._entries.pop(i))
                    return pyramid
        pixels = np.array(image, copy=True)
        pixels.flags.writeable = False
        pyramid = self.build(pixels, *args)
        with self._lock:
            self.builds += 1
            self._entries.append((pixels, pyramid))
            del self._entries[:max(0, len(self._entries) - self.size)]
        return pyramid

    def __len__(self):
        with self._lock:
            return len(self._entries)

    def values(self):
        """The kept pyramids, least recently used first."""
        with self._lock:
            return [pyramid for _, pyramid in self._entries]

    def clear(self):
        """Forget every kept pyramid (and the copies of their pixels)."""
        with self._lock:
            self._entries.clear()
        if self.on_clear is not None:
            self.on_clear()
