"""R-linear (real-affine) maps A(z) = l1 z + l2 conj(z) + l3.

Every real affine map of the plane has this form; its Wirtinger
derivatives are the constants f_z = l1 and f_zbar = l2, so its conformal
distortion is the constant K = (|l1| + |l2|) / (|l1| - |l2|).
"""

import math

import numpy as np

from ..block import LinearPart, Stage
from ..block.pack import rlinear_inverse
from ..errors import ArgumentError
from .transform import Transform


class RLinear(Transform):
    """The affine map A(z) = l1 z + l2 conj(z) + l3 of the plane.

    Parameters
    ----------
    l1, l2, l3 : complex
        The coefficients; a point (x, y) is z = x + iy. ``l2 = 0`` gives a
        similarity; ``|l1| == |l2|`` is singular. Its conformal distortion
        is ``K = (|l1| + |l2|) / (|l1| - |l2|)``, the same everywhere.

    Raises
    ------
    ArgumentError
        ``|l1| == |l2|`` or coefficients that are not finite.

    Examples
    --------
    >>> A = RLinear(1, 0, 3 + 4j)       # translation by (3, 4)
    >>> A([[1.0, 1.0]]).tolist()
    [[4.0, 5.0]]
    >>> RLinear(1, 1, 0)
    Traceback (most recent call last):
    ...
    fpiwarp.ArgumentError: singular R-linear map: |l1| == |l2|
    """

    def __init__(self, l1: complex, l2: complex = 0, l3: complex = 0):
        l1, l2, l3 = complex(l1), complex(l2), complex(l3)
        if not all(math.isfinite(v) for v in (l1.real, l1.imag, l2.real, l2.imag, l3.real, l3.imag)):
            raise ArgumentError("R-linear coefficients must be finite")
        if abs(abs(l1) - abs(l2)) <= 1e-14 * (abs(l1) + abs(l2)):
            raise ArgumentError("singular R-linear map: |l1| == |l2|")
        self.l1, self.l2, self.l3 = l1, l2, l3

    @classmethod
    def from_matrix(cls, matrix, offset=(0.0, 0.0)):
        """From the real map p -> matrix @ p + offset (matrix 2×2, offset 2)."""
        (m00, m01), (m10, m11) = np.asarray(matrix, dtype=np.float64)
        fz = 0.5 * complex(m00 + m11, m10 - m01)
        fzb = 0.5 * complex(m00 - m11, m10 + m01)
        return cls(fz, fzb, complex(offset[0], offset[1]))

    @property
    def K(self):
        """Constant conformal distortion (negative for orientation reversal)."""
        a, b = abs(self.l1), abs(self.l2)
        return (a + b) / (a - b)

    @property
    def dilation(self):
        return abs(self.l2) / abs(self.l1)

    def _map(self, z):
        return self.l1 * z + self.l2 * np.conj(z) + self.l3

    def _wirtinger(self, z):
        w = self._map(z)
        return w, np.full(np.shape(w), self.l1), np.full(np.shape(w), self.l2)

    @property
    def inverse(self):
        try:
            mu = rlinear_inverse(LinearPart(self.l1, self.l2, self.l3))  # the block's Newton seed: one formula
        except ValueError as err:
            raise ArgumentError(str(err)) from None
        return RLinear(mu.l1, mu.l2, mu.l3)

    def _fuse_with(self, nxt):
        if isinstance(nxt, RLinear):
            return RLinear(
                nxt.l1 * self.l1 + nxt.l2 * np.conj(self.l2),
                nxt.l1 * self.l2 + nxt.l2 * np.conj(self.l1),
                nxt.l1 * self.l3 + nxt.l2 * np.conj(self.l3) + nxt.l3,
            )
        return None

    def conjugated(self) -> "RLinear":
        return RLinear(np.conj(self.l1), np.conj(self.l2), np.conj(self.l3))

    def stages(self) -> list[Stage]:
        return [Stage(linear=LinearPart(self.l1, self.l2, self.l3))]

    def __repr__(self):
        return f"RLinear({self.l1!r}, {self.l2!r}, {self.l3!r})"
