"""The whole-plane local deformation operator of paper §4.1.

Two constructions (``construction=``):

- "continuous" (the default): the constrained FPI is fitted on the region
  of interest with each constrained edge extended along its line to where
  the line (in src) or its image (in dst) leaves the picture's extent
  (``extent=(width, height)`` or ``(x0, y0, x1, y1)``; default the box of
  src and dst grown by its larger side on every side), the ROI's corners
  pinned as exact constraint points. Along the whole lines inside the
  extent the map then follows each edge's similarity to 1e-3 of the
  extended edge's length (the edge bound, guaranteed by the default
  spacing), so it is continuous over the picture to that bound:
  benchmarks/local_continuity.py measures the largest jump between
  neighbouring pixels of a 1920x1080 output at 0.004 to 1.4 px (median
  0.11) against 17 to 395 px (median 117) for "paper". The price: the
  band between the two lines bends over the whole picture, not only near
  the ROI (maximal distortion over the ROI median 1.02x, up to 1.18x the
  paper's; over the picture up to ~1.5x), and the float32 kernels'
  inverse is ~3x less exact (~1e-2 px). Opposite edges whose lines (in
  src) or whose lines' images (in dst) meet inside the extent are refused
  (ConstraintError): the two similarities disagree at that point and no
  continuous map follows both. Beyond the extent the lines are not
  pinned and the map drifts from the similarities gradually.
- "paper": the constrained FPI fitted on the region of interest itself,
  as in the paper; the rest of this docstring describes its seams.

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
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..block import Region, Stage
from ..errors import ArgumentError, ConstraintError
from .constrained import EDGE_BOUND, ConstrainedFPI, as_mobius, edge_similarity, normalize_edges, shared_similarity
from .points import as_xy
from .quad import check_quad_pair, signed_area
from .transform import Transform

#: Constructions (``construction=``): "continuous" fits the constrained
#: FPI on the region of interest's constrained edges extended over the
#: picture (its extent); "paper" on the region of interest itself (§4.1).
CONSTRUCTIONS = ("continuous", "paper")
#: extent=None: the bounding box of src and dst grown on every side by
#: this many times its larger side.
EXTENT_MARGIN = 1.0


def _check_line_bounds(q, k, outward, name):
    """Refuse a quad that reaches beyond the line of its constrained edge k
    (non-convex at one of the edge's ends): there the outer similarity
    would take over inside the region of interest."""
    scale = float(np.max(np.abs(q - q.mean())))
    depth = ((q - q[k]) * np.conj(outward)).real
    beyond = np.flatnonzero(depth > 1e-9 * scale)
    if beyond.size:
        raise ConstraintError(
            f"{name} point {int(beyond[0])} lies beyond the line of constrained edge {k} "
            f"({name} is not convex at an end of that edge): the outer similarity would "
            "apply inside the region of interest; constrain other edges or make the quad convex there"
        )


def _extent_box(z, w, extent):
    """(x0, y0, x1, y1) of the picture: ``extent`` as (width, height) or
    (x0, y0, x1, y1), None: the quads' box grown by EXTENT_MARGIN."""
    if extent is None:
        both = np.concatenate([z, w])
        lo = complex(both.real.min(), both.imag.min())
        hi = complex(both.real.max(), both.imag.max())
        pad = EXTENT_MARGIN * max(hi.real - lo.real, hi.imag - lo.imag)
        return lo.real - pad, lo.imag - pad, hi.real + pad, hi.imag + pad
    try:
        box = [float(v) for v in extent]
    except (TypeError, ValueError):
        box = []
    if len(box) == 2:
        box = [0.0, 0.0, *box]
    if len(box) != 4 or not all(np.isfinite(box)) or box[2] <= box[0] or box[3] <= box[1]:
        raise ArgumentError(
            f"extent must be (width, height) or (x0, y0, x1, y1) of the picture with x1 > x0 and y1 > y0, "
            f"got {extent!r}"
        )
    return tuple(box)


def _line_in_box(p0, e, box):
    """The range (lo, hi) of t where p0 + t e lies in the box, or None."""
    lo, hi = -np.inf, np.inf
    for start, step, a, b in ((p0.real, e.real, box[0], box[2]), (p0.imag, e.imag, box[1], box[3])):
        if abs(step) < 1e-300:
            if not a <= start <= b:
                return None
            continue
        t0, t1 = sorted(((a - start) / step, (b - start) / step))
        lo, hi = max(lo, t0), min(hi, t1)
    return (lo, hi) if lo <= hi else None


def _crossing(z, i, j):
    """Line parameter t on edge i's line where it meets edge j's line (None: parallel)."""
    p, e = z[i], z[(i + 1) % 4] - z[i]
    q, f = z[j], z[(j + 1) % 4] - z[j]
    den = (np.conj(e) * f).imag
    if abs(den) <= 1e-12 * abs(e) * abs(f):
        return None
    return float((np.conj(q - p) * f).imag / den)


def _meet_refusal(z, w, edges, meet, where):
    """The error for opposite edges whose lines (in src) or whose lines'
    images (in dst) meet at ``meet`` inside the picture: the similarities
    disagree there, so no continuous map follows both."""
    sims = [edge_similarity(z, w, k) for k in edges]
    if where == "dst":  # the gap between the two preimages
        sims = [(1 / a, -b / a) for a, b in sims]
    (a_i, b_i), (a_j, b_j) = sims
    gap = abs((a_i - a_j) * meet + b_i - b_j)
    return ConstraintError(
        f"the lines of constrained edges {edges[0]} and {edges[1]} (in {where}) meet at "
        f"({meet.real:.6g}, {meet.imag:.6g}), inside the picture's extent, where the two edges' similarities "
        f"disagree by {gap:.3g}: no map continuous there follows both; give the picture's extent= (smaller "
        'than the default?), constrain edges whose lines meet outside the picture, or accept a seam with '
        'construction="paper"'
    )


def extended_quads(z, w, edges, kind, box):
    """The continuous construction's quads (complex (4,)) and pins: the
    region of interest z (and w) with each constrained edge stretched
    along its line to where the line (in src) or its image (in dst) leaves
    the picture's box; the similarities carry the new corners to dst.
    Returns (Z, W, pins), pins the parameters of z's constrained corners
    on Z's constrained edges (they must stay exact). Opposite edges whose
    lines meet inside the box: ConstraintError (see _meet_refusal)."""
    zz, ww = z.copy(), w.copy()
    ranges = {}
    for k in edges:
        e, ew = z[(k + 1) % 4] - z[k], w[(k + 1) % 4] - w[k]
        spans = [r for r in (_line_in_box(z[k], e, box), _line_in_box(w[k], ew, box)) if r is not None]
        lo = min([0.0] + [r[0] for r in spans])
        hi = max([1.0] + [r[1] for r in spans])
        if kind == "adjacent":  # only the free end moves: the shared corner is the wedge's apex
            lo, hi = (0.0, hi) if (k + 1) % 4 != edges[1 - edges.index(k)] else (lo, 1.0)
        ranges[k] = (lo, hi)
    if kind == "opposite":
        (a_i, b_i), (a_j, b_j) = (edge_similarity(z, w, k) for k in edges)
        corners = np.array([complex(box[0], box[1]), complex(box[2], box[1]), complex(box[2], box[3]),
                            complex(box[0], box[3])])
        length = min(abs(w[(k + 1) % 4] - w[k]) for k in edges)
        agree = np.max(np.abs((a_i - a_j) * corners + b_i - b_j)) <= EDGE_BOUND * length
        for q, where in ((z, "src"), (w, "dst")):
            for a, b in (edges, edges[::-1]):
                cross = _crossing(q, a, b)
                lo, hi = ranges[a]
                if cross is None or not lo - 1e-9 <= cross <= hi + 1e-9:
                    continue
                if not agree:
                    raise _meet_refusal(z, w, edges, q[a] + cross * (q[(a + 1) % 4] - q[a]), where)
                # one similarity on both lines (to the bound): stop short of the crossing
                ranges[a] = (0.9 * cross, hi) if cross < 0 else (lo, 1 + 0.9 * (cross - 1))
    pins = []
    for k in edges:
        lo, hi = ranges[k]
        a, b = edge_similarity(z, w, k)
        e = z[(k + 1) % 4] - z[k]
        zz[k], zz[(k + 1) % 4] = z[k] + lo * e, z[k] + hi * e
        ww[k], ww[(k + 1) % 4] = a * zz[k] + b, a * zz[(k + 1) % 4] + b
        pins.append([(0.0 - lo) / (hi - lo), (1.0 - lo) / (hi - lo)])
    return zz, ww, pins


def on_picture(transform, width, height):
    """``transform`` continuous over the picture (0, 0)-(width, height):
    a :class:`LocalDeformation` of the default extent is rebuilt with that
    extent (:meth:`fpiwarp.LocalDeformation.for_picture`); any other map, and one
    given its own extent, is returned as it is. What ``fpiwarp warp``, the
    viewer's and the widget's editor do with the picture they warp."""
    fit = getattr(transform, "for_picture", None)
    return transform if fit is None else fit(width, height)


class LocalDeformation(Transform):
    """Constrained FPI inside the region of interest, similarities outside.

    Parameters are those of :class:`~fpiwarp.ConstrainedFPI` (``src``,
    ``dst``, ``edges``, ``points_per_edge``, ``delta``), plus
    ``construction`` and ``extent`` (see below and the module docstring:
    by default the operator is continuous over its extent). Opposite
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
    construction : "continuous" or "paper"
        "continuous" (default): the spline is fitted on the constrained
        edges extended over the picture, so the map does not tear along
        their lines there; "paper": fitted on the region of interest
        alone (paper §4.1; the map jumps across the lines beyond the
        ROI's free edges).
    extent : (width, height) or (x0, y0, x1, y1), optional
        The picture the continuous construction must be continuous over
        (source and output coordinates); default the bounding box of src
        and dst grown by its larger side on every side. ``fpiwarp warp``
        passes the input picture and output size; :meth:`for_picture`
        gives the operator for a picture.

    Raises
    ------
    DegenerateQuadError, FoldOverError
        As :class:`~fpiwarp.ConstrainedFPI`.
    ConstraintError (a ValueError)
        Edges that cannot be constrained as asked, quads on the outer
        side of a constrained edge's line (see above), opposite edges
        whose lines meet inside the extent (continuous construction), or
        no spline within the edge bound (default spacing).
    ArgumentError
        An unknown ``construction`` or a malformed ``extent``.

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
        construction: str = "continuous",
        extent: Sequence[float] | None = None,
    ):
        self._settings = dict(points_per_edge=points_per_edge, delta=delta, spacing=spacing,
                              construction=construction, extent=extent)
        if construction not in CONSTRUCTIONS:
            raise ArgumentError(f"construction must be one of {CONSTRUCTIONS}, got {construction!r}")
        z, w, _ = check_quad_pair(src, dst)
        roi = (as_xy(z), as_xy(w))
        norm, kind = normalize_edges(edges)
        fit_z, fit_w, pins, lengths = z, w, None, None
        if construction == "continuous":
            if kind == "adjacent":
                shared_similarity(z, w, norm[0])  # refuse inconsistent points before extending
            for k in norm:  # refuse before extending: the message names the user's points
                e = z[(k + 1) % 4] - z[k]
                outward = -1j * e / abs(e) * np.sign(signed_area(z))
                _check_line_bounds(z, k, outward, "src")
                _check_line_bounds(w, k, edge_similarity(z, w, k)[0] * outward, "dst")
            fit_z, fit_w, pins = extended_quads(z, w, norm, kind, _extent_box(z, w, extent))
            # the edge bound relative to the extended edges (the lines' lengths in the picture): on a
            # 60-px edge of a 640-px picture, relative to the ROI's edges it is out of reach (1.7e-3)
        inner = ConstrainedFPI(
            as_xy(fit_z), as_xy(fit_w), edges=norm, points_per_edge=points_per_edge, delta=delta, spacing=spacing,
            pinned=pins, deviation_lengths=lengths,
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
        self._init_parts(inner, tuple(regions), roi, construction)

    def _init_parts(self, inner, regions, roi=None, construction="paper"):
        self.inner, self.regions = inner, regions
        self.roi = roi if roi is not None else (inner.src, inner.dst)
        self.construction = construction

    @classmethod
    def _from_parts(cls, inner, regions, roi=None, construction="paper"):
        obj = cls.__new__(cls)
        obj._init_parts(inner, regions, roi, construction)
        return obj

    @property
    def src(self):
        """The region of interest (the quad given)."""
        return self.roi[0]

    @property
    def dst(self):
        """Where the region of interest's corners go."""
        return self.roi[1]

    def for_picture(self, width: float, height: float) -> "LocalDeformation":
        """This operator with the picture (0, 0)-(width, height) as its extent
        (the continuous construction pins the lines over it); itself when it
        was built by the paper's construction, given an extent, or derived
        (an inverse or a fused map)."""
        kw = getattr(self, "_settings", None)
        if kw is None or kw["construction"] != "continuous" or kw["extent"] is not None:
            return self
        return LocalDeformation(self.src, self.dst, self.edges, **{**kw, "extent": (width, height)})

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
        return LocalDeformation._from_parts(self.inner.inverse, regions, self.roi[::-1], self.construction)

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
        roi = (self.roi[0], m(self.roi[1]))
        return LocalDeformation._from_parts(inner, regions, roi, self.construction)

    def stages(self) -> list[Stage]:
        return [dataclasses.replace(self.inner.stage(), regions=self.regions)]

    def __repr__(self):
        return f"LocalDeformation(src={self.src.tolist()}, dst={self.dst.tolist()}, edges={self.edges})"
