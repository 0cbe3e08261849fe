"""The FPI curve of the paper's Fig. 6: a closed curve through four anchors.

Four equally spaced points of the unit circle are sent to the anchors by
an FPI, and the curve is the image of the whole circle. The FPI is a
bijection of the plane minus its pole, so the curve never crosses itself;
it is bounded unless the circle passes through the pole, which is refused.
"""

import numpy as np
from numpy.typing import ArrayLike

from .maps.fpi import FPI
from .maps.points import as_xy
from .maps.quad import check_quad, signed_area


def curve_map(anchors: ArrayLike) -> FPI:
    """The FPI sending 1, i, -1, -i (clockwise anchors: 1, -i, -1, i) to the anchors."""
    z = check_quad(anchors, "anchors")
    ring = np.array([1, 1j, -1, -1j]) if signed_area(z) > 0 else np.array([1, -1j, -1, 1j])
    return FPI(as_xy(ring), as_xy(z))


def fpi_curve(anchors: ArrayLike, n: int = 256) -> np.ndarray:
    """The closed FPI curve through four anchor points (paper Fig. 6).

    Parameters
    ----------
    anchors : array_like, shape (4, 2)
        Four ``(x, y)`` points forming a simple quad, in the order the
        curve visits them.
    n : int, optional
        Points on the curve, at least 4 (default 256).

    Returns
    -------
    ndarray, float64, shape (n, 2)
        The curve, not repeating its start; point ``k * n // 4`` is anchor
        ``k`` when ``n`` is a multiple of 4.

    Raises
    ------
    DegenerateQuadError
        Invalid anchors.
    ValueError
        ``n < 4``, or the FPI's pole lies on the circle (the curve would
        pass through infinity).

    Examples
    --------
    >>> c = fpi_curve([[0, 0], [2, 0], [2, 1], [0, 1]], n=8)
    >>> np.round(c[::2], 12).tolist()
    [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]
    """
    n = int(n)
    if n < 4:
        raise ValueError(f"a closed curve needs at least 4 points, got n={n}")
    f = curve_map(anchors)
    pole = f.pole
    if pole is not None and abs(np.hypot(*pole) - 1) < 1e-9:
        raise ValueError("the FPI's pole lies on the circle: the curve would pass through infinity")
    z = check_quad(anchors, "anchors")
    sign = 1 if signed_area(z) > 0 else -1
    t = 2 * np.pi * np.arange(n) / n
    circle = np.exp(1j * sign * t)
    curve = f(as_xy(circle))
    exact = np.arange(0, n, n // 4)[:4] if n % 4 == 0 else []
    for k, i in enumerate(exact):
        curve[i] = (z[k].real, z[k].imag)
    return curve
