"""The constrained FPI f = m_W⁻¹ ∘ phi ∘ m_Z of paper §4.2 (Algorithm 3).

m_Z and m_W are the FPI's Möbius maps to unit-radius parallelograms; phi
is a thin-plate spline fitted there to points spread along two
constrained edges plus offset copies of them (eq. 15), so that f follows
each edge's similarity along the edge, with a normal derivative set by
the offset points, and stays as close to the FPI's affine map as the TPS
energy allows. Without edge constraints phi would be affine and f the FPI.

Edge k joins point k and point k + 1 (mod 4). Constraint points, for K
points per edge (ends included; equally spread as in the paper, or
re-spaced so the deviation from the edge's similarity is about equal
between neighbours, see fit_spline):

- opposite edges ((0, 2) or (1, 3)): K points on each edge, all four
  corners among them, each with an offset copy: 4 K centers;
- adjacent edges: K on the first, K - 1 on the second (the shared corner
  once: repeated centers make the TPS singular), the free corner, and an
  offset copy of every edge point (the shared corner gets one per edge,
  distinct points): 4 K centers as well.

Offsets (eq. 15) move a point p of edge z_a z_b (opposite edge z_c z_d,
side edges z_a z_d and z_b z_c) inwards by
δ (|z_a - z_d| |p - z_b| + |z_b - z_c| |p - z_a|) / |z_b - z_a|: the
side lengths linearly interpolated along the edge, times δ. The paper's
eq. 15 omits the division by |z_b - z_a|; with it the offsets scale with
the quad, as a relative distance δ must. For adjacent edges "the side
edge" at the shared corner is the other constrained edge, at the other
ends the free corner's edges. The same rule on W gives the target of
each offset point.
"""

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..block import MAX_CENTERS, MobiusPart, Stage
from ..errors import ArgumentError, ArgumentTypeError, ConstraintError, FoldOverError
from .mobius import Mobius, centered_at_zero, mobius_product
from .points import as_xy
from .quad import check_corners, check_quad_pair, parallelogram_mobius, signed_area
from .rlinear import RLinear
from .thin_plate_spline import ThinPlateSpline
from .transform import Transform, chain, distortion_from_wirtinger

# --- Finding fold-over of a map over its region of interest (the source quad).
#: Interior sampling: a GRID × GRID grid over the quad's bounding box.
GRID = 32
#: Samples along each edge, ends included.
EDGE_POINTS = 64
#: A sample whose J is at most this fraction of the median J counts as a
#: fold: on 5,431 fuzzed fits (benchmarks/foldover_sampling.py, seeds 7 and 11) a margin
#: of 0 missed 1 of the 605 folds a 200 × 200 sampling found, 0.01 missed
#: none and refused 13 unfolded fits that compress area over 100 times.
FOLD_MARGIN = 0.01
#: Offsets (in units of the quad's radius) of the points sampled around each
#: corner: folds of the spline can be as small as 1% of the quad next to a
#: reflex corner (measured), finer than the grid.
CORNER_FAN = np.outer([0.003, 0.01, 0.03], np.exp(2j * np.pi * np.arange(16) / 16)).ravel()
#: Local refinement: around each of the REFINE samples of least J (at
#: least a grid cell apart) a REFINE_GRID × REFINE_GRID grid one grid cell
#: wide either side, REFINE_LEVELS times, each time a third as wide around
#: the new least samples: at most REFINE_LEVELS · REFINE · REFINE_GRID²
#: more samples, whatever the map.
REFINE = 6
REFINE_GRID = 7
REFINE_LEVELS = 2


def inside_quad(z, p):
    """Boolean mask: which points p (complex) lie strictly inside the simple
    polygon z (complex), by the even-odd rule."""
    inside = np.zeros(p.shape, dtype=bool)
    for a, b in zip(z, np.roll(z, -1)):
        crosses = (a.imag > p.imag) != (b.imag > p.imag)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = a.real + (p.imag - a.imag) * (b.real - a.real) / (b.imag - a.imag)
        inside ^= crosses & (p.real < x)
    return inside


def roi_samples(z, grid=GRID, edge_points=EDGE_POINTS):
    """Points of the quad z (complex (4,)): its interior grid points, points
    along its four edges (Chebyshev-spaced: dense near the corners), and
    fans of points around each corner inside the quad, complex 1-D."""
    lo = complex(z.real.min(), z.imag.min())
    hi = complex(z.real.max(), z.imag.max())
    xs = np.linspace(lo.real, hi.real, grid)
    ys = np.linspace(lo.imag, hi.imag, grid)
    p = (xs[None, :] + 1j * ys[:, None]).ravel()
    t = 0.5 * (1 - np.cos(np.linspace(0.0, np.pi, edge_points)))
    edges = [a + t * (b - a) for a, b in zip(z, np.roll(z, -1))]
    size = float(np.max(np.abs(z - z.mean())))
    fans = (z[:, None] + size * CORNER_FAN[None, :]).ravel()
    return np.concatenate([p[inside_quad(z, p)], *edges, fans[inside_quad(z, fans)]])


def _jacobian(f, p):
    _, fz, fzb = f.wirtinger(p)
    return np.abs(fz) ** 2 - np.abs(fzb) ** 2


def _least(p, jac, n, apart):
    """Up to n of the points p of least jac, each at least ``apart`` from
    those before it."""
    kept = []
    for k in np.argsort(jac)[: 64 * n]:
        if all(abs(p[k] - q) >= apart for q in kept):
            kept.append(p[k])
            if len(kept) == n:
                break
    return np.array(kept, dtype=complex)


def refine(f, z, p, jac, cell, levels=REFINE_LEVELS):
    """The samples p (with Jacobian jac) and, around those of least J, finer
    grids inside the quad z, ``levels`` times (see REFINE); ``cell`` is the
    width of the first grid's cells."""
    steps = np.linspace(-1.0, 1.0, REFINE_GRID)
    offsets = (steps[None, :] + 1j * steps[:, None]).ravel()
    for _ in range(levels):
        q = (_least(p, jac, REFINE, cell)[:, None] + cell * offsets[None, :]).ravel()
        q = q[inside_quad(z, q)]
        p, jac = np.concatenate([p, q]), np.concatenate([jac, _jacobian(f, q)])
        cell /= 3
    return p, jac


def worst_fold(f, z, margin=FOLD_MARGIN, **kw):
    """(point, J/J_typical) where the map f folds over quad z worst, or None.

    J is compared with its median over the samples (J_typical), so the
    second value says how strongly orientation is reversed relative to the
    map's usual area scale; a sample with J <= margin J_typical counts (a
    fold between samples shows as a near-zero J at its neighbours). The
    samples of least J are refined locally (see REFINE) before the test."""
    p = roi_samples(z, **kw)
    jac = _jacobian(f, p)
    typical = float(np.median(np.abs(jac)))
    span = max(np.ptp(z.real), np.ptp(z.imag))
    p, jac = refine(f, z, p, jac, span / (kw.get("grid", GRID) - 1))
    k = int(np.argmin(jac))
    if jac[k] > margin * typical:
        return None
    return complex(p[k]), float(jac[k] / typical)


def refuse_fold(f, z, what):
    """Raise FoldOverError if the map f folds over the quad z (complex (4,));
    ``what`` names the map in the message."""
    fold = worst_fold(f, z)
    if fold is not None:
        p, rel = fold
        raise FoldOverError(
            f"{what} folds over inside src: its Jacobian determinant is {rel:.3g} times its typical "
            f"size at ({p.real:.6g}, {p.imag:.6g}) (it must stay above {FOLD_MARGIN:g}), so it is not "
            "one-to-one there and its inverse would return one of several preimages; deform the "
            "constrained edges less"
        )


# --- Where the constrained FPI's spline is pinned, and fitting it there.
def edge_similarity(z, w, k):
    """(a, b) of the similarity a z + b taking edge k of z onto edge k of w."""
    z0, z1, w0, w1 = z[k], z[(k + 1) % 4], w[k], w[(k + 1) % 4]
    a = (w1 - w0) / (z1 - z0)
    return a, w0 - a * z0


def _offsets(q, k, other, t, delta, orient):
    """Offset copies (eq. 15, normalized) of points q[k] + t (q[k+1] - q[k])."""
    za, zb = q[k], q[(k + 1) % 4]
    e = zb - za
    inward = 1j * e / abs(e) * orient  # left normal for counter-clockwise quads
    side_a, side_b = other
    dist = delta * ((1 - t) * side_a + t * side_b)
    return za + t * e + inward * dist


def constraint_points(q, edges, kind, points_per_edge, delta, spacing=None):
    """Constraint points on quad q (complex (4,)): edge points, free corner
    (adjacent only), then offset copies; see the module docstring.

    ``spacing``: one array of edge parameters t (0 and 1 included, K
    increasing values) per edge of ``edges``; None: equally spread."""
    orient = np.sign(signed_area(q))
    if spacing is None:
        spacing = [np.linspace(0.0, 1.0, points_per_edge)] * 2
    side = [abs(q[(k + 1) % 4] - q[k]) for k in range(4)]  # side[k]: length of edge k
    pts, offs = [], []
    for n, (k, t) in enumerate(zip(edges, spacing)):
        e_pts = q[k] + t * (q[(k + 1) % 4] - q[k])
        # side edges: at q[k] edge k-1, at q[k+1] edge k+1
        o = _offsets(q, k, (side[(k - 1) % 4], side[(k + 1) % 4]), t, delta, orient)
        if kind == "adjacent" and n == 1:
            e_pts = e_pts[1:]  # shared corner once
        pts.append(e_pts)
        offs.append(o)
    if kind == "adjacent":
        pts.append(np.array([q[(edges[0] + 3) % 4]]))
    return np.concatenate(pts + offs)


#: Spacings of the constraint points along the constrained edges (``spacing=``).
SPACINGS = ("adaptive", "graded", "uniform")
#: "adaptive": re-spacing passes after the graded start, samples per gap
#: between neighbouring points where the edge deviation is measured, and
#: the share of equal spacing mixed into each new spacing (keeps points
#: from crowding where the deviation was largest, see respace).
ADAPT_PASSES = 4
ADAPT_SAMPLES = 8
ADAPT_MIX = 0.15
#: "adaptive": density caps (see respace) tried in turn where the spacing
#: folds the map over (by the fold test of :mod:`fpiwarp.maps.constrained`, the
#: one ConstrainedFPI refuses a fit by).
ADAPT_CAPS = (None, 3.0, 2.0)
PAPER = "paper's: 10 equally spread points, delta 0.01"
#: The default spacing ("adaptive") keeps only fits whose constrained edges
#: follow their similarities to this part of the edge length (see fit_spline).
EDGE_BOUND = 1e-3


def graded_spacing(k):
    """k edge parameters in [0, 1], ends included: the mean of equal
    spacing and the Chebyshev-Lobatto nodes ½ - ½ cos(π i / (k - 1)),
    denser near the corners, where with equal spacing the spline strays
    farthest from the edge's similarity."""
    i = np.arange(k) / (k - 1)
    return 0.5 * i + 0.5 * (0.5 - 0.5 * np.cos(np.pi * i))


def respace(t, gap_error, mix=ADAPT_MIX, cap=None):
    """New edge parameters, as many as ``t``, that equidistribute a
    deviation of order h² per gap.

    ``gap_error[i]``: the largest deviation measured between t[i] and
    t[i+1]. Reading it as c_i h_i² (h_i the gap's width), gaps of width
    proportional to c_i^(-1/2) = h_i / sqrt(gap_error[i]) give every gap
    the same deviation: the new points sit at equal quantiles of the
    density sqrt(gap_error[i]) / h_i (normalized to mean 1), of which
    ``mix`` is replaced by the uniform density 1, so no gap grows beyond
    1 / ``mix`` times the equal one and the points do not all crowd where
    the deviation was largest. ``cap``: no density above ``cap`` times
    the mean, so no gap below about 1 / ``cap`` times the equal one
    (None: no such bound). Ends stay at 0 and 1.
    """
    t = np.asarray(t, dtype=np.float64)
    h = np.diff(t)
    e = np.asarray(gap_error, dtype=np.float64)
    if not np.all(np.isfinite(e)) or e.max() <= 1e-14:
        return t  # nothing to equidistribute (the map meets the edge to rounding)
    density = np.sqrt(np.maximum(e, 1e-6 * e.max())) / h
    density = (1 - mix) * density / np.sum(density * h) + mix
    if cap is not None:
        for _ in range(3):  # clipping lowers the mean: clip again against the new one
            density = np.minimum(density, cap * np.sum(density * h))
    cum = np.concatenate([[0.0], np.cumsum(density * h)])
    return np.interp(np.linspace(0.0, 1.0, len(t)), cum / cum[-1], t)


def edge_deviation(f, z, w, k, t, samples=ADAPT_SAMPLES):
    """Largest |f(p) - S_k(p)| / |w_k+1 - w_k| between each pair of
    neighbouring edge parameters t[i], t[i+1] (``samples`` points per gap,
    ends excluded), S_k edge k's similarity; f maps complex points."""
    a, b = edge_similarity(z, w, k)
    u = np.linspace(0.0, 1.0, samples + 2)[1:-1]
    s = (t[:-1, None] + np.diff(t)[:, None] * u[None, :]).reshape(-1)
    p = z[k] + s * (z[(k + 1) % 4] - z[k])
    dev = np.abs(f(p) - (a * p + b)) / abs(w[(k + 1) % 4] - w[k])
    return dev.reshape(len(t) - 1, samples).max(axis=1)


def offset_partners(kind, k):
    """Per constraint point (in :func:`constraint_points`' order) the index
    of the edge point it is the offset copy of, -1 for the edge points and
    the free corner: the spline's pairs for the block
    (:mod:`fpiwarp.maps.thin_plate_spline`)."""
    if kind == "adjacent":  # edge 2 starts at the shared corner, edge 1's last point
        anchors = np.concatenate([np.arange(k), [k - 1], np.arange(k, 2 * k - 1)])
    else:
        anchors = np.arange(2 * k)
    return np.concatenate([np.full(2 * k, -1), anchors])


def _fit_phi(z, w, m_src, m_dst, edges, kind, k, delta, spacing):
    k = len(spacing[0]) if spacing is not None else k  # the paper's fallback has fewer points
    pz = constraint_points(z, edges, kind, k, delta, spacing)
    pw = constraint_points(w, edges, kind, k, delta, spacing)
    tps = ThinPlateSpline.fit(m_src.map_complex(pz), m_dst.map_complex(pw))
    tps.partner = offset_partners(kind, k)
    return tps, pz, pw


def pin(t, pins):
    """The edge parameters t with the nearest interior ones moved onto the
    parameters ``pins`` (each in (0, 1)), so constraint points sit exactly
    there; increasing, ends kept."""
    t = np.array(t, dtype=np.float64)
    free = list(range(1, len(t) - 1))
    for p in sorted(pins, key=lambda p: -min(p, 1 - p)):
        if not 1e-9 < p < 1 - 1e-9:
            continue  # an end: always a point
        if not free:
            break
        i = min(free, key=lambda i: abs(t[i] - p))
        t[i] = p
        free.remove(i)
    return np.sort(t)


def _pinned(ts, pins):
    return ts if pins is None else [pin(t, p) for t, p in zip(ts, pins)]


def _adapt(z, w, m_src, m_dst, edges, kind, k, delta, cap, pins=None):
    ts = _pinned([graded_spacing(k)] * 2, pins)
    m_inv = m_dst.inverse
    for _ in range(ADAPT_PASSES):
        tps, _, _ = _fit_phi(z, w, m_src, m_dst, edges, kind, k, delta, ts)

        def f(p, tps=tps):
            return m_inv.map_complex(tps.map_complex(m_src.map_complex(p)))

        ts = _pinned([respace(t, edge_deviation(f, z, w, e, t), cap=cap) for e, t in zip(edges, ts)], pins)
    return ts


class _Composed:
    """m_W⁻¹ ∘ tps ∘ m_Z, just enough of a map for the fold test."""

    def __init__(self, m_src, tps, m_inv):
        self.parts = (m_src, tps, m_inv)

    def map_complex(self, p):
        for part in self.parts:
            p = part.map_complex(p)
        return p

    def wirtinger(self, p):
        w, fz, fzb = self.parts[0].wirtinger(p)
        for part in self.parts[1:]:
            w, fz, fzb = chain(part, w, fz, fzb)
        return w, fz, fzb


def folds(tps, m_src, m_dst, z):
    """Does m_W⁻¹ ∘ tps ∘ m_Z fold over the counter-clockwise quad z, by
    the test ConstrainedFPI refuses a fit by (:func:`fpiwarp.maps.constrained.worst_fold`)?"""
    with np.errstate(all="ignore"):
        return worst_fold(_Composed(m_src, tps, m_dst.inverse), z) is not None


def fit_spline(z, w, m_src, m_dst, edges, kind, k, delta, spacing="adaptive", pins=None, segments=None):
    """phi, the constraint points on z and on w, the edge parameters used
    (one array per constrained edge) and the name of the spacing used, for
    counter-clockwise quads z, w.

    "uniform": the paper's equal spacing; "graded": see
    :func:`graded_spacing`; "adaptive": from the graded spacing,
    ADAPT_PASSES times measure the deviation from each edge's similarity
    per gap and :func:`respace` to equidistribute it, then fit once more
    (a fixed number of passes: the spacing depends continuously on the
    quads). Points crowded near a corner can make the spline fold over
    next to a strongly stretched or shrunk free edge; so where the result
    folds (:func:`folds`), the same is done with the density capped
    (ADAPT_CAPS), then the graded and the equal spacing, then the paper's
    construction (at most 10 equally spread points, δ at least 0.01);
    of these fits, those whose edges stray from their similarities by at
    most EDGE_BOUND of the edge length (measured on 800 points per edge)
    and that do not fold over are candidates, and the one of least maximal
    conformal distortion (on the fold test's samples of z) is kept. None
    within the bound: ConstraintError with the closest deviation; all
    within it fold: the least distorted, which ConstrainedFPI refuses.
    ``pins``: per constrained edge, edge parameters where a point must sit
    (see :func:`pin`), or None; ``segments``: per constrained edge, parts
    (t0, t1, factor) of it where the deviation is measured, times factor
    (the fitted edge's length over the one the bound is relative to there),
    or None: the whole edge, factor 1.
    """
    if spacing not in SPACINGS:
        raise ArgumentError(f"spacing must be one of {SPACINGS}, got {spacing!r}")
    uniform = ("uniform", lambda: [np.linspace(0.0, 1.0, k)] * 2)
    graded = ("graded", lambda: [graded_spacing(k)] * 2)
    if spacing == "uniform":
        tries = [uniform]
    elif spacing == "graded":
        tries = [graded]
    else:
        tries = [
            ("adaptive" + (f", density capped at {cap:g}" if cap else ""),
             lambda cap=cap: _adapt(z, w, m_src, m_dst, edges, kind, k, delta, cap, pins))
            for cap in ADAPT_CAPS
        ] + [graded, uniform]
    if len(tries) == 1:
        used, make = tries[0]
        ts = _pinned(make(), pins)
        return (*_fit_phi(z, w, m_src, m_dst, edges, kind, k, delta, ts), ts, used)
    # The default: every spacing tried; among the fits that follow the
    # edges to EDGE_BOUND and do not fold over, the least distorted.
    samples = roi_samples(z)
    fits = []
    for used, make in tries:
        ts = _pinned(make(), pins)
        d = max(delta, 0.01) if used == PAPER else delta
        tps, pz, pw = _fit_phi(z, w, m_src, m_dst, edges, kind, k, d, ts)
        comp = _Composed(m_src, tps, m_dst.inverse)
        dev = max(
            float(edge_deviation(comp.map_complex, z, w, e, np.linspace(t0, t1, 101)).max()) * scale
            for e, parts in zip(edges, segments or ([(0.0, 1.0, 1.0)],) * 2)
            for t0, t1, scale in parts
        )
        with np.errstate(all="ignore"):
            _, fz, fzb = comp.wirtinger(samples)
        kmax = float(np.max(distortion_from_wirtinger(fz, fzb)))
        fits.append((dev, kmax, (tps, pz, pw, ts, used)))
    within = sorted((f for f in fits if f[0] <= EDGE_BOUND), key=lambda f: f[1])
    for _, _, fit in within:
        if not folds(fit[0], m_src, m_dst, z):
            return fit
    # last resort, the paper's construction (at most 10 equal points, δ >= 0.01)
    ts = _pinned([np.linspace(0.0, 1.0, min(k, 10))] * 2, pins)
    paper = (*_fit_phi(z, w, m_src, m_dst, edges, kind, k, max(delta, 0.01), ts), ts, PAPER)
    comp = _Composed(m_src, paper[0], m_dst.inverse)
    dev = max(float(edge_deviation(comp.map_complex, z, w, e, np.linspace(t0, t1, 101)).max()) * scale
              for e, parts in zip(edges, segments or ([(0.0, 1.0, 1.0)],) * 2) for t0, t1, scale in parts)
    if dev <= EDGE_BOUND and not folds(paper[0], m_src, m_dst, z):
        return paper
    if not within:
        best = min(f[0] for f in fits)
        raise ConstraintError(
            f"no spline of {k} points per edge follows the constrained edges' similarities to "
            f"{EDGE_BOUND:g} of the edge length here: the closest strays by {best:.3g}; deform the "
            'constrained edges less, or accept the deviation with spacing="graded" or "uniform"'
        )
    fold_free = [f for f in fits if not folds(f[2][0], m_src, m_dst, z)]
    if fold_free:
        best = min(f[0] for f in fold_free)
        raise ConstraintError(
            f"the splines that follow the constrained edges' similarities to {EDGE_BOUND:g} of the edge "
            f"length fold over inside src; the closest one that does not strays by {best:.3g}: deform the "
            'constrained edges less, or accept the deviation with spacing="graded" or "uniform"'
        )
    return within[0][2]  # every fit folds: ConstrainedFPI refuses it (FoldOverError, with where)


# --- The constrained FPI f = m_W⁻¹ ∘ phi ∘ m_Z of paper §4.2 (Algorithm 3).
#: Adjacent constrained edges must agree on one similarity to this relative tolerance.
SIMILARITY_RTOL = 1e-6


def normalize_edges(edges):
    """Validate an edge pair; return ((i, j), kind) with kind "opposite" or
    "adjacent" and, for adjacent edges, i the edge whose end is the shared corner."""
    try:
        i, j = (int(e) for e in edges)
    except (TypeError, ValueError):
        raise ConstraintError(f"edges must be two edge indices in 0..3, got {edges!r}") from None
    if not (0 <= i <= 3 and 0 <= j <= 3) or i == j:
        raise ConstraintError(f"edges must be two different edge indices in 0..3, got {edges!r}")
    if (i - j) % 4 == 2:
        return (min(i, j), max(i, j)), "opposite"
    if (j - i) % 4 == 1:
        return (i, j), "adjacent"
    return (j, i), "adjacent"


def shared_similarity(z, w, first):
    """The one similarity of adjacent edges ``first`` and ``first + 1``.

    Raises ValueError when no similarity takes the three constrained
    corners of z to those of w (relative tolerance SIMILARITY_RTOL).
    """
    idx = [first, (first + 1) % 4, (first + 2) % 4]
    a1, _ = edge_similarity(z, w, first)
    a2, _ = edge_similarity(z, w, (first + 1) % 4)
    if abs(a1 - a2) > SIMILARITY_RTOL * max(abs(a1), abs(a2)):
        raise ConstraintError(
            f"adjacent constrained edges {first} and {(first + 1) % 4} must undergo one shared "
            f"similarity, but no similarity maps src points {idx} to dst points {idx} (edge scale-"
            f"rotations {complex(a1):.6g} and {complex(a2):.6g} differ): move only the free point "
            f"{(first + 3) % 4}, or constrain opposite edges"
        )
    # least squares over the three corners (exact up to SIMILARITY_RTOL)
    zz, ww = z[idx], w[idx]
    zc, wc = zz - zz.mean(), ww - ww.mean()
    a = np.vdot(zc, wc) / np.vdot(zc, zc)
    return a, ww.mean() - a * zz.mean()


#: Attributes an inverse or a fused map carries over.
#: SourceRegion: points per edge of src whose images outline the spline's image of src.
BOUNDARY_POINTS = 128
_ATTRS = ("edges", "kind", "points_per_edge", "delta", "spacing", "edge_parameters", "spacing_used")


class ConstrainedFPI(Transform):
    """The constrained 4-point interpolant from quad ``src`` to quad ``dst``.

    Interpolates all four corners, follows each constrained edge's
    similarity along that edge (z_k -> w_k, z_k+1 -> w_k+1), and is
    otherwise as close to the FPI as a thin-plate spline in the FPI's
    parallelogram coordinates can be (paper §4.2, Algorithm 3).

    Parameters
    ----------
    src, dst : array-like (4, 2)
        The quads, same orientation (clockwise in (x, y), as image
        coordinates give for counter-clockwise on screen, is fine).
    edges : pair of int
        The constrained edges; edge k joins point k and point k + 1 (mod 4).
        Opposite ((0, 2), (1, 3)) or adjacent. Adjacent edges share one
        similarity: dst must be src under one similarity at their three
        corners, or ValueError.
    points_per_edge : int or None
        K, points spread along each constrained edge (ends included);
        the spline gets 4 K centers, so 2 <= K <= 16 (16: the block's 64).
        None (default): as many as the block holds as pairs (an edge point
        and its offset copy in two rows, see ``fpiwarp.block.layout``):
        16 for opposite edges, 15 for adjacent ones (their free corner and
        the shared corner's second offset copy take a pair each). Adjacent
        edges with K = 16 are packed as plain terms, which float32
        evaluates less exactly for small δ.
    delta : float
        δ of eq. 15, the relative distance of the offset points (default
        0.002; the paper's figures: 0.01). Smaller follows the edges
        closer and distorts less; the spline's weights grow like 1 / δ,
        which the block's paired terms carry to the kernels without the
        float32 cancellation plain terms would suffer.
    pinned : None or two sequences of floats
        Per constrained edge (in the order of the normalized ``edges``),
        edge parameters t in [0, 1] where a constraint point must sit, so
        the map meets the edge's similarity exactly at z_k + t (z_k+1 -
        z_k) (:class:`~fpiwarp.LocalDeformation` pins the region of
        interest's corners on its extended edges).
    deviation_lengths : None or two floats
        With ``pinned``: per constrained edge, the length the edge bound
        (1e-3) is relative to between the outermost pins (the region of
        interest's edge); elsewhere on the edge, and by default, it is
        relative to the edge's own length in ``dst``.
    spacing : "adaptive", "graded" or "uniform"
        Where the K points sit along each edge. "adaptive" (default)
        re-spaces them from the measured deviation so it is about equal
        between all neighbours, also fits capped, graded, equal and the
        paper's spacings, and keeps the least distorted fit whose edges
        follow their similarities to 1e-3 of the edge length and that
        does not fold over (``fpiwarp.maps.constrained.fit_spline``; none
        within 1e-3: ConstraintError with the measured deviation);
        "uniform" is the paper's equal spacing (the paper's
        construction: ``points_per_edge=10, delta=0.01,
        spacing="uniform"``). Measured over 320 random fold-free
        configurations (benchmarks/seams.py), deviation from the edges'
        similarities relative to the edge length, median / p90 / max:
        the defaults 1.1e-4 / 2.3e-4 / 6.0e-4; the paper's construction
        2.5e-3 / 5.2e-3 / 2.0e-2. Maximal conformal distortion per
        configuration: median 0.998 times the paper's construction's.

    Attributes
    ----------
    pre, core, post : the parts m_Z, phi (a ThinPlateSpline; its Newton
        inverse for an inverse map) and m_W⁻¹, applied in that order.
    edges, kind : the normalized edge pair and "opposite" or "adjacent".
    constraints : (src points, dst points), each (4 K, 2): the spline's
        constraints before the Möbius change of coordinates.
    spacing, spacing_used, edge_parameters : the spacing asked for, the
        one used ("adaptive" gives way to a capped or plainer spacing where
        it would fold the map over, see ``fpiwarp.maps.constrained.fit_spline``), and the edge
        parameters t in [0, 1] used, one array per constrained edge.

    ``inverse`` is numerical: m_Z⁻¹ ∘ phi⁻¹ ∘ m_W with phi⁻¹ by Newton's
    method (converged to 1e-9 relative or InverseNotConvergedError).

    A fit that folds over inside ``src`` raises FoldOverError, a
    ValueError: such a map is not one-to-one and its inverse would return
    one of several preimages. It is found where the Jacobian determinant
    is at most 1% of its median at one of the samples of
    :mod:`fpiwarp.maps.constrained` (a 32 × 32 grid over the quad, 64 points per
    edge, fans around the corners). A fit that misses a corner by more than 1e-9 of the quad's
    size raises IllConditionedPairError.

    >>> sq = [[0, 0], [2, 0], [2, 1], [0, 1]]
    >>> f = ConstrainedFPI(sq, [[0, 0], [2, 0], [2.2, 1.1], [0, 1]], edges=(3, 1))
    >>> np.round(f(sq), 9).tolist()[2]
    [2.2, 1.1]
    >>> ConstrainedFPI(sq, [[0, 0], [2, 0], [2.2, 1.1], [0, 1]], edges=(0, 1))
    Traceback (most recent call last):
    ...
    fpiwarp.ConstraintError: adjacent constrained edges 0 and 1 must undergo one shared similarity, ...
    """

    def __init__(
        self,
        src: ArrayLike,
        dst: ArrayLike,
        edges: tuple[int, int],
        points_per_edge: int | None = None,
        delta: float = 0.002,
        spacing: str = "adaptive",
        pinned: tuple[Sequence[float], Sequence[float]] | None = None,
        deviation_lengths: tuple[float, float] | None = None,
    ):
        z, w, flip = check_quad_pair(src, dst)
        edges, kind = normalize_edges(edges)
        k = _check_points_per_edge(points_per_edge, kind)
        delta = float(delta)
        if not (np.isfinite(delta) and delta > 0):
            raise ConstraintError(f"delta must be a positive number, got {delta!r}")
        if kind == "adjacent":
            shared_similarity(z, w, edges[0])  # refuse inconsistent points early
        # As for the FPI: solve counter-clockwise, mirror the parts back.
        zs, ws = (np.conj(z), np.conj(w)) if flip else (z, w)
        m_src = parallelogram_mobius(zs)
        m_dst = parallelogram_mobius(ws)
        pins = _check_pins(pinned, k)
        segments = _deviation_segments(w, edges, pins, deviation_lengths)
        tps, pz, pw, ts, used = fit_spline(zs, ws, m_src, m_dst, edges, kind, k, delta, spacing, pins, segments)
        if flip:
            m_src, tps, m_dst = m_src.conjugated(), tps.conjugated(), m_dst.conjugated()
        self._init_parts(z, w, m_src, tps, m_dst.inverse)
        self.edges, self.kind = edges, kind
        self.points_per_edge, self.delta, self.spacing = k, delta, spacing
        self.edge_parameters, self.spacing_used = tuple(ts), used
        self.constraints = (as_xy(pz if not flip else np.conj(pz)), as_xy(pw if not flip else np.conj(pw)))
        check_corners(self, z, w)  # ill-conditioned quads: refuse rather than miss a corner
        refuse_fold(self, z, "the constrained FPI")

    def _init_parts(self, z, w, pre, core, post):
        self._z, self._w = z, w
        if pre.beta != 0:  # the block's pre-Möbius has no offset term
            raise ConstraintError("ConstrainedFPI parts: the pre-Möbius must have beta == 0 (the block stores none)")
        self.pre, self.core, self.post = pre, core, post

    @classmethod
    def _from_parts(cls, z, w, pre, core, post, **attrs):
        obj = cls.__new__(cls)
        obj._init_parts(z, w, pre, core, post)
        obj.__dict__.update(attrs)
        return obj

    @property
    def src(self):
        return as_xy(self._z)

    @property
    def dst(self):
        return as_xy(self._w)

    @property
    def tps(self):
        """The thin-plate spline phi (for an inverse: the spline it inverts)."""
        return getattr(self.core, "tps", self.core)

    def _map(self, z):
        return self.post.map_complex(self.core.map_complex(self.pre.map_complex(z)))

    def _wirtinger(self, z):
        w, fz, fzb = self.pre.wirtinger(z)
        w, fz, fzb = chain(self.core, w, fz, fzb)
        return chain(self.post, w, fz, fzb)

    @property
    def inverse(self):
        """m_Z⁻¹ ∘ phi⁻¹ ∘ m_W, phi⁻¹ by Newton (see InverseThinPlateSpline)."""
        attrs = {k: v for k, v in self.__dict__.items() if k in _ATTRS}
        if "constraints" in self.__dict__:
            attrs["constraints"] = self.constraints[::-1]
        core = self.core.inverse
        if isinstance(self.core, ThinPlateSpline):
            core.region = SourceRegion(self._z, self.pre, self.core, self.post)
        return ConstrainedFPI._from_parts(self._w, self._z, self.post.inverse, core, self.pre.inverse, **attrs)

    def _fuse_with(self, nxt):
        """A following Möbius map (or similarity) joins the post-Möbius:
        one stage instead of two (used by Compound)."""
        m = as_mobius(nxt)
        if m is None:
            return None
        post = Mobius(*mobius_product(m.coefficients, self.post.coefficients), center=self.post.q)
        if post.q != self.post.q:  # the fused pole sits at the center: keep two steps
            return None
        attrs = {k: v for k, v in self.__dict__.items() if k in _ATTRS}
        return ConstrainedFPI._from_parts(self._z, m.map_complex(self._w), self.pre, self.core, post, **attrs)

    def stage(self, **kw) -> Stage:
        """One parameter-block stage: pre-Möbius, TPS core (or its Newton
        inverse), post-Möbius; ``kw`` adds Stage fields (regions)."""
        p = self.pre
        pre = MobiusPart(center=p.q, inverse_pole=p.s, scale=p.alpha)
        return self.core.stage(pre=pre, post=centered_at_zero(self.post), **kw)

    def stages(self) -> list[Stage]:
        return [self.stage()]

    def __repr__(self):
        return (
            f"ConstrainedFPI(src={self.src.tolist()}, dst={self.dst.tolist()}, "
            f"edges={getattr(self, 'edges', None)})"
        )


class SourceRegion:
    """Where the spline's Newton inverse should land: in src (z, counter-
    clockwise or not) for targets in the spline's image of src, a polygon
    through the images of BOUNDARY_POINTS points per edge of src (Chebyshev
    spaced: the image bends most near the corners; 64 points,
    either spaced, missed points the image covers).
    ``pre``/``post``: the forward map's Möbius parts. The spline can fold
    outside src and cover part of src's image a second time."""

    def __init__(self, z, pre, core, post):
        t = 0.5 * (1 - np.cos(np.linspace(0.0, np.pi, BOUNDARY_POINTS + 1)[:-1]))  # dense at the corners
        edge = np.concatenate([a + t * (b - a) for a, b in zip(z, np.roll(z, -1))])
        self.z, self.pre_inverse = z, pre.inverse
        with np.errstate(all="ignore"):
            self.image = core.map_complex(pre.map_complex(edge))

    def holds(self, x):
        return inside_quad(self.z, self.pre_inverse.map_complex(x))

    def wants(self, target):
        im = self.image
        near = (target.real >= im.real.min()) & (target.real <= im.real.max())
        near &= (target.imag >= im.imag.min()) & (target.imag <= im.imag.max())
        out = np.zeros(target.shape, dtype=bool)
        out[near] = inside_quad(im, target[near])
        return out


def as_mobius(t):
    """t as a Möbius map if it is one (a Mobius, or an RLinear similarity), else None."""
    if isinstance(t, Mobius):
        return t
    if isinstance(t, RLinear) and t.l2 == 0:
        return Mobius(t.l1, t.l3, 0, 1)
    return None


#: points_per_edge=None: the most whose constraint points the block holds as
#: pairs (two rows each): 4 K rows for opposite edges, 4 K + 2 for adjacent ones.
PAIRED_POINTS = {"opposite": MAX_CENTERS // 4, "adjacent": MAX_CENTERS // 4 - 1}


def _deviation_segments(w, edges, pins, lengths):
    """Where fit_spline measures the edge bound: per constrained edge the
    whole edge, and between its outermost pins (if any) relative to
    ``lengths`` (None: the whole edges only)."""
    if lengths is None:
        return None
    try:
        lengths = [float(v) for v in lengths]
    except (TypeError, ValueError):
        lengths = []
    if len(lengths) != 2 or not all(np.isfinite(v) and v > 0 for v in lengths):
        raise ConstraintError(f"deviation_lengths must be two positive lengths, got {lengths!r}")
    out = []
    for k, v, p in zip(edges, lengths, pins or ([], [])):
        parts = [(0.0, 1.0, 1.0)]
        if p:
            parts.append((min(p), max(p), abs(w[(k + 1) % 4] - w[k]) / v))
        out.append(parts)
    return out


def _check_pins(pinned, k):
    """pinned: None, or two sequences of edge parameters in (0, 1), at most k - 2 each."""
    if pinned is None:
        return None
    try:
        pins = [[float(v) for v in p] for p in pinned]
    except (TypeError, ValueError):
        pins = None
    if pins is None or len(pins) != 2 or not all(
        len(p) <= k and all(np.isfinite(v) and 0 <= v <= 1 for v in p) for p in pins
    ):
        raise ConstraintError(
            f"pinned must be two sequences (one per constrained edge) of at most {k} edge parameters "
            f"in [0, 1], got {pinned!r}"
        )
    return pins


def _check_points_per_edge(k, kind):
    if k is None:
        return PAIRED_POINTS[kind]
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
        raise ArgumentTypeError(f"points_per_edge must be an int or None, got {type(k).__name__}")
    k = int(k)
    kmax = MAX_CENTERS // 4
    if not 2 <= k <= kmax:
        raise ConstraintError(
            f"points_per_edge must be in 2..{kmax}: the spline gets 4 * points_per_edge "
            f"centers and the parameter block holds at most {MAX_CENTERS}, got {k}"
        )
    return k

