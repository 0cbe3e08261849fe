"""Shared pieces of the fpiwarp.torch tests: the torch import rule, maps, an independent float64 sampler.

Without torch the tests skip with the reason in a developer run; with
"torch" in FPIWARP_REQUIRE_LIBRARIES (CI) they fail instead.
"""

import os

import numpy as np
import pytest

import fpiwarp


def require_torch():
    """The torch module; skip the calling test module without it (fail when required)."""
    try:
        import torch
    except ImportError as exc:
        required = {s.strip() for s in os.environ.get("FPIWARP_REQUIRE_LIBRARIES", "").split(",")}
        if "torch" in required:
            pytest.fail(f"torch is required by FPIWARP_REQUIRE_LIBRARIES but cannot be imported: {exc}",
                        pytrace=False)
        pytest.skip(f"torch is not installed: {exc}", allow_module_level=True)
    return torch


MODES = ("constant", "edge", "reflect", "wrap")
#: A 32 × 24 source and a target that moves every corner a few pixels.
SRC = np.array([[0.0, 0.0], [31.0, 0.0], [31.0, 23.0], [0.0, 23.0]])
DST = SRC + np.array([[2.3, -1.7], [1.4, 2.1], [-2.9, 1.6], [-1.8, -2.2]])


def border_index(i, n, mode):
    """fpiwarp's documented border rule on integer indices; also which were inside."""
    inside = (i >= 0) & (i < n)
    if mode in ("edge", "constant"):
        return np.clip(i, 0, n - 1), inside
    if mode == "wrap":
        return np.mod(i, n), inside
    if n == 1:
        return np.zeros_like(i), inside
    period = 2 * (n - 1)
    m = np.mod(i, period)
    return np.where(m >= n, period - m, m), inside


def _taps(c, order):
    if order == 0:
        return [np.floor(c + 0.5).astype(np.int64)], [np.ones_like(c)]
    b = np.floor(c)
    t = c - b
    b = b.astype(np.int64)
    if order == 1:
        return [b, b + 1], [1 - t, t]
    t2, t3 = t * t, t * t * t
    return [b - 1, b, b + 1, b + 2], [-0.5 * t3 + t2 - 0.5 * t, 1.5 * t3 - 2.5 * t2 + 1,
                                      -1.5 * t3 + 2 * t2 + 0.5 * t, 0.5 * t3 - 0.5 * t2]


def reference_sample(image, pos, order, mode, cval):
    """Float64 values of the (H, W, C) image at (rows, cols, 2) positions, by the documented rules
    (checked against fpiwarp.warp_image in the tests, to its float32 output's rounding)."""
    h, w, c = image.shape
    x, y = pos[..., 0], pos[..., 1]
    with np.errstate(invalid="ignore"):
        ok = (np.abs(x) <= 2.0**24) & (np.abs(y) <= 2.0**24)
    x, y = np.where(ok, x, 0.0), np.where(ok, y, 0.0)
    out = np.zeros(x.shape + (c,))
    xs, wx = _taps(x, order)
    ys, wy = _taps(y, order)
    for yi, wyi in zip(ys, wy):
        row, rin = border_index(yi, h, mode)
        for xi, wxi in zip(xs, wx):
            col, cin = border_index(xi, w, mode)
            vals = image[row, col]
            if mode == "constant":
                vals = np.where((rin & cin)[..., None], vals, cval)
            out += (wyi * wxi)[..., None] * vals
    return np.where(ok[..., None], out, cval)


def pole_map():
    """An FPI whose pole image w∞ lies inside a 30 × 40 output (its pixels sample from far away)."""
    f = fpiwarp.FPI([[0, 0], [30, 0], [30, 20], [0, 20]], [[9, -11], [21, 6], [20, 8], [11, 9]])
    w = f.pole_image
    assert w is not None and 0 < w[0] < 40 and 0 < w[1] < 30
    return f
