"""The GL stack's argument checks: those of :mod:`fpiwarp.validation`,
the library's one set of checks, in the pairs the GL code asks for."""

from ...validation import check_mode, check_order, check_transform

__all__ = ["check_order_and_mode", "check_transform"]


def check_order_and_mode(order, mode):
    """(order as an int, mode) after the library's checks; raises
    :class:`fpiwarp.ArgumentError` for anything else."""
    return check_order(order), check_mode(mode)
