"""The analytic derivatives of a parameter block: the reference the kernels'
antialiasing mirrors (their ``fw_map_wirtinger`` / ``fpw_map_wirtinger``).

A stage is a chain of simple parts (:mod:`fpiwarp.block.layout`), each
with a closed-form derivative, so the block's Wirtinger derivatives
(f_z, f_zbar) follow from the chain rule, stage after stage, alongside the
values of :func:`fpiwarp.block.reference.evaluate`:

* a region's similarity a z + b: (a, 0);
* a Möbius part k u / (1 - s u), u = z - c: (k / (1 - s u)², 0);
* the affine core l1 p + l2 conj(p) + l3: (l1, l2);
* the TPS core (plain or paired): its derivatives (:func:`~fpiwarp.block.reference.tps_core`);
* the TPS core's Newton inverse x(p): by the inverse function theorem,
  from the TPS derivatives (g_z, g_zbar) at the solution x,
  (conj(g_z), -g_zbar) / (|g_z|² - |g_zbar|²).

Composing h = g ∘ f: h_z = g_w f_z + g_wbar conj(f_zbar), h_zbar = g_w f_zbar +
g_wbar conj(f_z). The real Jacobian is J[:, 0] = f_z + f_zbar, J[:, 1] =
i (f_z - f_zbar) (as complex numbers x + iy), which is how the
antialiasing footprint's edges are formed.
"""

import numpy as np

from .describe import describe, stage_rows
from .layout import (
    CORE_AFFINE,
    CORE_TPS,
    CORE_TPS_INVERSE,
    CORE_TPS_PAIRS,
    CORE_TPS_PAIRS_INVERSE,
    PAIRED_CORES,
    ROW_L3,
    ROW_L12,
    ROW_POST,
    ROW_PRE,
    ROW_SCALE,
)
from .reference import complex_at, newton, region_winner, tps_core


def chain(g_w, g_wb, f_z, f_zb):
    """Wirtinger derivatives of g ∘ f from those of g (at f) and of f."""
    return g_w * f_z + g_wb * np.conj(f_zb), g_w * f_zb + g_wb * np.conj(f_z)


def wirtinger(block, points, dtype=np.float64):
    """(values, f_z, f_zbar) of a parameter block at (..., 2) points: values
    as (..., 2) like :func:`~fpiwarp.block.reference.evaluate`, the
    derivatives complex. ``dtype=np.float32`` imitates device precision."""
    kind = describe(block)
    cdt = np.complex64 if dtype == np.float32 else np.complex128
    block = np.asarray(block, dtype=dtype)
    pts = np.asarray(points, dtype=dtype)
    z = (pts[..., 0] + 1j * pts[..., 1]).astype(cdt)
    dz, dzb = np.ones_like(z), np.zeros_like(z)
    with np.errstate(all="ignore"):
        for k, stage in enumerate(kind.stages):
            z, g_w, g_wb = stage_wirtinger(stage_rows(block, k), stage, z, dtype)
            dz, dzb = chain(g_w, g_wb, dz, dzb)
    out = np.empty(z.shape + (2,), dtype=dtype)
    out[..., 0], out[..., 1] = z.real, z.imag
    return out, dz, dzb


def jacobian(block, points, dtype=np.float64):
    """The real Jacobian (..., 2, 2), J[i, j] = d f_i / d x_j, of a block."""
    _, fz, fzb = wirtinger(block, points, dtype)
    fx, fy = fz + fzb, 1j * (fz - fzb)
    jac = np.empty(np.shape(fz) + (2, 2), dtype=dtype)
    jac[..., 0, 0], jac[..., 1, 0] = fx.real, fx.imag
    jac[..., 0, 1], jac[..., 1, 1] = fy.real, fy.imag
    return jac


def stage_wirtinger(rows, kind, z, dtype):
    """One stage's values and Wirtinger derivatives at complex z (mirrors
    :func:`fpiwarp.block.reference.evaluate_stage` step by step)."""
    inside, outside, outside_dz = region_winner(rows, kind, z, dtype)
    u = z - complex_at(rows[ROW_PRE], 0)
    den = 1 - complex_at(rows[ROW_PRE], 2) * u
    k1 = complex_at(rows[ROW_SCALE], 0)
    p = k1 * u / den
    dz, dzb = k1 / (den * den), np.zeros_like(z)
    if kind.core == CORE_AFFINE:
        l1, l2, l3 = complex_at(rows[ROW_L12], 0), complex_at(rows[ROW_L12], 2), complex_at(rows[ROW_L3], 0)
        p, (dz, dzb) = l1 * p + l2 * np.conj(p) + l3, chain(l1, l2, dz, dzb)
    elif kind.core in (CORE_TPS, CORE_TPS_PAIRS):
        p, g_w, g_wb = tps_core(p, rows, kind.n_centers, dtype, kind.core in PAIRED_CORES)
        dz, dzb = chain(g_w, g_wb, dz, dzb)
    elif kind.core in (CORE_TPS_INVERSE, CORE_TPS_PAIRS_INVERSE):
        paired = kind.core in PAIRED_CORES
        p = newton(p, rows, kind.n_centers, kind.newton_iters, rows[ROW_L3, 2], dtype, paired)
        _, g_z, g_zb = tps_core(p, rows, kind.n_centers, dtype, paired)
        det = (g_z * np.conj(g_z)).real - (g_zb * np.conj(g_zb)).real
        dz, dzb = chain(np.conj(g_z) / det, -g_zb / det, dz, dzb)
    else:  # describe() refuses unknown cores; kept explicit like every kernel
        raise ValueError(f"unknown core {kind.core}")
    den = 1 - complex_at(rows[ROW_POST], 0) * p
    k2 = complex_at(rows[ROW_SCALE], 2)
    w = complex_at(rows[ROW_POST], 2) + k2 * p / den
    g = k2 / (den * den)
    dz, dzb = g * dz, g * dzb
    return (np.where(inside, outside, w), np.where(inside, outside_dz, dz),
            np.where(inside, np.zeros_like(dzb), dzb))
