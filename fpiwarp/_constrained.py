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

import numpy as np
from numpy.typing import ArrayLike

from ._constraint_fit import edge_similarity, fit_spline
from ._errors import ArgumentTypeError, ConstraintError
from ._exactness import check_corners
from ._foldover import inside_quad, refuse_fold
from ._linear import RLinear
from ._mobius import Mobius, centered_at_zero, mobius_product
from ._quad import check_quad_pair, parallelogram_mobius
from ._tps import ThinPlateSpline
from ._transform import Transform, chain
from .block import MAX_CENTERS, MobiusPart, Stage

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
    spacing : "adaptive", "graded" or "uniform"
        Where the K points sit along each edge. "adaptive" (default)
        re-spaces them from the measured deviation so it is about equal
        between all neighbours (``fpiwarp._constraint_fit.fit_spline``),
        falling back to plainer spacings where that would fold the map
        over; "uniform" is the paper's equal spacing (the paper's
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
        it would fold the map over, see ``fpiwarp._constraint_fit.fit_spline``), and the edge
        parameters t in [0, 1] used, one array per constrained edge.

    ``inverse`` is numerical: m_Z⁻¹ ∘ phi⁻¹ ∘ m_W with phi⁻¹ by Newton's
    method (converged to 1e-9 relative or InverseNotConvergedError).

    A fit that folds over inside ``src`` raises FoldOverError, a
    ValueError: such a map is not one-to-one and its inverse would return
    one of several preimages. It is found where the Jacobian determinant
    is at most 1% of its median at one of the samples of
    :mod:`fpiwarp._foldover` (a 32 × 32 grid over the quad, 64 points per
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
        tps, pz, pw, ts, used = fit_spline(zs, ws, m_src, m_dst, edges, kind, k, delta, spacing)
        if flip:
            m_src, tps, m_dst = m_src.conjugated(), tps.conjugated(), m_dst.conjugated()
        self._init_parts(z, w, m_src, tps, m_dst.inverse)
        self.edges, self.kind = edges, kind
        self.points_per_edge, self.delta, self.spacing = k, delta, spacing
        self.edge_parameters, self.spacing_used = tuple(ts), used
        self.constraints = (_xy(pz if not flip else np.conj(pz)), _xy(pw if not flip else np.conj(pw)))
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
        return _xy(self._z)

    @property
    def dst(self):
        return _xy(self._w)

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


def _xy(z):
    return np.stack([np.real(z), np.imag(z)], axis=-1)
