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
    and for read-only sources across calls; kernels keep theirs on the
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


def frozen_source_key(image):
    """A key naming the pixels of ``image`` (an ndarray) for as long as they
    cannot change, or None when they can.

    Only read-only memory qualifies: ``image`` and every array it views
    (its ``.base`` chain) must have ``writeable=False``, and the chain must
    end at an array that owns its memory or at a ``bytes`` object (a
    read-only view of a writeable array, a memory map or a foreign buffer
    give None: someone else may write them). The key is the owner's
    identity and the view's address, shape, strides and dtype; a cache that
    holds the view keeps the owner alive, so the identity is not reused.
    (numpy lets the owner of an array set ``writeable=True`` again: a
    program that does so and writes must not rely on this key.)
    """
    if not isinstance(image, np.ndarray):
        return None
    owner = image
    while isinstance(owner, np.ndarray):
        if owner.flags.writeable:
            return None
        if owner.base is None:
            break
        if not isinstance(owner.base, (np.ndarray, bytes)):
            return None
        if isinstance(owner.base, bytes):
            break
        owner = owner.base
    address = image.__array_interface__["data"][0]
    return id(owner), address, image.shape, image.strides, image.dtype.str


class PyramidCache:
    """The pyramids of the last ``size`` read-only sources (see
    :func:`frozen_source_key`), built by ``build(image)``; thread-safe.
    :meth:`get` builds a pyramid for every other source without keeping it."""

    def __init__(self, build, size):
        self.build = build
        self.size = size
        self._lock = threading.Lock()
        self._entries = {}

    def get(self, image):
        key = frozen_source_key(image)
        if key is None:
            return self.build(image)
        with self._lock:
            hit = self._entries.pop(key, None)
            if hit is not None:
                self._entries[key] = hit  # most recent last
                return hit[1]
        built = self.build(image)
        with self._lock:
            self._entries[key] = (image, built)  # the view keeps its owner (the key's identity) alive
            while len(self._entries) > self.size:
                self._entries.pop(next(iter(self._entries)))
        return built

    def clear(self):
        """Forget every kept pyramid (and release their sources)."""
        with self._lock:
            self._entries.clear()
