"""The 4-point interpolant f = m_W⁻¹ ∘ A ∘ m_Z (paper §2-3).

m_Z and m_W are Möbius maps sending the source and target quads to
parallelograms; A is the R-linear map between the parallelograms. Since
Möbius maps are conformal, f has the constant conformal distortion of A,
the least maximal distortion possible (paper Property 3); its inverse is
the FPI of the swapped quads, exact and with the same K.
"""

import numpy as np
from numpy.typing import ArrayLike

from ..block import LinearPart, MobiusPart, Stage
from ..errors import IllConditionedPairError
from .mobius import centered_at_zero
from .points import as_xy
from .quad import check_exact, check_quad_pair, parallelogram_mobius
from .rlinear import RLinear
from .transform import Transform, chain

#: Poles farther than size / POLE_RTOL from the quad are rounding of a pole
#: at infinity (the map is affine to working precision).
POLE_RTOL = 1e-13


def _parallelogram_frame(p):
    """Center and two edge vectors of a parallelogram p (complex, (4,))."""
    ea = 0.5 * ((p[1] - p[0]) + (p[2] - p[3]))
    eb = 0.5 * ((p[3] - p[0]) + (p[2] - p[1]))
    return p.mean(), ea, eb


def affine_between(p, r):
    """The R-linear map taking parallelogram p to parallelogram r (eq. 3-4).

    Raises IllConditionedPairError where rounding has made it singular
    (|l1| == |l2|, K infinite: the quads are too thin for float64)."""
    cp, pa, pb = _parallelogram_frame(p)
    cr, ra, rb = _parallelogram_frame(r)
    det = pa * np.conj(pb) - np.conj(pa) * pb
    with np.errstate(all="ignore"):
        l1 = (ra * np.conj(pb) - np.conj(pa) * rb) / det
        l2 = (pa * rb - pb * ra) / det
        l3 = cr - l1 * cp - l2 * np.conj(cp)
    try:
        return RLinear(l1, l2, l3)
    except ValueError as exc:
        raise IllConditionedPairError(
            f"src -> dst is too ill-conditioned for float64: the affine map between their "
            f"parallelograms is singular ({exc}); use fatter quads or a smaller distortion"
        ) from None


class FPI(Transform):
    """The 4-point interpolant from quad ``src`` to quad ``dst``.

    ``src`` and ``dst`` are four (x, y) points each, array-like (4, 2), of
    the same orientation (either one: in image coordinates, y down, what
    looks counter-clockwise on screen is clockwise in (x, y)). The map
    sends ``src[j]`` to ``dst[j]``, is a bijection of the plane minus the
    pole z∞ onto the plane minus its image w∞, and has the constant
    conformal distortion ``K``.

    Parameters
    ----------
    src, dst : array_like, shape (4, 2)
        The source and target quads, ``(x, y)`` points (x = column, y = row
        in images), simple (convex or not), of the same orientation.

    Attributes
    ----------
    K : float
        The constant conformal distortion, >= 1.
    dilation : float
        ``(K - 1) / (K + 1)``.
    pole : ndarray (2,) or None
        The point the map sends to infinity (None for an affine map).
    inverse : FPI
        The exact inverse, again an FPI.
    m_src, linear, m_dst : Mobius, RLinear, Mobius
        The parts, ``f = m_dst⁻¹ ∘ linear ∘ m_src``.

    Raises
    ------
    DegenerateQuadError
        Invalid quads: wrong shape, NaN/inf, coincident or collinear points,
        zero area, a bow-tie, or source and target of opposite orientation.
    IllConditionedPairError
        A pair that float64 cannot build exactly (thin quads, K > 1e6), a
        DegenerateQuadError: every map built meets its corners, its
        inverse's corners and round trips around ``src`` within 1e-9 of the
        quad's size plus the rounding of the coordinates (see
        :mod:`fpiwarp.maps.quad`).

    See Also
    --------
    warp_image, map_points, ConstrainedFPI, LocalDeformation

    Examples
    --------
    >>> f = FPI([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 0], [2, 0], [2, 1], [0, 1]])
    >>> round(f.K, 12)
    2.0
    >>> f([[0.5, 0.5]]).round(12).tolist()
    [[1.0, 0.5]]
    >>> FPI([[0, 0], [1, 1], [1, 0], [0, 1]], [[0, 0], [2, 0], [2, 1], [0, 1]])
    Traceback (most recent call last):
    ...
    fpiwarp.DegenerateQuadError: src is self-intersecting (bow-tie): edge 0-1 crosses edge 2-3
    """

    def __init__(self, src: ArrayLike, dst: ArrayLike):
        z, w, flip = check_quad_pair(src, dst)
        # The closed form wants counter-clockwise quads in (x, y); solve for
        # mirrored quads otherwise and mirror the parts back.
        if flip:
            z, w = np.conj(z), np.conj(w)
        m_src = parallelogram_mobius(z)
        m_dst = parallelogram_mobius(w)
        linear = affine_between(m_src.map_complex(z), m_dst.map_complex(w))
        if flip:
            m_src, linear, m_dst = m_src.conjugated(), linear.conjugated(), m_dst.conjugated()
            z, w = np.conj(z), np.conj(w)
        self._init_parts(z, w, m_src, linear, m_dst)
        check_exact(self, z, w)  # refuse what float64 could not build exactly

    def _init_parts(self, z, w, m_src, linear, m_dst):
        self._z, self._w = z, w
        self.m_src, self.linear, self.m_dst = m_src, linear, m_dst
        self._m_dst_inv = m_dst.inverse

    @classmethod
    def _from_parts(cls, z, w, m_src, linear, m_dst):
        obj = cls.__new__(cls)
        obj._init_parts(z, w, m_src, linear, m_dst)
        return obj

    @property
    def src(self):
        return as_xy(self._z)

    @property
    def dst(self):
        return as_xy(self._w)

    @property
    def K(self):
        """The constant conformal distortion K >= 1 (eq. 11)."""
        return self.linear.K

    @property
    def dilation(self):
        """The constant conformal dilation (K - 1) / (K + 1)."""
        return self.linear.dilation

    @property
    def pole(self):
        """z∞ = m_Z⁻¹ ∘ A⁻¹ ∘ m_W(∞) as (x, y), or None where f is affine."""
        return self.inverse.pole_image

    @property
    def pole_image(self):
        """w∞ = m_W⁻¹ ∘ A ∘ m_Z(∞) as (x, y), or None where f is affine.

        A point more than ``1 / POLE_RTOL`` quad sizes away is rounding of a
        pole at infinity (an affine map, e.g. the FPI between similar quads,
        whose two Möbius poles cancel): None.
        """
        m = self.m_src
        if m.s == 0:  # m_Z(∞) = ∞ and A(∞) = ∞: w∞ is the pole image of m_W⁻¹
            w = self._m_dst_inv.pole_image
            w = None if w is None else complex(w[0], w[1])
        else:
            with np.errstate(all="ignore"):
                w = complex(self._m_dst_inv.map_complex(self.linear.map_complex(m.beta - m.alpha / m.s)))
        size = float(np.max(np.abs(self._w - self._w.mean())))
        if w is None or not np.isfinite(w) or abs(w - self._w.mean()) > size / POLE_RTOL:
            return None
        return np.array([w.real, w.imag])

    @property
    def is_affine(self):
        """True where f has no pole (an affine map of the whole plane)."""
        return self.pole_image is None

    def _map(self, z):
        return self._m_dst_inv.map_complex(self.linear.map_complex(self.m_src.map_complex(z)))

    def _wirtinger(self, z):
        w, fz, fzb = self.m_src.wirtinger(z)
        w, fz, fzb = chain(self.linear, w, fz, fzb)
        return chain(self._m_dst_inv, w, fz, fzb)

    @property
    def inverse(self):
        """The exact inverse: the FPI from dst to src."""
        return FPI._from_parts(self._w, self._z, self.m_dst, self.linear.inverse, self.m_src)

    def stages(self) -> list[Stage]:
        m, a, n = self.m_src, self.linear, self._m_dst_inv
        # pre: m_Z has beta = 0; post: m_W⁻¹ re-centered at 0 (its input,
        # parallelogram coordinates of unit size, lies near 0).
        post = centered_at_zero(n)
        pre = MobiusPart(center=m.q, inverse_pole=m.s, scale=m.alpha)
        return [Stage(pre=pre, linear=LinearPart(a.l1, a.l2, a.l3), post=post)]

    def __repr__(self):
        return f"FPI(src={self.src.tolist()}, dst={self.dst.tolist()})"
