"""Where the constrained FPI's spline is pinned, and fitting it there.

The constraint points of paper §4.2 (eq. 15): points along the two
constrained edges and their offset copies, on the source quad and on the
target quad (see :mod:`fpiwarp._constrained` for the construction). Their
spacing along each edge is the paper's equal one ("uniform"), denser near
the corners ("graded"), or re-spaced until the deviation from each edge's
similarity is spread evenly ("adaptive"), with a fallback where crowded
points would fold the map over. ``fit_spline`` fits the thin-plate spline
between the Möbius images of the points.
"""

import numpy as np

from ._errors import ArgumentError
from ._foldover import worst_fold
from ._quad import signed_area
from ._tps import ThinPlateSpline
from ._transform import chain


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
#: folds the map over (by the fold test of :mod:`fpiwarp._foldover`, the
#: one ConstrainedFPI refuses a fit by).
ADAPT_CAPS = (None, 3.0, 2.0)
PAPER = "paper's: 10 equally spread points, delta 0.01"


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
    (:mod:`fpiwarp._tps_pairing`)."""
    if kind == "adjacent":  # edge 2 starts at the shared corner, edge 1's last point
        anchors = np.concatenate([np.arange(k), [k - 1], np.arange(k, 2 * k - 1)])
    else:
        anchors = np.arange(2 * k)
    return np.concatenate([np.full(2 * k, -1), anchors])


def _fit_phi(z, w, m_src, m_dst, edges, kind, k, delta, spacing):
    pz = constraint_points(z, edges, kind, k, delta, spacing)
    pw = constraint_points(w, edges, kind, k, delta, spacing)
    tps = ThinPlateSpline.fit(m_src.map_complex(pz), m_dst.map_complex(pw))
    tps.partner = offset_partners(kind, k)
    return tps, pz, pw


def _adapt(z, w, m_src, m_dst, edges, kind, k, delta, cap):
    ts = [graded_spacing(k)] * 2
    m_inv = m_dst.inverse
    for _ in range(ADAPT_PASSES):
        tps, _, _ = _fit_phi(z, w, m_src, m_dst, edges, kind, k, delta, ts)

        def f(p, tps=tps):
            return m_inv.map_complex(tps.map_complex(m_src.map_complex(p)))

        ts = [respace(t, edge_deviation(f, z, w, e, t), cap=cap) for e, t in zip(edges, ts)]
    return ts


class _Composed:
    """m_W⁻¹ ∘ tps ∘ m_Z, just enough of a map for the fold test."""

    def __init__(self, m_src, tps, m_inv):
        self.parts = (m_src, tps, m_inv)

    def wirtinger(self, p):
        w, fz, fzb = self.parts[0].wirtinger(p)
        for part in self.parts[1:]:
            w, fz, fzb = chain(part, w, fz, fzb)
        return w, fz, fzb


def folds(tps, m_src, m_dst, z):
    """Does m_W⁻¹ ∘ tps ∘ m_Z fold over the counter-clockwise quad z, by
    the test ConstrainedFPI refuses a fit by (:func:`fpiwarp._foldover.worst_fold`)?"""
    with np.errstate(all="ignore"):
        return worst_fold(_Composed(m_src, tps, m_dst.inverse), z) is not None


def fit_spline(z, w, m_src, m_dst, edges, kind, k, delta, spacing="adaptive"):
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
    construction (at most 10 equally spread points, δ at least 0.01), and
    the first that does not fold is kept (none: the uncapped one).
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
             lambda cap=cap: _adapt(z, w, m_src, m_dst, edges, kind, k, delta, cap))
            for cap in ADAPT_CAPS
        ] + [graded, uniform, (PAPER, lambda: [np.linspace(0.0, 1.0, min(k, 10))] * 2)]
    first = None
    for used, make in tries:
        ts = make()
        d = max(delta, 0.01) if used == PAPER else delta
        tps, pz, pw = _fit_phi(z, w, m_src, m_dst, edges, kind, k, d, ts)
        if first is None:
            first = (tps, pz, pw, ts, used)
        if len(tries) == 1 or not folds(tps, m_src, m_dst, z):
            return tps, pz, pw, ts, used
    return first
