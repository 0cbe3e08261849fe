"""The whole-plane local deformation operator of paper §4.1.

Inside the region of interest the constrained FPI; beyond each
constrained edge's line, that edge's similarity (opposite edges: one on
each side; adjacent edges: the shared one beyond both lines). The parts
are chosen by the parameter block's region rule (see
:mod:`fpiwarp.block`): a point z lies in region r when depth_r =
Re((z - o_r) conj(n_r)) > 0, o_r a point on the line and n_r the unit
outward normal (so depth is the distance beyond the line); if it lies in
both, the larger depth wins; otherwise the constrained FPI applies.

Both quads must lie on the inner side of each constrained edge's line
(convex at the ends of the constrained edges), otherwise part of the quad
would follow the outer similarity: such input is refused.

Consequences of that rule, stated once:

- Across the constrained edges themselves the map jumps by no more than
  the constrained FPI strays from each edge's similarity along the edge:
  over 320 random fold-free configurations (benchmarks/seams.py), with
  the defaults (16 adaptively spaced points per edge, δ 0.002) median
  1.1e-4 of the (output) edge length, p90 2.3e-4, at most 6.0e-4 (0.3 px
  on a 500-px edge); with the paper's construction (points_per_edge=10,
  delta=0.01, spacing="uniform") median 2.5e-3, p90 5.2e-3, at most
  2.0e-2 (10 px).
- Beyond the free edges there is no third region: the strip (or wedge)
  between the two lines, continued past the free edges, keeps the
  constrained FPI, with its pole if it has one there. Along the lines'
  continuations beyond the constrained edges' ends the constrained FPI
  and the similarity generally disagree: the map jumps there (measured,
  relative to the edge length: about 1e-2 a twentieth of the edge past a
  corner, 1e-1 a quarter past it, median; up to 0.1 and 0.8; the edge
  points' spacing does not change this). Place the
  quad so the shape to deform crosses the region of interest through the
  constrained edges, as in the paper's figures.
- Opposite edges whose lines are not parallel meet at a point; in the
  wedge beyond both lines, the nearer line's similarity does NOT apply,
  the farther one's does (largest depth): the two similarities meet on
  the bisector of the lines, where they differ in general, so the map
  jumps along that bisector ray. With adjacent edges both regions carry
  the same similarity and no jump arises there.

The inverse uses the same rule in the output: region r beyond the image
line S_r(line r) with normal a_r n_r / |a_r|², so depths are preserved
exactly (depth'(S_r z) = depth_r(z)); the inner part is the constrained
FPI's numerical inverse. It is the exact inverse wherever the forward map
is one-to-one (the region of interest and the outer half-planes near it);
in the places listed above where the forward map jumps, images of
different parts may overlap or leave gaps, and there the inverse picks
by the same rule.
"""

import dataclasses

import numpy as np
from numpy.typing import ArrayLike

from ..block import Region, Stage
from .constrained import ConstrainedFPI, as_mobius, edge_similarity, shared_similarity
from .quad import signed_area
from .transform import Transform


def _check_line_bounds(q, k, outward, name):
    """Refuse a quad that reaches beyond the line of its constrained edge k
    (non-convex at one of the edge's ends): there the outer similarity
    would take over inside the region of interest."""
    scale = float(np.max(np.abs(q - q.mean())))
    depth = ((q - q[k]) * np.conj(outward)).real
    beyond = np.flatnonzero(depth > 1e-9 * scale)
    if beyond.size:
        raise ValueError(
            f"{name} point {int(beyond[0])} lies beyond the line of constrained edge {k} "
            f"({name} is not convex at an end of that edge): the outer similarity would "
            "apply inside the region of interest; constrain other edges or make the quad convex there"
        )


class LocalDeformation(Transform):
    """Constrained FPI inside the region of interest, similarities outside.

    Parameters are those of :class:`~fpiwarp.ConstrainedFPI` (``src``,
    ``dst``, ``edges``, ``points_per_edge``, ``delta``). Opposite
    edges give two outer half-planes, each following its edge's
    similarity; adjacent edges give one shared similarity beyond both
    lines (dst must be src under one similarity at their three corners,
    or ValueError). Both quads must lie on the inner side of each
    constrained edge's line (convex at the ends of the constrained edges),
    or ValueError. See the module docstring for what happens beyond the
    free edges and where the outer half-planes meet.

    Parameters
    ----------
    src, dst : array_like, shape (4, 2)
        The region of interest and where its corners go, ``(x, y)``.
    edges : pair of int
        The constrained edges; edge k joins point k and point k + 1.
    points_per_edge, delta, spacing
        As in :class:`~fpiwarp.ConstrainedFPI` (defaults: as many points
        as the block holds as pairs, δ 0.002, adaptive spacing).

    Raises
    ------
    DegenerateQuadError, FoldOverError
        As :class:`~fpiwarp.ConstrainedFPI`.
    ValueError
        Edges that cannot be constrained as asked, or quads on the outer
        side of a constrained edge's line (see above).

    Examples
    --------
    >>> f = LocalDeformation([[0, 0], [2, 0], [2, 1], [0, 1]],
    ...                      [[0, 0], [2, 0], [2.2, 1.1], [0, 1]], edges=(3, 1))
    >>> np.round(f([[-5.0, 0.5], [9.0, 0.5]]), 9).tolist()   # identity left, far edge's similarity right
    [[-5.0, 0.5], [9.8, -0.85]]
    """

    def __init__(
        self,
        src: ArrayLike,
        dst: ArrayLike,
        edges: tuple[int, int],
        points_per_edge: int | None = None,
        delta: float = 0.002,
        spacing: str = "adaptive",
    ):
        inner = ConstrainedFPI(
            src, dst, edges=edges, points_per_edge=points_per_edge, delta=delta, spacing=spacing
        )
        z, w = inner._z, inner._w
        orient = np.sign(signed_area(z))
        i, j = inner.edges
        if inner.kind == "adjacent":
            sims = [shared_similarity(z, w, i)] * 2
        else:
            sims = [edge_similarity(z, w, i), edge_similarity(z, w, j)]
        regions = []
        for k, (a, b) in zip((i, j), sims):
            e = z[(k + 1) % 4] - z[k]
            outward = -1j * e / abs(e) * orient
            _check_line_bounds(z, k, outward, "src")
            _check_line_bounds(w, k, a * outward / abs(a), "dst")
            regions.append(Region(origin=complex(z[k]), normal=complex(outward), a=complex(a), b=complex(b)))
        self._init_parts(inner, tuple(regions))

    def _init_parts(self, inner, regions):
        self.inner, self.regions = inner, regions

    @classmethod
    def _from_parts(cls, inner, regions):
        obj = cls.__new__(cls)
        obj._init_parts(inner, regions)
        return obj

    @property
    def src(self):
        return self.inner.src

    @property
    def dst(self):
        return self.inner.dst

    @property
    def edges(self):
        return self.inner.edges

    def _select(self, z):
        """Index of the winning region per point, -1 for the inner part
        (the block's rule: largest depth > 0 wins)."""
        best = np.zeros(np.shape(z))
        which = np.full(np.shape(z), -1)
        for r, reg in enumerate(self.regions):
            depth = ((z - reg.origin) * np.conj(reg.normal)).real
            win = depth > best
            best = np.where(win, depth, best)
            which = np.where(win, r, which)
        return which

    def _map(self, z):
        z = np.asarray(z, dtype=np.complex128)
        which = self._select(z)
        out = np.empty_like(z)
        inside = which < 0
        out[inside] = self.inner.map_complex(z[inside])
        for r, reg in enumerate(self.regions):
            sel = which == r
            out[sel] = reg.a * z[sel] + reg.b
        return out

    def _wirtinger(self, z):
        z = np.asarray(z, dtype=np.complex128)
        which = self._select(z)
        w, fz, fzb = np.empty_like(z), np.empty_like(z), np.zeros_like(z)
        inside = which < 0
        w[inside], fz[inside], fzb[inside] = self.inner.wirtinger(z[inside])
        for r, reg in enumerate(self.regions):
            sel = which == r
            w[sel] = reg.a * z[sel] + reg.b
            fz[sel] = reg.a
        return w, fz, fzb

    @property
    def inverse(self):
        regions = tuple(
            Region(
                origin=reg.a * reg.origin + reg.b,
                normal=reg.a * reg.normal / abs(reg.a) ** 2,
                a=1 / reg.a,
                b=-reg.b / reg.a,
            )
            for reg in self.regions
        )
        return LocalDeformation._from_parts(self.inner.inverse, regions)

    def _fuse_with(self, nxt):
        """A following similarity joins the stage: the inner part's
        post-Möbius and each region's similarity absorb it."""
        m = as_mobius(nxt)
        if m is None or m.s != 0:
            return None
        inner = self.inner._fuse_with(m)
        regions = tuple(
            Region(origin=r.origin, normal=r.normal, a=m.alpha * r.a, b=m.map_complex(np.complex128(r.b)))
            for r in self.regions
        )
        return LocalDeformation._from_parts(inner, regions)

    def stages(self) -> list[Stage]:
        return [dataclasses.replace(self.inner.stage(), regions=self.regions)]

    def __repr__(self):
        return f"LocalDeformation(src={self.src.tolist()}, dst={self.dst.tolist()}, edges={self.edges})"
