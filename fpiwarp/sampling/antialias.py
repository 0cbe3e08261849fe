"""Antialiased sampling from the analytic Jacobian: the numpy reference.

Each output pixel is the average of its pixel square's footprint in the
source. The footprint of the square centred at output pixel q is taken
from the inverse map's Jacobian J at q (``transform.inverse``, analytic):
the parallelogram p + J·(s, t), s, t in [-1/2, 1/2], p the pixel's source
position. Its two edge vectors are the columns of J: J·(1, 0), the source
displacement of one output step in x, of length ``Lx``, and J·(0, 1), of
length ``Ly``.

The footprint is supersampled on a grid aligned with those edge vectors,
``nx`` by ``ny`` sub-samples (:func:`tap_counts` of Lx and Ly: 1 where
the edge does not shrink, else about L / AA_SPACING but at least 2, at most
AA_MAX_TAPS), at s = (2i + 1 - nx) / (2 nx) and
t = (2j + 1 - ny) / (2 ny), each interpolated with the chosen order and
border mode and averaged with equal weights (a box filter over the
footprint). So:

* sub-samples lie at most AA_SPACING (1.25) source pixels apart along each
  edge (AA_FAR_SPACING, 1.75, beyond AA_KNEE_TAPS of them), which together
  with the interpolation's own low-pass keeps the average close to the
  exact box integral (see the benchmark's antialiasing section);
* the two axes are counted separately: a footprint shrunk in one direction
  only is sampled densely along that direction only (anisotropic);
* where the map magnifies or keeps the scale (Lx, Ly <= 1 + AA_SLACK),
  nx = ny = 1 and the pixel is plain interpolation at p, bit for bit;
* the work is bounded: at most AA_MAX_TAPS² sub-samples per pixel (a
  pixel next to the pole, whose footprint is huge, reads at most that
  many, sparsely); a NaN Jacobian counts as magnifying;
* border modes act on every sub-sample's taps as in
  :func:`fpiwarp.sampling.sampler.sample`; a pixel whose own source position is
  not finite or beyond COORD_LIMIT gives cval (the pole rule), and a
  sub-sample beyond COORD_LIMIT contributes cval.
"""

import numpy as np

from ..block.sampling_rules import (
    AA_BLEND,
    AA_FAR_SPACING,
    AA_KNEE_TAPS,
    AA_LEVEL_SPAN,
    AA_MAX_TAPS,
    AA_SLACK,
    AA_SPACING,
    COORD_LIMIT,
)
from ..maps.transform import unsolved_as_nan
from .positions import CHUNK_PIXELS, pixel_grid
from .pyramid import Pyramid
from .sampler import sample


def tap_counts(edge):
    """Sub-samples along a footprint edge of complex length vector ``edge``
    (source pixels per output pixel): int array, 1..AA_MAX_TAPS. Lengths
    L <= 1 + AA_SLACK (and NaN) give 1, others ceil(min(L / AA_SPACING,
    max(AA_KNEE_TAPS, L / AA_FAR_SPACING)) - AA_SLACK) but at least 2
    (infinite ones AA_MAX_TAPS).

    >>> tap_counts(np.array([0.5, 1.0, 1.2, 2.0, 2.4, 3.0, 5.0, 8.0, 9.0, np.inf])).tolist()
    [1, 1, 2, 2, 2, 3, 4, 5, 6, 16]
    """
    with np.errstate(invalid="ignore", over="ignore"):
        length = np.abs(edge)
        length = np.where(np.isnan(length), 0.0, length)
        n = np.minimum(length / AA_SPACING, np.maximum(AA_KNEE_TAPS, length / AA_FAR_SPACING))
        n = np.maximum(np.ceil(n - AA_SLACK), 2.0)
    return np.where(length <= 1.0 + AA_SLACK, 1, np.clip(n, 1, AA_MAX_TAPS)).astype(np.int64)


def footprint_edges(fz, fzb):
    """The footprint's edge vectors J·(1, 0) and J·(0, 1), as complex
    numbers, from the inverse map's Wirtinger derivatives."""
    return fz + fzb, 1j * (fz - fzb)


def pyramid_levels(ex, ey, top):
    """The pyramid level each footprint is supersampled at, and the weight
    of the next level: (k, u), int and float64 arrays of the edges' shape.

    k = floor(lod), lod = log2(L_short · (1 + AA_SLACK) / AA_LEVEL_SPAN)
    clamped to [0, top], L_short the shorter edge's length (NaN counts as
    0); u = clamp((frac(lod) - 1 + AA_BLEND) / AA_BLEND, 0, 1), 0 at the top
    level.

    >>> short = np.array([1.0, 3.9, 4.0, 8.0, 15.0, 64.0]) + 0j
    >>> k, u = pyramid_levels(short, 2 * short, 3)
    >>> k.tolist(), np.round(u, 3).tolist()
    ([0, 0, 1, 2, 2, 3], [0.0, 0.911, 0.0, 0.0, 0.685, 0.0])
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        short = np.minimum(np.abs(ex), np.abs(ey))
        short = np.where(np.isnan(short), 0.0, short)
        lod = np.clip(np.log2(np.maximum(short * (1.0 + AA_SLACK) / AA_LEVEL_SPAN, 1.0)), 0.0, top)
    k = np.floor(lod).astype(np.int64)
    u = np.clip((lod - k - 1.0 + AA_BLEND) / AA_BLEND, 0.0, 1.0)
    return k, np.where(k >= top, 0.0, u)


def level_taps(ex, ey, k):
    """(nx, ny): :func:`tap_counts` of the edges measured in level-k texels
    (``k`` an int or an int array of the edges' shape)."""
    scale = 2.0**k
    with np.errstate(invalid="ignore"):  # infinite edges next to the pole
        return tap_counts(ex / scale), tap_counts(ey / scale)


def sample_counts(ex, ey, top):
    """The sub-samples the reference reads for each footprint (edges ex,
    ey; ``top`` the pyramid's coarsest level): 1 where both level-0 counts
    are 1 (plain interpolation), else nx·ny at level k plus, where the
    blend weight u > 0, nx·ny at level k + 1 (:func:`pyramid_levels`).
    At most 2 · AA_MAX_TAPS² (the bound on work per pixel).

    >>> sample_counts(np.array([0.5, 3.0, 8.0, 7.5 + 0.1j]), np.array([0.5j, 3j, 8j, 7.5j]), 10).tolist()
    [1, 9, 4, 13]
    """
    k, u = pyramid_levels(ex, ey, top)
    nx, ny = level_taps(ex, ey, k)
    nx1, ny1 = level_taps(ex, ey, k + 1)
    counts = nx * ny + np.where(u > 0, nx1 * ny1, 0)
    return np.where((tap_counts(ex) > 1) | (tap_counts(ey) > 1), counts, 1)


def supersample(pyramid, k, x, y, ex, ey, order, mode, cval):
    """The box average of footprints (1-D arrays: source positions x, y,
    edges ex, ey) supersampled at level ``k`` (one int for all): tap_counts
    of the edges in level-k texels per edge, sub-samples at the source
    positions p + ex·s + ey·t as described in the module docstring."""
    nx, ny = level_taps(ex, ey, k)
    acc = np.zeros((x.size, pyramid.image.shape[-1]))
    for j in range(int(ny.max(initial=1))):
        for i in range(int(nx.max(initial=1))):
            live = np.flatnonzero((i < nx) & (j < ny))
            s = (2 * i + 1 - nx[live]) / (2 * nx[live])
            t = (2 * j + 1 - ny[live]) / (2 * ny[live])
            d = ex[live] * s + ey[live] * t
            acc[live] += pyramid.sample(k, x[live] + d.real, y[live] + d.imag, order, mode, cval)
    return acc / (nx * ny)[:, None]


def sample_antialiased(image, pos, ex, ey, order=1, mode="constant", cval=0.0, pyramid=None):
    """Average ``image`` (H, W, C) over the footprints of output pixels at
    source positions ``pos`` (shape S + (2,), float64) with complex edge
    vectors ``ex``, ``ey`` (shape S), reading the levels of ``pyramid`` (a
    :class:`~fpiwarp.sampling.pyramid.Pyramid` of ``image``, built here
    when None). Float64 values S + (C,), before rounding; plain
    :func:`sample` where both level-0 counts are 1."""
    x, y = pos[..., 0], pos[..., 1]
    shrinks = (tap_counts(ex) > 1) | (tap_counts(ey) > 1)
    if not shrinks.any():
        return sample(image, x, y, order, mode, cval)
    out = np.empty(x.shape + (image.shape[-1],))
    flat_out = out.reshape(-1, out.shape[-1])
    plain, multi = np.flatnonzero(~shrinks), np.flatnonzero(shrinks)
    if plain.size:  # sampling is pointwise: the same values as sampling every pixel
        flat_out[plain] = sample(image, x.reshape(-1)[plain], y.reshape(-1)[plain], order, mode, cval)
    pyramid = Pyramid(image) if pyramid is None else pyramid
    x, y = x.reshape(-1)[multi], y.reshape(-1)[multi]
    ex, ey = ex.reshape(-1)[multi], ey.reshape(-1)[multi]
    level, blend = pyramid_levels(ex, ey, pyramid.top)
    values = np.zeros((multi.size, out.shape[-1]))
    for k in np.unique(level):
        sel = np.flatnonzero(level == k)
        here = supersample(pyramid, int(k), x[sel], y[sel], ex[sel], ey[sel], order, mode, cval)
        values[sel] = (1.0 - blend[sel, None]) * here
        up = sel[blend[sel] > 0]
        if up.size:
            values[up] += blend[up, None] * supersample(pyramid, int(k) + 1, x[up], y[up], ex[up], ey[up],
                                                        order, mode, cval)
    cval = np.broadcast_to(np.asarray(cval, dtype=np.float64), (out.shape[-1],))
    with np.errstate(invalid="ignore"):
        finite = (np.abs(x) <= COORD_LIMIT) & (np.abs(y) <= COORD_LIMIT)
    flat_out[multi] = np.where(finite[:, None], values, cval)
    return out


def iter_footprints(transform, output_shape, chunk_pixels=CHUNK_PIXELS):
    """Like :func:`fpiwarp.sampling.positions.iter_source_positions`, with each
    band's footprint edges: yield (row_start, row_stop, positions, ex, ey).
    Positions are exactly those of the plain warp; the edges come from the
    analytic Wirtinger derivatives of ``transform.inverse``."""
    inverse = transform.inverse
    rows, cols = output_shape
    band = max(1, chunk_pixels // cols)
    for r0 in range(0, rows, band):
        r1 = min(rows, r0 + band)
        grid = pixel_grid(r0, r1, cols)
        with unsolved_as_nan(), np.errstate(all="ignore"):
            pos = inverse(grid)
            _, fz, fzb = inverse.wirtinger(grid[..., 0] + 1j * grid[..., 1])
        ex, ey = footprint_edges(fz, fzb)
        yield r0, r1, pos, ex, ey
