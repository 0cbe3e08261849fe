"""The caller's ``out=`` on every array path: the one-line errors for an
``out=`` that overlaps its input or is not of the input's kind, and the
copy into a numpy ``out=`` of the host paths. The device paths
(``fpiwarp.arrays.dispatch``, ``fpiwarp.batch.arrays`` and each backend's
``arrays`` module) all import from here, so nothing here imports them.
"""

import numpy as np

from ..errors import ArgumentError, DeviceMismatchError


def overlap_error(what):
    """The one-line error for an ``out=`` that shares memory with its input ``what``."""
    verb = "map" if what == "points" else "warp"
    return ArgumentError(f"out= shares memory with {what}; {verb} into another array")


def check_host_out(out, source, what):
    """``out=`` of a host (numpy) call: a numpy array apart from ``source``; shape and dtype are checked by the
    copy's caller."""
    if not isinstance(out, np.ndarray):
        raise DeviceMismatchError(f"out= is a {type(out).__name__}; a numpy input is written into a numpy array")
    if np.shares_memory(out, source):
        raise overlap_error(what)


def copy_host_out(result, out):
    """``result`` of a host warp copied into the caller's numpy ``out=``
    (already checked by :func:`check_host_out`), which must match its shape
    and dtype; returns ``out``."""
    if out.shape != result.shape or out.dtype != result.dtype:
        raise ArgumentError(f"out= must be {result.shape} {result.dtype}, got {out.shape} {out.dtype}")
    np.copyto(out, result)
    return out


def copy_points_out(result, out, points):
    """``result`` of a host map_points call, or copied into the caller's numpy ``out=``."""
    if out is None:
        return result
    if not isinstance(out, np.ndarray) or out.shape != result.shape or out.dtype != result.dtype:
        raise ArgumentError(f"out= must be a numpy array {result.shape} {result.dtype}")
    if np.shares_memory(out, points):
        raise overlap_error("points")
    np.copyto(out, result)
    return out
