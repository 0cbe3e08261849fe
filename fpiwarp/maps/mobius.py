"""Möbius maps m(z) = (a z + b) / (c z + d), stored in a centered form.

The centered form m(z) = beta + alpha * u / (1 - s * u), u = z - q, keeps
the numbers well conditioned in float32 when q sits near the data: s is
the reciprocal distance from q to the pole (s = 0: no pole, m is a
similarity), and the inverse has the same form with
(q, s, alpha, beta) -> (beta, -s / alpha, 1 / alpha, q).
"""

import math

import numpy as np

from ..block import LinearPart, MobiusPart, Stage
from ..errors import ArgumentError
from .transform import Transform


def _complex(value, name):
    value = complex(value)
    if not math.isfinite(value.real) or not math.isfinite(value.imag):  # math: ~10x cheaper on scalars
        raise ArgumentError(f"{name} must be finite, got {value}")
    return value


class Mobius(Transform):
    """A Möbius map, conformal everywhere but at its pole.

    ``Mobius(a, b, c, d)`` is z -> (a z + b) / (c z + d) with ad - bc != 0.
    ``Mobius.centered(q, s, alpha, beta)`` builds it from the centered form.

    Parameters
    ----------
    a, b, c, d : complex
        The coefficients, with ``ad - bc != 0``. A point (x, y) is the
        complex number x + iy.
    center : complex, optional
        A point near where the map is used, about which it is stored
        (keeps the float32 parameter block well conditioned).

    Raises
    ------
    ArgumentError
        ``ad - bc == 0``, or coefficients that are not finite numbers.

    Examples
    --------
    >>> m = Mobius(1, 0, 0, 2)          # z / 2
    >>> m([[2.0, 4.0]]).tolist()
    [[1.0, 2.0]]
    >>> Mobius(1, 2, 2, 4)
    Traceback (most recent call last):
    ...
    fpiwarp.ArgumentError: Möbius coefficients need ad - bc != 0
    """

    def __init__(self, a: complex, b: complex, c: complex, d: complex, *, center: complex | None = None):
        a, b, c, d = (_complex(v, n) for v, n in zip((a, b, c, d), "abcd"))
        det = a * d - b * c
        scale = max(abs(a * d), abs(b * c), 1e-300)
        if abs(det) <= 1e-14 * scale:
            raise ArgumentError("Möbius coefficients need ad - bc != 0")
        q = 0j if center is None else _complex(center, "center")
        if abs(c * q + d) <= 1e-12 * (abs(c * q) + abs(d)):
            # the center sits on the pole -d/c (c != 0 here, as ad - bc != 0):
            # center the form one pole-distance-from-origin (at least 1) away
            q = -d / c + max(1.0, abs(d / c))
        den = c * q + d
        try:
            den2 = den**2
        except OverflowError:
            den2 = complex(math.inf)
        if den2 == 0 or not math.isfinite(abs(den2)):  # cz + d at the center under- or overflows when squared
            raise ArgumentError(f"Möbius coefficients (c z + d = {den:g} at the center {q:g}) are outside "
                                "float64's range there; rescale them or pick another center")
        self._set(q, -c / den, det / den2, (a * q + b) / den)

    @classmethod
    def centered(cls, q, s, alpha, beta):
        """m(z) = beta + alpha * (z - q) / (1 - s * (z - q))."""
        obj = cls.__new__(cls)
        alpha = _complex(alpha, "alpha")
        if alpha == 0:
            raise ArgumentError("alpha must be non-zero")
        obj._set(_complex(q, "q"), _complex(s, "s"), alpha, _complex(beta, "beta"))
        return obj

    @classmethod
    def from_points(cls, src, dst):
        """The unique Möbius map sending three points to three points."""
        from .points import as_complex

        z = as_complex(src, "src")
        w = as_complex(dst, "dst")
        if z.shape != (3,) or w.shape != (3,):
            raise ArgumentError("from_points needs three source and three target points")
        for name, pts in (("src", z), ("dst", w)):
            if len({complex(v) for v in pts}) < 3 or not np.all(np.isfinite(pts)):
                raise ArgumentError(f"from_points needs three distinct finite {name} points, got {pts}")
        # cross-ratio maps of each triple to (0, 1, inf), then compose
        mz = _to_standard(z)
        mw = _to_standard(w)
        return Mobius(*mobius_product(_inv(mw), mz), center=z.mean())

    def _set(self, q, s, alpha, beta):
        self.q, self.s, self.alpha, self.beta = q, s, alpha, beta

    @property
    def coefficients(self):
        """(a, b, c, d) with m(z) = (a z + b) / (c z + d)."""
        q, s, al, be = self.q, self.s, self.alpha, self.beta
        return (al - be * s, be + be * s * q - al * q, -s, 1 + s * q)

    @property
    def pole(self):
        """The point sent to infinity, as (x, y); None for a similarity."""
        if self.s == 0:
            return None
        p = self.q + 1 / self.s
        return np.array([p.real, p.imag])

    @property
    def pole_image(self):
        """The image of infinity, as (x, y); None for a similarity."""
        if self.s == 0:
            return None
        p = self.beta - self.alpha / self.s
        return np.array([p.real, p.imag])

    K = 1.0
    dilation = 0.0

    def _map(self, z):
        u = z - self.q
        return self.beta + self.alpha * u / (1 - self.s * u)

    def _wirtinger(self, z):
        u = z - self.q
        den = 1 - self.s * u
        w = self.beta + self.alpha * u / den
        fz = self.alpha / den**2
        return w, fz, np.zeros_like(fz)

    @property
    def inverse(self):
        return Mobius.centered(self.beta, -self.s / self.alpha, 1 / self.alpha, self.q)

    def _fuse_with(self, nxt):
        if isinstance(nxt, Mobius):
            return Mobius(*mobius_product(nxt.coefficients, self.coefficients), center=self.q)
        return None

    def conjugated(self) -> "Mobius":
        """z -> conj(m(conj z)), the same map seen in the mirrored plane."""
        return Mobius.centered(*(np.conj(v) for v in (self.q, self.s, self.alpha, self.beta)))

    def stages(self) -> list[Stage]:
        pre = MobiusPart(center=self.q, inverse_pole=self.s, scale=self.alpha)
        return [Stage(pre=pre, linear=LinearPart(1, 0, self.beta))]

    def __repr__(self):
        return f"Mobius.centered(q={self.q!r}, s={self.s!r}, alpha={self.alpha!r}, beta={self.beta!r})"


def mobius_product(m, n):
    """Coefficients (a, b, c, d) of the Möbius map m ∘ n, from those of m and
    n (the product of their 2×2 coefficient matrices)."""
    a, b, c, d = m
    e, f, g, h = n
    return (a * e + b * g, a * f + b * h, c * e + d * g, c * f + d * h)


def centered_at_zero(m):
    """Möbius ``m`` as the post-Möbius part of a block stage, written about 0:
    m(p) = offset + scale p / (1 - inverse_pole p), whatever its center q."""
    if m.q != 0:
        m = Mobius(*m.coefficients, center=0)
    return MobiusPart(inverse_pole=m.s, scale=m.alpha, offset=m.beta)


def _inv(m):
    a, b, c, d = m
    return (d, -b, -c, a)


def _to_standard(z):
    """Coefficients of the Möbius map sending z0, z1, z2 to 0, 1, inf."""
    z0, z1, z2 = z
    return (z1 - z2, -z0 * (z1 - z2), z1 - z0, -z2 * (z1 - z0))
