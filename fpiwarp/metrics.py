"""Distortion metrics of the paper's §5.1, for any map over points or a grid.

For a map f with Wirtinger derivatives f_z, f_zbar:

- conformal distortion ``K = (|f_z| + |f_zbar|) / (|f_z| - |f_zbar|) >= 1``
  (inf where f folds over, ``|f_zbar| >= |f_z|``);
- conformal dilation ``d = |f_zbar| / |f_z| = (K - 1) / (K + 1)``, 0 iff
  conformal, > 1 where f reverses orientation;
- Jacobian determinant ``J = |f_z|² - |f_zbar|²``, and the area distortion
  max J + 1 / min J (inf when min J <= 0: a fold-over or a singularity).

Maps that are :class:`~fpiwarp.Transform` objects use their analytic
derivatives; any other callable taking (N, 2) points to (N, 2) points is
differentiated by central differences with step ``h``.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .errors import ArgumentError, ArgumentTypeError
from .maps.points import as_complex, as_xy
from .maps.transform import Transform, distortion_from_wirtinger

#: What the metrics measure: an fpiwarp map (analytic derivatives) or any
#: callable taking (N, 2) points to (N, 2) points (central differences).
MapLike = Transform | Callable[[np.ndarray], np.ndarray]


def _derivatives(f, points, h):
    z = as_complex(points)
    if isinstance(f, Transform):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            _, fz, fzb = f.wirtinger(z)
        return fz, fzb
    if not callable(f):
        raise ArgumentTypeError(f"f must be a Transform or a callable on (N, 2) points, got {type(f).__name__}")
    flat = z.reshape(-1)
    scale = max(1.0, float(np.max(np.abs(flat)))) if flat.size else 1.0
    step = h * scale

    def g(p):
        out = np.asarray(f(as_xy(p)), dtype=np.float64)
        return out[..., 0] + 1j * out[..., 1]

    fx = (g(flat + step) - g(flat - step)) / (2 * step)
    fy = (g(flat + 1j * step) - g(flat - 1j * step)) / (2 * step)
    return (0.5 * (fx - 1j * fy)).reshape(z.shape), (0.5 * (fx + 1j * fy)).reshape(z.shape)


def conformal_distortion(f: MapLike, points: ArrayLike, h: float = 1e-6) -> np.ndarray:
    """Pointwise conformal distortion K of ``f`` at ``points``.

    Parameters
    ----------
    f : Transform or callable
        An fpiwarp map (analytic derivatives) or any callable taking (N, 2)
        points to (N, 2) points (central differences).
    points : array_like, shape (..., 2)
        Where to measure, ``(x, y)``.
    h : float, optional
        Relative step of the central differences (callables only).

    Returns
    -------
    ndarray, shape (...)
        ``K = (|f_z| + |f_zbar|) / (|f_z| - |f_zbar|) >= 1``; inf where
        ``f`` folds over or is singular.

    Raises
    ------
    ArgumentTypeError
        ``f`` is neither a Transform nor callable.

    Examples
    --------
    >>> import fpiwarp
    >>> from fpiwarp.metrics import conformal_distortion
    >>> f = fpiwarp.FPI([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 0], [2, 0], [2, 1], [0, 1]])
    >>> conformal_distortion(f, [[0.2, 0.3], [0.9, 0.1]]).round(9).tolist()   # constant: the FPI's K
    [2.0, 2.0]
    """
    return distortion_from_wirtinger(*_derivatives(f, points, h))


def conformal_dilation(f: MapLike, points: ArrayLike, h: float = 1e-6) -> np.ndarray:
    """Pointwise conformal dilation ``|f_zbar| / |f_z|`` at (..., 2) ``points``.

    Parameters
    ----------
    f : Transform or callable
        An fpiwarp map (analytic derivatives) or any callable taking (N, 2)
        points to (N, 2) points (central differences).
    points : array_like, shape (..., 2)
        Where to measure, ``(x, y)``.
    h : float, optional
        Relative step of the central differences (callables only).

    Returns
    -------
    ndarray, shape (...)
        ``d = (K - 1) / (K + 1)``: 0 where ``f`` is conformal, above 1 where
        it reverses orientation.

    Examples
    --------
    >>> from fpiwarp.metrics import conformal_dilation
    >>> stretch = lambda p: p * [3.0, 1.0]                   # any callable: finite differences
    >>> conformal_dilation(stretch, [[1.0, 2.0]]).round(6).tolist()
    [0.5]
    """
    fz, fzb = _derivatives(f, points, h)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(fzb) / np.abs(fz)


def jacobian_determinant(f: MapLike, points: ArrayLike, h: float = 1e-6) -> np.ndarray:
    """Pointwise Jacobian determinant ``|f_z|² - |f_zbar|²`` (> 0: orientation kept).

    Parameters
    ----------
    f : Transform or callable
        An fpiwarp map (analytic derivatives) or any callable taking (N, 2)
        points to (N, 2) points (central differences).
    points : array_like, shape (..., 2)
        Where to measure, ``(x, y)``.
    h : float, optional
        Relative step of the central differences (callables only).

    Returns
    -------
    ndarray, shape (...)
        The local area scale of ``f``; negative where it reverses
        orientation.

    Examples
    --------
    >>> import fpiwarp
    >>> from fpiwarp.metrics import jacobian_determinant
    >>> jacobian_determinant(fpiwarp.RLinear(2, 0, 0), [[5.0, 5.0]]).round(9).tolist()   # scale 2: area 4
    [4.0]
    """
    fz, fzb = _derivatives(f, points, h)
    return np.abs(fz) ** 2 - np.abs(fzb) ** 2


def area_distortion(f: MapLike, points: ArrayLike, h: float = 1e-6) -> float:
    """The area distortion ``max J + 1 / min J`` over ``points`` (paper §5.1).

    Parameters
    ----------
    f : Transform or callable
        An fpiwarp map (analytic derivatives) or any callable taking (N, 2)
        points to (N, 2) points (central differences).
    points : array_like, shape (..., 2)
        Where to measure, ``(x, y)``.
    h : float, optional
        Relative step of the central differences (callables only).

    Returns
    -------
    float
        Smallest (2) for an area-preserving map; inf if some J <= 0 (a
        fold-over or a singularity).

    Examples
    --------
    >>> import fpiwarp
    >>> from fpiwarp.metrics import area_distortion, grid
    >>> round(area_distortion(fpiwarp.RLinear(1, 0, 5), grid([[0, 0], [1, 1]], n=4)), 9)
    2.0
    """
    jac = jacobian_determinant(f, points, h)
    lo = float(np.min(jac))
    if not lo > 0:
        return float("inf")
    return float(np.max(jac)) + 1.0 / lo


@dataclass(frozen=True)
class DistortionSummary:
    """The columns of the paper's §5.1 table, plus the maximal K."""

    max_dilation: float
    mean_dilation: float
    std_dilation: float
    area_distortion: float
    max_distortion: float


def summarize(f: MapLike, points: ArrayLike, h: float = 1e-6) -> DistortionSummary:
    """The paper's §5.1 table row for ``f`` over ``points``.

    Parameters
    ----------
    f : Transform or callable
        An fpiwarp map (analytic derivatives) or any callable taking (N, 2)
        points to (N, 2) points (central differences).
    points : array_like, shape (..., 2)
        Where to measure, ``(x, y)``.
    h : float, optional
        Relative step of the central differences (callables only).

    Returns
    -------
    DistortionSummary
        Max, mean and std of the dilation, the area distortion and the
        maximal K.

    Examples
    --------
    >>> import fpiwarp
    >>> from fpiwarp.metrics import grid, summarize
    >>> f = fpiwarp.FPI([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 0], [0.97, 0], [1.7, 0.16], [0, 0.99]])
    >>> s = summarize(f, grid([[0, 0], [1, 1]], n=50))
    >>> round(s.max_dilation, 2), round(s.mean_dilation, 2), round(s.std_dilation, 6)
    (0.32, 0.32, 0.0)
    """
    fz, fzb = _derivatives(f, points, h)
    with np.errstate(divide="ignore", invalid="ignore"):
        dil = np.abs(fzb) / np.abs(fz)
    jac = np.abs(fz) ** 2 - np.abs(fzb) ** 2
    lo = float(np.min(jac))
    return DistortionSummary(
        max_dilation=float(np.max(dil)),
        mean_dilation=float(np.mean(dil)),
        std_dilation=float(np.std(dil)),
        area_distortion=float(np.max(jac)) + 1.0 / lo if lo > 0 else float("inf"),
        max_distortion=float(np.max(distortion_from_wirtinger(fz, fzb))),
    )


def grid(corners: ArrayLike, n: int = 64) -> np.ndarray:
    """An n × n grid of points spanning a quad (bilinear), shape (n, n, 2).

    ``corners`` is (4, 2) in quad order, or (2, 2) [[x0, y0], [x1, y1]]
    for an axis-aligned rectangle.

    >>> grid([[0, 0], [2, 1]], n=3)[..., 0].tolist()
    [[0.0, 1.0, 2.0], [0.0, 1.0, 2.0], [0.0, 1.0, 2.0]]
    """
    c = np.asarray(corners, dtype=np.float64)
    if c.shape == (2, 2):
        (x0, y0), (x1, y1) = c
        c = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    if c.shape != (4, 2):
        raise ArgumentError(f"corners must be (4, 2) quad corners or (2, 2) rectangle bounds, got {c.shape}")
    n = int(n)
    if n < 2:
        raise ArgumentError(f"a grid needs n >= 2, got {n}")
    s = np.linspace(0.0, 1.0, n)[None, :, None]
    t = np.linspace(0.0, 1.0, n)[:, None, None]
    return (1 - t) * ((1 - s) * c[0] + s * c[1]) + t * ((1 - s) * c[3] + s * c[2])
