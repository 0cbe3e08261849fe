"""Seeded case generators for testing maps and backends, like ``numpy.testing``.

The test suite and the benchmarks draw their quads and constrained
configurations from here, so that a test that checks "the benchmark's
configurations" checks exactly those, and a backend of your own can be
tested on the same cases. Everything takes a ``numpy.random.Generator``
(or a seed) and returns float64 ``(4, 2)`` arrays of ``(x, y)`` points; nothing
here needs more than numpy.

- :func:`random_quad`: a simple quad of radius about 1 around the origin,
  counter-clockwise in ``(x, y)``, convex or not;
- :func:`squashed`, :func:`mirrored`: a quad stretched along a random
  direction, or mirrored (its orientation reversed);
- :func:`unit_pairs`, :func:`mirrored_pairs`, :func:`broad_pairs`: lists of
  ``(src, dst)`` pairs: valid unit-size ones, ones of opposite orientation
  (no FPI joins them), and ones spread over scales, offsets, aspect ratios
  and near-degenerate corners (some refused, some ill-conditioned);
- :func:`constrained_configurations`: ``(src, dst, edges)`` triples for
  :class:`~fpiwarp.ConstrainedFPI` and :class:`~fpiwarp.LocalDeformation` on
  which the paper's construction (:data:`PAPER_CONSTRUCTION`) is fold-free.

Examples
--------
>>> import numpy as np
>>> import fpiwarp
>>> from fpiwarp.testing import random_quad, unit_pairs
>>> rng = np.random.default_rng(0)
>>> random_quad(rng).shape
(4, 2)
>>> src, dst = unit_pairs(rng, 1, offset=0.0)[0]
>>> bool(np.allclose(fpiwarp.FPI(src, dst)(src), dst))
True
"""

from __future__ import annotations

import numpy as np

#: The unit square centered at the origin, corners counter-clockwise in (x, y).
UNIT_SQUARE = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])

#: The paper's constrained construction (§4: 10 equally spread points per
#: edge, offset copies at δ = 0.01), the default before adaptive spacing.
PAPER_CONSTRUCTION = {"points_per_edge": 10, "spacing": "uniform", "delta": 0.01}

__all__ = ["PAPER_CONSTRUCTION", "UNIT_SQUARE", "broad_pairs", "constrained_configurations", "mirrored",
           "mirrored_pairs", "random_quad", "squashed", "unit_pairs"]


def _rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def random_quad(rng: np.random.Generator | int | None, convex: bool = True) -> np.ndarray:
    """A random simple quad of radius about 1 around the origin, counter-clockwise
    in (x, y); with ``convex=False`` one corner is pulled in to 15 % of its
    radius (a simple, usually non-convex quad)."""
    rng = _rng(rng)
    gaps = rng.uniform(0.35, 1.0, 4)
    angles = rng.uniform(0, 2 * np.pi) + np.cumsum(gaps / gaps.sum() * 2 * np.pi)
    radii = rng.uniform(0.4, 1.0, 4)
    if not convex:
        radii[rng.integers(4)] *= 0.15
    return radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def squashed(pts: np.ndarray, rng: np.random.Generator | int | None, aspect: float) -> np.ndarray:
    """``pts`` stretched by ``aspect`` along a random direction (aspect < 1 squashes)."""
    t = _rng(rng).uniform(0, np.pi)
    c, s = np.cos(t), np.sin(t)
    rot = np.array([[c, -s], [s, c]])
    return np.asarray(pts, dtype=np.float64) @ rot @ np.diag([1.0, aspect]) @ rot.T


def mirrored(pts: np.ndarray) -> np.ndarray:
    """``pts`` mirrored in the y axis: the same quad of the other orientation."""
    return np.asarray(pts, dtype=np.float64) * np.array([-1.0, 1.0])


def unit_pairs(rng: np.random.Generator | int | None, n: int, offset: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` valid pairs of unit-size quads of the same orientation (half of
    them clockwise), both moved by ``offset``."""
    rng = _rng(rng)
    out = []
    for _ in range(n):
        z, w = random_quad(rng), random_quad(rng)
        if rng.random() < 0.5:
            z, w = mirrored(z), mirrored(w)
        out.append((z + offset, w + offset))
    return out


def mirrored_pairs(rng: np.random.Generator | int | None, n: int,
                   offset: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` pairs of opposite orientation (no orientation-preserving map joins them)."""
    return [(z + offset, mirrored(w) + offset) for z, w in unit_pairs(rng, n, 0.0)]


def broad_pairs(rng: np.random.Generator | int | None, n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` pairs spread over scales 1e-6..1e9, offsets up to 1e9, aspect ratios
    up to 1e9 (thin quads) and near-degenerate corners, 5 % mirrored: a fuzz
    of what FPI must either build exactly or refuse with a clear error."""
    rng = _rng(rng)
    out = []
    for _ in range(n):
        quads = []
        for _ in range(2):
            q = random_quad(rng, convex=rng.random() < 0.8)
            kind = rng.random()
            if kind < 0.4:
                q = squashed(q, rng, 10.0 ** -rng.uniform(0, 9))
            elif kind < 0.5:  # one corner pulled close to the line of its neighbours
                k = rng.integers(4)
                a, b = q[(k - 1) % 4], q[(k + 1) % 4]
                q[k] = 0.5 * (a + b) + (q[k] - 0.5 * (a + b)) * 10.0 ** -rng.uniform(0, 9)
            quads.append(q)
        z, w = quads
        if rng.random() < 0.05:
            w = mirrored(w)
        scale = 10.0 ** rng.uniform(-6, 9)
        offset = rng.choice([0.0, 1.0]) * 10.0 ** rng.uniform(0, 9) * rng.choice([-1, 1], size=2)
        out.append((z * scale + offset, w * scale + offset * rng.uniform(0.5, 2)))
    return out


def constrained_configurations(n: int, seed: int = 16, grid_n: int = 41,
                               construction: dict | None = None) -> list[tuple[np.ndarray, np.ndarray, tuple]]:
    """``n`` seeded ``(src, dst, edges)`` configurations of a constrained map.

    src is :data:`UNIT_SQUARE` with every corner moved by 0.3 N(0, 1), dst
    is src with every corner moved by 0.3 N(0, 1) again, the constrained
    edges (0, 2) or (1, 3) with equal odds; a configuration is kept when a
    :class:`~fpiwarp.ConstrainedFPI` and a :class:`~fpiwarp.LocalDeformation`
    (the paper's construction) can be built with ``construction`` (default
    :data:`PAPER_CONSTRUCTION`)
    and that ConstrainedFPI's Jacobian determinant is positive on a
    ``grid_n`` × ``grid_n`` grid spanning src (no fold-over). The same
    ``n``, ``seed`` and ``grid_n`` give the same list, and a shorter list is
    a prefix of a longer one.
    """
    from .maps.constrained import ConstrainedFPI
    from .maps.local import LocalDeformation
    from .metrics import grid, jacobian_determinant

    kw = dict(PAPER_CONSTRUCTION if construction is None else construction)
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        src = UNIT_SQUARE + 0.3 * rng.standard_normal((4, 2))
        dst = src + 0.3 * rng.standard_normal((4, 2))
        edges = (0, 2) if rng.random() < 0.5 else (1, 3)
        try:
            f = ConstrainedFPI(src, dst, edges, **kw)
            LocalDeformation(src, dst, edges, construction="paper", **kw)
        except ValueError:
            continue
        if np.min(jacobian_determinant(f, grid(src, grid_n))) > 0:
            out.append((src, dst, edges))
    return out
