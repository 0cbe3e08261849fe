"""The interface every map of fpiwarp shares, and composition of maps.

A map takes (..., 2) arrays of (x, y) points to (..., 2) float64 arrays.
Inside, each map works on complex numbers and reports its Wirtinger
derivatives f_z and f_zbar, from which the Jacobian, the conformal
distortion K = (|f_z| + |f_zbar|) / (|f_z| - |f_zbar|) and the dilation
|f_zbar| / |f_z| follow for every map type alike.

Composition is in mathematical order: ``(g @ f)(p) == g(f(p))``.

The protocol every map implements (:class:`Transform`, an abstract base
class): ``map_complex(z)`` and ``wirtinger(z)`` on complex arrays, the
``inverse`` map and the ``stages()`` that kernels evaluate. Code outside a
map's own module calls these public names only.
"""

from __future__ import annotations

import abc
import contextlib
import contextvars
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..block import Stage, pack
from ..errors import ArgumentError, ArgumentTypeError
from .points import as_complex, as_xy

_UNSOLVED_AS_NAN = contextvars.ContextVar("fpiwarp_unsolved_as_nan", default=False)


@contextlib.contextmanager
def unsolved_as_nan():
    """Inside this block, points that a numerical inverse cannot solve come
    out NaN ("outside") instead of raising InverseNotConvergedError.

    Image warping wants this: such a pixel gets the border treatment, as in
    the kernels, while the rest of the image is still warped.
    """
    token = _UNSOLVED_AS_NAN.set(True)
    try:
        yield
    finally:
        _UNSOLVED_AS_NAN.reset(token)


def unsolved_are_nan():
    """True inside :func:`unsolved_as_nan`."""
    return _UNSOLVED_AS_NAN.get()


def chain(outer, inner_value, inner_fz, inner_fzb):
    """Wirtinger chain rule: value and derivatives of outer ∘ inner."""
    w, gz, gzb = outer.wirtinger(inner_value)
    fz = gz * inner_fz + gzb * np.conj(inner_fzb)
    fzb = gz * inner_fzb + gzb * np.conj(inner_fz)
    return w, fz, fzb


def distortion_from_wirtinger(fz, fzb):
    """K = (|f_z| + |f_zbar|) / (|f_z| - |f_zbar|); inf where the map folds or
    is singular (|f_zbar| >= |f_z|), so that a maximum flags it."""
    a, b = np.abs(fz), np.abs(fzb)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = (a + b) / (a - b)
    return np.where(a > b, k, np.inf)


def jacobian_from_wirtinger(fz, fzb):
    """The real 2×2 Jacobian J[..., i, j] = d f_i / d x_j."""
    fx = fz + fzb
    fy = 1j * (fz - fzb)
    jac = np.empty(np.shape(fz) + (2, 2), dtype=np.float64)
    jac[..., 0, 0] = fx.real
    jac[..., 0, 1] = fy.real
    jac[..., 1, 0] = fx.imag
    jac[..., 1, 1] = fy.imag
    return jac


class Transform(abc.ABC):
    """Base class of all maps: call, inverse, Jacobian, distortion, ``@``.

    The protocol, on complex128 arrays z = x + iy of any shape:

    * ``map_complex(z) -> w``: the map's values (inf or nan at its pole);
    * ``wirtinger(z) -> (w, f_z, f_zbar)``: values and Wirtinger derivatives;
    * ``inverse``: the inverse map (exact, or a numerical one that raises
      :class:`~fpiwarp.InverseNotConvergedError` rather than answer wrongly);
    * ``stages()``: the parameter-block stages, applied in order, that
      evaluate the map in the kernels (see :mod:`fpiwarp.block`).

    A subclass implements ``wirtinger`` (and ``map_complex`` where values
    alone are cheaper), ``inverse`` and ``stages``. The built-in maps
    implement the first two under the names ``_wirtinger`` and ``_map``,
    which the public methods forward to.

    Points are ``(x, y)`` in arrays of shape (..., 2) (x = column, y = row
    in images); every method keeps the leading shape.

    Examples
    --------
    >>> import numpy as np
    >>> import fpiwarp
    >>> f = fpiwarp.FPI([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 0], [2, 0], [2, 1], [0, 1]])
    >>> p = np.array([[0.25, 0.5]])
    >>> f(p).round(9).tolist(), f.inverse(f(p)).round(9).tolist()
    ([[0.5, 0.5]], [[0.25, 0.5]])
    >>> (f.jacobian(p).round(9) + 0.0).tolist()          # J[i, j] = d f_i / d x_j
    [[[2.0, 0.0], [0.0, 1.0]]]
    >>> f.distortion(p).round(9).tolist()
    [2.0]
    >>> g = fpiwarp.RLinear(1, 0, 10)                    # x -> x + 10
    >>> (g @ f)(p).round(9).tolist()                     # g after f
    [[10.5, 0.5]]
    >>> f.params().dtype.name, f.params().shape[1]       # the block kernels read
    ('float32', 4)
    """

    def __call__(self, points: ArrayLike) -> np.ndarray:
        """Map (..., 2) points; float64 (..., 2) out. Points sent to infinity
        (the pole) come out as inf or nan."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return as_xy(self.map_complex(as_complex(points)))

    def map_complex(self, z: np.ndarray) -> np.ndarray:
        """The map's values at complex128 points ``z`` (any shape)."""
        return self._map(z)

    def wirtinger(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(w, f_z, f_zbar) at complex128 points ``z``: values and Wirtinger
        derivatives, from which the Jacobian and the distortion follow."""
        return self._wirtinger(z)

    def _map(self, z):
        return self.wirtinger(z)[0]

    def _wirtinger(self, z):
        raise NotImplementedError(f"{type(self).__name__} does not implement wirtinger()")

    @property
    @abc.abstractmethod
    def inverse(self) -> Transform:
        """The inverse map."""

    @abc.abstractmethod
    def stages(self) -> list[Stage]:
        """Parameter-block stages, applied in order, that evaluate this map."""

    def params(self) -> np.ndarray:
        """The flat float32 parameter block every backend reads (ArgumentError
        for a map the block cannot hold, e.g. one whose R-linear part has no
        float64 inverse for the device Newton's seed)."""
        try:
            return pack(self.stages())
        except ValueError as err:
            raise ArgumentError(f"{type(self).__name__} cannot be packed into the parameter block: {err}") from None

    def jacobian(self, points: ArrayLike) -> np.ndarray:
        """Analytic Jacobian, shape (..., 2, 2), J[..., i, j] = d f_i / d x_j."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            _, fz, fzb = self.wirtinger(as_complex(points))
        return jacobian_from_wirtinger(fz, fzb)

    def distortion(self, points: ArrayLike) -> np.ndarray:
        """Pointwise conformal distortion K >= 1 (ratio of the Jacobian's
        singular values); inf where the map folds over."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            _, fz, fzb = self.wirtinger(as_complex(points))
        return distortion_from_wirtinger(fz, fzb)

    def dilation_at(self, points: ArrayLike) -> np.ndarray:
        """Pointwise conformal dilation ``|f_zbar| / |f_z| = (K - 1) / (K + 1)``."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            _, fz, fzb = self.wirtinger(as_complex(points))
            return np.abs(fzb) / np.abs(fz)

    def __matmul__(self, other: Transform) -> Compound:
        if not isinstance(other, Transform):
            return NotImplemented
        return Compound([other, self])


class Compound(Transform):
    """Maps applied in sequence: ``Compound([f, g])(p) == g(f(p))``.

    Nested compounds are flattened; Möbius and R-linear neighbours are
    fused into one map where the algebra allows (a Möbius after a Möbius
    is one Möbius), so kernels evaluate as few stages as possible.

    Parameters
    ----------
    steps : sequence of Transform
        The maps, in the order they are applied. ``g @ f`` is
        ``Compound([f, g])``.

    Raises
    ------
    ArgumentTypeError
        A step that is not a Transform.

    Examples
    --------
    >>> import fpiwarp
    >>> f = fpiwarp.FPI([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 0], [1, 0], [1.2, 1], [0, 1]])
    >>> g = fpiwarp.LocalDeformation([[0, 0], [1, 0], [1, 1], [0, 1]],
    ...                              [[0, 0], [1, 0], [1, 1.1], [0, 1]], edges=(3, 1))
    >>> h = fpiwarp.Compound([f, g])
    >>> bool((h([[0.5, 0.5]]) == g(f([[0.5, 0.5]]))).all()), len(h.steps)
    (True, 2)
    """

    def __init__(self, steps: Sequence[Transform]):
        flat = []
        for step in steps:
            if not isinstance(step, Transform):
                raise ArgumentTypeError(f"compound steps must be Transforms, got {type(step).__name__}")
            flat.extend(step.steps if isinstance(step, Compound) else [step])
        if not flat:
            raise ArgumentError("a compound needs at least one step")
        self.steps = tuple(_fuse(flat))

    def map_complex(self, z: np.ndarray) -> np.ndarray:
        for step in self.steps:
            z = step.map_complex(z)
        return z

    def wirtinger(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w, fz, fzb = self.steps[0].wirtinger(z)
        for step in self.steps[1:]:
            w, fz, fzb = chain(step, w, fz, fzb)
        return w, fz, fzb

    _map, _wirtinger = map_complex, wirtinger  # the former names, for code written against them

    @property
    def inverse(self) -> Transform:
        return Compound([step.inverse for step in reversed(self.steps)])

    def stages(self) -> list[Stage]:
        return [stage for step in self.steps for stage in step.stages()]

    def __repr__(self):
        return f"Compound({list(self.steps)!r})"


def _fuse(steps):
    """Merge neighbouring steps that define a fused map (``_fuse_with``)."""
    out = []
    for step in steps:
        if out:
            merged = out[-1]._fuse_with(step) if hasattr(out[-1], "_fuse_with") else None
            if merged is not None:
                out[-1] = merged
                continue
        out.append(step)
    return out
