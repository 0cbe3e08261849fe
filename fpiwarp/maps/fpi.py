"""The 4-point interpolant f = m_W⁻¹ ∘ A ∘ m_Z (paper §2-3).

m_Z and m_W are Möbius maps sending the source and target quads to
parallelograms; A is the R-linear map between the parallelograms. Since
Möbius maps are conformal, f has the constant conformal distortion of A,
the least maximal distortion possible (paper Property 3); its inverse is
the FPI of the swapped quads, exact and with the same K.
"""

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..block import LinearPart, MobiusPart, Stage
from ..block.many import pack_one_stage, rlinear_inverse_many
from ..errors import ArgumentError, DegenerateQuadError, IllConditionedPairError
from .mobius import Mobius, centered_at_zero
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

    @classmethod
    def many(cls, src: ArrayLike, dst: ArrayLike) -> "FPIStack":
        """N FPIs at once from (N, 4, 2) ``src`` and ``dst``: an
        :class:`~fpiwarp.maps.fpi.FPIStack`, what ``[FPI(s, d) for s, d in zip(src, dst)]``
        gives (the same checks and refusals, messages prefixed by the map's
        index), built on arrays: a few microseconds per map.

        Examples
        --------
        >>> import numpy as np
        >>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
        >>> maps = FPI.many([square, square], [square * [2, 1], square + 0.5])
        >>> maps.K.round(12).tolist()
        [2.0, 1.0]
        >>> maps([[[0.5, 0.5]], [[0.5, 0.5]]]).round(12).tolist()
        [[[1.0, 0.5]], [[1.0, 1.0]]]
        """
        return _fpi_many(src, dst)

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


# --- Many FPIs at once (batches): the same construction on (N, 4) arrays.
#: Relative band around each threshold of the construction and its checks
#: within which a map is rebuilt by :class:`FPI` itself (whose decision is
#: the definition); elsewhere the vectorised decision is the same.
_BAND = 1e-3


def _sum4(a):
    """Sum over the last axis of 4 in Python's order (((a0 + a1) + a2) + a3)."""
    return ((a[..., 0] + a[..., 1]) + a[..., 2]) + a[..., 3]


def _cross(a, b):
    return a.real * b.imag - a.imag * b.real


def _signed_area(z):
    """:func:`fpiwarp.maps.quad.signed_area` of (N, 4) quads."""
    u = z - _sum4(z / 4)[:, None]
    return 0.5 * _sum4(_cross(u, np.roll(u, -1, axis=1)))


def quads_near_refusal(z):
    """(N,) bool: quads that :func:`~fpiwarp.maps.quad.check_quad` refuses or
    might refuse (within the band of its tolerances); the others it accepts."""
    from .quad import DEGENERACY_TOL  # noqa: PLC0415

    u = z - _sum4(z / 4)[:, None]
    scale = np.abs(u).max(axis=1)
    with np.errstate(all="ignore"):
        u = u / scale[:, None]
    near = ~(scale > 0)
    tol = DEGENERACY_TOL * (1 + _BAND)
    for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)):
        near |= ~(np.abs(u[:, i] - u[:, j]) > tol)
    for a, b, c in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):  # also every sign the bow-tie test reads
        near |= ~(np.abs(_cross(u[:, c] - u[:, a], u[:, b] - u[:, a])) > tol)
    for e, f in ((0, 2), (1, 3)):
        a, b, c, d = u[:, e], u[:, (e + 1) % 4], u[:, f], u[:, (f + 1) % 4]
        near |= (_cross(b - a, c - a) * _cross(b - a, d - a) < 0) & (_cross(d - c, a - c) * _cross(d - c, b - c) < 0)
    near |= ~(np.abs(_signed_area(u)) > tol)
    return near


def _parallelogram_mobius_many(z):
    """:func:`~fpiwarp.maps.quad.parallelogram_mobius` of (N, 4) quads of
    positive orientation: (q, s, alpha) complex (N,) and (N,) bool of the
    maps whose decisions lie within the band (rebuilt one by one)."""
    from .quad import ALTERNATING, PARALLELOGRAM_TOL  # noqa: PLC0415

    q = _sum4(z) / 4
    rho = np.abs(z - q[:, None]).max(axis=1)
    v = (z - q[:, None]) / rho[:, None]
    e = np.array(ALTERNATING)
    s1 = _sum4(v)
    sum_e2 = _sum4(e * v * v)
    c0 = _sum4(e * v)
    affine = np.abs(c0) <= PARALLELOGRAM_TOL
    near = np.abs(np.abs(c0) - PARALLELOGRAM_TOL) <= _BAND * PARALLELOGRAM_TOL
    s2 = 0.5 * (s1 * s1 - _sum4(v * v))
    c1 = s1 * c0 - sum_e2
    c2 = s2 * c0 - s1 * sum_e2 + _sum4(e * v * (v * v))
    with np.errstate(all="ignore"):
        root = np.sqrt(c1 * c1 - 4 * c2 * c0)
        plus, minus = np.abs(c1 + root), np.abs(c1 - root)
        near |= np.abs(plus - minus) <= _BAND * np.maximum(plus, minus)
        big = np.where(plus >= minus, c1 + root, c1 - root)
        cands = np.stack([np.where(big != 0, 2 * c0 / big, np.nan), np.where(c2 != 0, big / (2 * c2), np.nan)])
        dens = 1 - cands[:, :, None] * v[None]
        p = v[None] / dens
        area = np.stack([_signed_area(p[0]), _signed_area(p[1])])
        radius = np.abs(p - _sum4(p / 4)[..., None]).max(axis=2)
        ok = np.isfinite(cands) & (np.abs(dens).min(axis=2) > 1e-12) & np.all(np.isfinite(p), axis=2) & (area > 0)
        near |= (np.isfinite(cands) & ((np.abs(np.abs(dens).min(axis=2) - 1e-12) <= 1e-12 * _BAND)
                                       | (np.abs(area) <= _BAND * radius**2))).any(axis=0)
        size = np.where(ok, np.abs(cands), np.inf)
        near |= ok.all(axis=0) & (np.abs(size[0] - size[1]) <= _BAND * np.maximum(size[0], size[1]))
    near |= ~ok.any(axis=0)
    best = np.where(size[0] <= size[1], cands[0], cands[1])
    s = np.where(affine, 0, best / rho)
    return q, np.where(np.isfinite(s), s, 0), (1 / rho).astype(complex), near & ~affine | ~np.isfinite(s)


def _mobius(z, q, s, alpha):
    """beta = 0 centered Möbius maps, (N,) parts, at (N, P) points."""
    u = z - q[:, None]
    return alpha[:, None] * u / (1 - s[:, None] * u)


def mobius_inverse_many(p, q, s, alpha):
    """The inverses of :func:`_mobius` at (N, P) points."""
    return q[:, None] + (1 / alpha)[:, None] * p / (1 + (s / alpha)[:, None] * p)


def _frames(p):
    ea = 0.5 * ((p[:, 1] - p[:, 0]) + (p[:, 2] - p[:, 3]))
    eb = 0.5 * ((p[:, 3] - p[:, 0]) + (p[:, 2] - p[:, 1]))
    return _sum4(p) / 4, ea, eb


class FPIStack(Sequence):
    """N four-point interpolants built at once, as arrays: what ``[FPI(s, d)
    for s, d in zip(src, dst)]`` gives, without N Python objects.

    Made by :meth:`fpiwarp.FPI.many`. ``stack[i]`` is map i as an :class:`FPI`
    (the same parts); ``K``, ``src``, ``dst`` are arrays; ``stack(points)``
    maps (N, P, 2) point sets, set i by map i; ``inverse`` is the stack of
    inverses. :func:`fpiwarp.warp_batch` and :func:`fpiwarp.map_points_batch`
    take it as their ``transforms`` and pack its blocks in one pass
    (:meth:`block_stack`).

    The construction and its checks are those of :class:`FPI`, on (N, 4)
    arrays; a map whose decision (a degeneracy tolerance, the choice of
    Möbius root, the exactness probes) lies within a narrow band of a
    threshold is rebuilt by :class:`FPI` itself, so the stack accepts and
    refuses exactly what :class:`FPI` does, with its messages prefixed by
    the map's index. Parts agree with :class:`FPI`'s within 1e-12
    relative (numpy's and Python's complex division round differently), K
    within 1e-14 K² (``|l1| - |l2|`` cancels), float32 blocks within one
    float32 ulp (measured: bit for bit on 500 of 500 random maps).
    """

    def __init__(self, z, w, parts):
        self._z, self._w = z, w
        self._parts = parts  # (q_src, s_src, alpha_src, l1, l2, l3, q_dst, s_dst, alpha_dst), complex (N,)

    @classmethod
    def of(cls, fpis):
        """The stack of given :class:`FPI` objects (their parts as they are)."""
        fpis = list(fpis)
        z = np.array([f._z for f in fpis], dtype=complex).reshape(-1, 4)
        w = np.array([f._w for f in fpis], dtype=complex).reshape(-1, 4)
        return cls(z, w, tuple(np.array(v, dtype=complex) for v in zip(*(_parts_of(f) for f in fpis))))

    @property
    def parts(self):
        """(q_src, s_src, alpha_src, l1, l2, l3, q_dst, s_dst, alpha_dst),
        complex (N,) each: the centered Möbius parts (beta = 0) and the
        R-linear part of every map, f = m_dst⁻¹ ∘ A ∘ m_src."""
        return self._parts

    def __len__(self):
        return len(self._z)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return FPIStack(self._z[i], self._w[i], tuple(p[i] for p in self._parts))
        qs, ss, als, l1, l2, l3, qd, sd, ald = (complex(p[i]) for p in self._parts)
        m_src, m_dst = Mobius.centered(qs, ss, als, 0), Mobius.centered(qd, sd, ald, 0)
        return FPI._from_parts(self._z[i].copy(), self._w[i].copy(), m_src, RLinear(l1, l2, l3), m_dst)

    @property
    def src(self):
        return np.stack([self._z.real, self._z.imag], axis=-1)

    @property
    def dst(self):
        return np.stack([self._w.real, self._w.imag], axis=-1)

    @property
    def K(self):
        """(N,) the constant conformal distortion of each map."""
        a, b = np.abs(self._parts[3]), np.abs(self._parts[4])
        return (a + b) / (a - b)

    @property
    def inverse(self):
        """The stack of the inverses (the FPIs from dst to src)."""
        qs, ss, als, l1, l2, l3, qd, sd, ald = self._parts

        m1, m2, m3 = rlinear_inverse_many(l1, l2, l3)
        return FPIStack(self._w, self._z, (qd, sd, ald, m1, m2, m3, qs, ss, als))

    @property
    def poles(self):
        """(N,) complex: the point each map sends to infinity (z∞ of
        :attr:`fpiwarp.FPI.pole`), NaN where the map is affine (no pole)."""
        qs, ss, als, l1, l2, l3, qd, sd, ald = self._parts

        m1, m2, m3 = rlinear_inverse_many(l1, l2, l3)
        with np.errstate(all="ignore"):
            zeta = np.where(sd != 0, -ald / sd, np.nan)  # m_dst(∞); A⁻¹ of it, then m_src⁻¹
            xi = m1 * zeta + m2 * np.conj(zeta) + m3
            pole = mobius_inverse_many(xi[:, None], qs, ss, als)[:, 0]
            pole = np.where(sd != 0, pole, np.where(ss != 0, qs + 1 / ss, np.nan))
        return np.where(np.isfinite(pole), pole, np.nan)

    def map_complex(self, z):
        """(N, P) complex points, set i mapped by map i."""
        qs, ss, als, l1, l2, l3, qd, sd, ald = self._parts
        with np.errstate(all="ignore"):
            p = _mobius(z, qs, ss, als)
            p = l1[:, None] * p + l2[:, None] * np.conj(p) + l3[:, None]
            return mobius_inverse_many(p, qd, sd, ald)

    def __call__(self, points):
        """(N, ..., 2) points, set i mapped by map i (float64)."""
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim < 2 or pts.shape[0] != len(self) or pts.shape[-1] != 2:
            raise ArgumentError(f"points must have shape ({len(self)}, ..., 2), got {pts.shape}")
        flat = pts.reshape(len(self), -1, 2)
        w = self.map_complex(flat[..., 0] + 1j * flat[..., 1])
        return np.stack([w.real, w.imag], axis=-1).reshape(pts.shape)

    def block_stack(self):
        """The maps' float32 parameter blocks (one stage each) as a
        ``fpiwarp.block.many.BlockStack``, packed in one pass."""

        qs, ss, als, l1, l2, l3, qd, sd, ald = self._parts
        # the stage of FPI.stages(): pre = m_src (beta 0), post = m_dst⁻¹ centered at 0 (m_dst's beta is 0)
        return pack_one_stage(qs, ss, als, 1 / ald, -sd / ald, qd, l1, l2, l3)

    def __repr__(self):
        return f"FPIStack(<{len(self)} maps>)"


def _fpi_many(src, dst):

    names = ("src", "dst")
    arrs = []
    for name, given in zip(names, (src, dst)):
        try:
            arr = np.asarray(given, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise DegenerateQuadError(f"{name} must be (N, 4, 2) numeric points: {exc}") from None
        if np.iscomplexobj(np.asarray(given)):
            raise DegenerateQuadError(f"{name} must be real (x, y) points, got complex numbers")
        if arr.ndim != 3 or arr.shape[1:] != (4, 2):
            raise DegenerateQuadError(f"{name} must have shape (N, 4, 2), got {arr.shape}")
        arrs.append(arr)
    if arrs[0].shape != arrs[1].shape:
        raise DegenerateQuadError(f"src and dst must have the same shape, got {arrs[0].shape} and {arrs[1].shape}")
    n = arrs[0].shape[0]
    z = arrs[0][..., 0] + 1j * arrs[0][..., 1]
    w = arrs[1][..., 0] + 1j * arrs[1][..., 1]
    if n <= _FEW:  # a few maps: one FPI each is quicker than the arrays' fixed cost
        return _from_fpis(arrs, n, z, w)
    chunks = [_build_chunk(arrs[0][a:a + _CHUNK], arrs[1][a:a + _CHUNK], z[a:a + _CHUNK], w[a:a + _CHUNK])
              for a in range(0, n, _CHUNK)]
    parts = [np.concatenate([c[0][k] for c in chunks]) if chunks else np.zeros(0, complex) for k in range(9)]
    rebuild = np.concatenate([c[1] for c in chunks]) if chunks else np.zeros(0, bool)
    for i in np.flatnonzero(rebuild):
        _one_into(parts, i, arrs, n)
    return FPIStack(z, w, tuple(parts))


#: Up to this many maps FPI.many builds one FPI each (~0.1 ms a map; the
#: arrays' path costs ~0.5 ms however few maps it builds).
_FEW = 4


def _parts_of(f):
    return (f.m_src.q, f.m_src.s, f.m_src.alpha, f.linear.l1, f.linear.l2, f.linear.l3, f.m_dst.q, f.m_dst.s,
            f.m_dst.alpha)


def _one_into(parts, i, arrs, n):
    """Build map i of n as one FPI (its own checks and errors, prefixed with
    which map) and write its nine parts into ``parts`` at i."""
    from ..errors import FpiwarpError  # noqa: PLC0415

    try:
        f = FPI(arrs[0][i], arrs[1][i])
    except FpiwarpError as exc:
        raise type(exc)(f"map {i} of {n}: {exc}") from None
    for part, value in zip(parts, _parts_of(f)):
        part[i] = value


def _from_fpis(arrs, n, z, w):
    parts = [np.zeros(n, complex) for _ in range(9)]
    for i in range(n):
        _one_into(parts, i, arrs, n)
    return FPIStack(z, w, tuple(parts))


#: Maps built together: their (N, 29) probe arrays stay in the CPU's cache.
_CHUNK = 1024


def _build_chunk(src, dst, z, w):
    """(parts, rebuild) of a chunk of maps (see :func:`_fpi_many`)."""
    from .quad import EPS, EXACT_RTOL, MAX_COORDINATE, MAX_K, REPRESENTATION_ULPS, ROUND_TRIP_MARGIN  # noqa: PLC0415

    finite = np.all(np.isfinite(src) & np.isfinite(dst) & (np.abs(src) <= MAX_COORDINATE)
                    & (np.abs(dst) <= MAX_COORDINATE), axis=(1, 2))
    zs, ws = np.where(finite[:, None], z, 0), np.where(finite[:, None], w, 0)
    with np.errstate(all="ignore"):
        rebuild = ~finite | quads_near_refusal(zs) | quads_near_refusal(ws)
        area_z, area_w = _signed_area(zs), _signed_area(ws)
        rebuild |= (area_z < 0) != (area_w < 0)
        flip = area_z < 0
        zc, wc = np.where(flip[:, None], np.conj(zs), zs), np.where(flip[:, None], np.conj(ws), ws)
        qs, ss, als, near_s = _parallelogram_mobius_many(zc)
        qd, sd, ald, near_d = _parallelogram_mobius_many(wc)
        rebuild |= near_s | near_d
        cp, pa, pb = _frames(_mobius(zc, qs, ss, als))
        cr, ra, rb = _frames(_mobius(wc, qd, sd, ald))
        det = pa * np.conj(pb) - np.conj(pa) * pb
        l1 = (ra * np.conj(pb) - np.conj(pa) * rb) / det
        l2 = (pa * rb - pb * ra) / det
        l3 = cr - l1 * cp - l2 * np.conj(cp)
        a, b = np.abs(l1), np.abs(l2)
        K = (a + b) / (a - b)
        rebuild |= ~(np.isfinite(l1) & np.isfinite(l2) & np.isfinite(l3)) | ~(K >= 1) | ~(K <= MAX_K / 2)
    parts = [qs, ss, als, l1, l2, l3, qd, sd, ald]
    for k in range(len(parts)):  # mirror the clockwise maps' parts back
        parts[k] = np.where(flip, np.conj(parts[k]), parts[k])
        parts[k] = np.where(rebuild, 0, parts[k])
    parts[2] = np.where(rebuild, 1, parts[2])
    parts[8] = np.where(rebuild, 1, parts[8])
    parts[3] = np.where(rebuild, 2, parts[3])
    stack = FPIStack(z, w, tuple(parts))
    with np.errstate(all="ignore"):
        rebuild |= _inexact(stack, z, w, EPS, EXACT_RTOL, REPRESENTATION_ULPS, ROUND_TRIP_MARGIN)
    return parts, rebuild


#: Probe grid of the exactness check (:func:`fpiwarp.maps.quad.check_exact`), in units of the source's box.
_PROBE = np.linspace(-1.0, 2.0, 5)


def _inexact(stack, z, w, eps, rtol, ulps, margin):
    """(N,) bool: maps :func:`~fpiwarp.maps.quad.check_exact` refuses or might
    refuse (errors within a factor 4 of its limits): corners, inverse
    corners and round trips over a 5 × 5 grid around the source (the
    probes near the pole replaced by the first corner)."""
    n = len(stack)
    cz, cw = _sum4(z) / 4, _sum4(w) / 4
    rz, rw = np.abs(z - cz[:, None]).max(axis=1), np.abs(w - cw[:, None]).max(axis=1)
    allowed_z = rtol * rz + ulps * eps * np.abs(np.stack([z.real, z.imag])).max(axis=(0, 2))
    largest_w = np.abs(np.stack([w.real, w.imag])).max(axis=(0, 2))
    allowed_w = rtol * rw + ulps * eps * largest_w
    lo_x, lo_y = z.real.min(axis=1), z.imag.min(axis=1)
    xs = lo_x[:, None] + (z.real.max(axis=1) - lo_x)[:, None] * _PROBE
    ys = lo_y[:, None] + (z.imag.max(axis=1) - lo_y)[:, None] * _PROBE
    grid = (xs[:, None, :] + 1j * ys[:, :, None]).reshape(n, -1)
    inv = stack.inverse
    pole = inv.map_complex(np.full((n, 1), 1e300 + 0j))[:, 0]  # near the image of infinity: rounding-free enough
    near_pole = np.abs(grid - pole[:, None]) <= 0.1 * rz[:, None]  # the check skips 0.05 radii; rings left out
    grid = np.where(near_pole, z[:, :1], grid)
    forward = stack.map_complex(np.concatenate([z, grid], axis=1))
    back = inv.map_complex(np.concatenate([w, forward[:, 4:]], axis=1))
    K = stack.K
    err_w = np.abs(forward[:, :4] - w).max(axis=1)
    err_z = np.abs(back[:, :4] - z).max(axis=1)
    err_r = np.abs(back[:, 4:] - grid).max(axis=1)
    allowed_r = (allowed_z + K * rz / rw * ulps * eps * largest_w) / margin
    pole_in_box = (xs[:, 0] - rz <= pole.real) & (pole.real <= xs[:, -1] + rz) & (ys[:, 0] - rz <= pole.imag) & \
        (pole.imag <= ys[:, -1] + rz)
    return ~(err_w * 4 <= allowed_w) | ~(err_z * 4 <= allowed_z) | ~(err_r * 4 <= allowed_r) | pole_in_box
