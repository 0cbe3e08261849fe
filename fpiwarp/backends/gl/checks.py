"""Argument checks of the GL stack that :mod:`fpiwarp._warp` does not
offer as public helpers: kept in this one module so that a library-wide
validation module can replace them in one place."""

from ..._sampling import MODES, ORDERS
from ..._transform import Transform


def check_transform(transform):
    """Raise TypeError unless ``transform`` is an fpiwarp map."""
    if not isinstance(transform, Transform):
        raise TypeError(f"transform must be an fpiwarp map (FPI, Mobius, RLinear, ...), "
                        f"got {type(transform).__name__}")


def check_order_and_mode(order, mode):
    """Raise ValueError unless ``order`` and ``mode`` name a sampling of
    :mod:`fpiwarp._sampling`."""
    if order not in ORDERS:
        raise ValueError(f"order must be one of {ORDERS}, got {order!r}")
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
