"""The numpy reference evaluation of a parameter block: what every kernel
mirrors line by line (the steps are listed in :mod:`fpiwarp.block.layout`).

``dtype=np.float32`` imitates device precision; float64 checks the block
against the maps' own formulas.
"""

import numpy as np

from .describe import describe, stage_rows
from .layout import (
    CORE_AFFINE,
    CORE_TPS,
    CORE_TPS_PAIRS,
    NEWTON_CORES,
    PAIRED_CORES,
    ROW_CENTERS,
    ROW_L3,
    ROW_L12,
    ROW_MU3,
    ROW_MU12,
    ROW_POST,
    ROW_PRE,
    ROW_REGIONS,
    ROW_SCALE,
    ROW_SEED,
    ROW_SEED_GRID,
    SEED_N,
)
from .tps_pairs import tps_pairs_core


def complex_at(row, i):
    """The complex number in columns (i, i + 1) of a row."""
    return complex(row[i], row[i + 1])


def tps_core(p, rows, n, dtype, paired=False):
    """The TPS core of a stage and its Wirtinger derivatives at p; ``paired``:
    its center rows are pairs (:mod:`fpiwarp.block.tps_pairs`)."""
    l1, l2, l3 = complex_at(rows[ROW_L12], 0), complex_at(rows[ROW_L12], 2), complex_at(rows[ROW_L3], 0)
    val = l1 * p + l2 * np.conj(p) + l3
    dz = np.full_like(p, l1)
    dzb = np.full_like(p, l2)
    if paired:
        v, gz, gzb = tps_pairs_core(p, rows, n, dtype, ROW_CENTERS)
        return val + v, dz + gz, dzb + gzb
    for j in range(n):
        c, b = complex_at(rows[ROW_CENTERS + j], 0), complex_at(rows[ROW_CENTERS + j], 2)
        d = p - c
        r2 = (d.real**2 + d.imag**2).astype(dtype)
        safe = np.where(r2 > 0, r2, 1)
        lg = np.where(r2 > 0, np.log(safe), 0)
        val = val + b * (0.5 * r2 * lg)
        g = 0.5 * b * (lg + 1)
        dz = dz + g * np.conj(d)
        dzb = dzb + g * d
    return val, dz, dzb


def evaluate(block, points, dtype=np.float64):
    """Evaluate a parameter block on (..., 2) points: the reference that
    every kernel mirrors. ``dtype=np.float32`` imitates device precision.
    Raises ValueError for a block no kernel evaluates (see :func:`describe`)."""
    kind = describe(block)
    cdt = np.complex64 if dtype == np.float32 else np.complex128
    block = np.asarray(block, dtype=dtype)
    pts = np.asarray(points, dtype=dtype)
    z = (pts[..., 0] + 1j * pts[..., 1]).astype(cdt)
    with np.errstate(all="ignore"):
        for k, stage in enumerate(kind.stages):
            z = evaluate_stage(stage_rows(block, k), stage, z, dtype)
    out = np.empty(z.shape + (2,), dtype=dtype)
    out[..., 0], out[..., 1] = z.real, z.imag
    return out


def region_winner(rows, kind, z, dtype):
    """Step 1 of a stage: where a region wins at complex z, and its
    similarity a z + b there. Returns (won, outside, a): ``won`` is a bool
    mask, ``outside`` the winning similarity's value and ``a`` its
    derivative (NaN where no region wins); the largest depth wins."""
    best = np.zeros(z.shape, dtype=dtype)
    outside = np.full(z.shape, np.nan + 0j, dtype=z.dtype)
    slope = np.full(z.shape, np.nan + 0j, dtype=z.dtype)
    for r in range(kind.n_regions):
        o, nrm = complex_at(rows[ROW_REGIONS + 2 * r], 0), complex_at(rows[ROW_REGIONS + 2 * r], 2)
        a, b = complex_at(rows[ROW_REGIONS + 2 * r + 1], 0), complex_at(rows[ROW_REGIONS + 2 * r + 1], 2)
        depth = ((z - o) * np.conj(nrm)).real
        win = depth > best
        best = np.where(win, depth, best)
        outside = np.where(win, a * z + b, outside)
        slope = np.where(win, a, slope)
    return best > 0, outside, slope


def evaluate_stage(rows, kind, z, dtype, seed=None):
    """One stage (its rows and :class:`~fpiwarp.block.describe.StageKind`) on
    complex z; ``seed``: a Newton core's coarse-pass seeds per point (see
    :func:`newton`)."""
    won, outside, _ = region_winner(rows, kind, z, dtype)
    if kind.core != CORE_AFFINE and kind.n_regions > 0:
        # the kernels skip the costly cores where a region wins: so does the
        # reference (per point the same numbers: every step is elementwise)
        w = np.full(z.shape, np.nan + 0j, dtype=z.dtype)
        inner = None if seed is None else tuple(s[~won] for s in seed)
        w[~won] = _pre_core_post(rows, kind, z[~won], dtype, inner)
        return np.where(won, outside, w)
    return np.where(won, outside, _pre_core_post(rows, kind, z, dtype, seed))


def pre_mobius(rows, z):
    """Step 2 of a stage: the pre-Möbius at complex z."""
    u = z - complex_at(rows[ROW_PRE], 0)
    return complex_at(rows[ROW_SCALE], 0) * u / (1 - complex_at(rows[ROW_PRE], 2) * u)


def _pre_core_post(rows, kind, z, dtype, seed=None):
    """Steps 2-4 of a stage (pre-Möbius, core, post-Möbius) on complex z."""
    p = pre_mobius(rows, z)
    if kind.core == CORE_AFFINE:
        l1, l2, l3 = complex_at(rows[ROW_L12], 0), complex_at(rows[ROW_L12], 2), complex_at(rows[ROW_L3], 0)
        p = l1 * p + l2 * np.conj(p) + l3
    elif kind.core in (CORE_TPS, CORE_TPS_PAIRS):
        p = tps_core(p, rows, kind.n_centers, dtype, kind.core in PAIRED_CORES)[0]
    elif kind.core in NEWTON_CORES:
        p = newton(p, rows, kind.n_centers, kind.newton_iters, rows[ROW_L3, 2], dtype, kind.core in PAIRED_CORES,
                   seed)
    else:  # describe() refuses unknown cores; kept explicit like every kernel
        raise ValueError(f"unknown core {kind.core}")
    return complex_at(rows[ROW_POST], 2) + complex_at(rows[ROW_SCALE], 2) * p / (1 - complex_at(rows[ROW_POST], 0) * p)


def seed_correction(target, rows, dtype):
    """The seed table's bilinear correction at complex targets (layout:
    ROW_SEED): added to the R-linear seed; 0 for all-zero table rows."""
    lo_re, lo_im, gx, gy = (dtype(v) for v in rows[ROW_SEED])
    last = dtype(SEED_N - 1)

    def axis(v, lo, g):
        with np.errstate(invalid="ignore", over="ignore"):
            f = ((v - lo) * g).astype(dtype)
        f = np.where(f > 0, np.minimum(f, last), dtype(0)).astype(dtype)  # NaN -> 0
        i = np.minimum(np.floor(f), dtype(SEED_N - 2)).astype(np.int64)
        return i, (f - i).astype(dtype)

    i, tx = axis(target.real, lo_re, gx)
    j, ty = axis(target.imag, lo_im, gy)
    grid = rows[ROW_SEED_GRID : ROW_SEED_GRID + SEED_N * SEED_N // 2]
    nodes = np.stack([grid[:, 0] + 1j * grid[:, 1], grid[:, 2] + 1j * grid[:, 3]], axis=1).reshape(-1)
    nodes = nodes.astype(target.dtype)

    def at(jj, ii):
        return nodes[jj * SEED_N + ii]

    bottom = at(j, i) + tx * (at(j, i + 1) - at(j, i))
    top = at(j + 1, i) + tx * (at(j + 1, i + 1) - at(j + 1, i))
    return bottom + ty * (top - bottom)


def newton(target, rows, n, iters, tol, dtype, paired=False, seed=None):
    """Solve TPS(x) = target by Newton from the inverse of the R-linear
    part plus the seed table's correction; where that does not end within
    ``tol`` after ``iters`` steps and the correction there is not 0, again
    from the R-linear inverse alone (the restart: a point the R-linear
    seed solves is never lost to the table); NaN where neither does.
    ``paired``: the paired TPS core.

    ``seed``: a warp's coarse-pass seed (x0, a, b) per target
    (:mod:`fpiwarp.block.coarse`): where x0 is finite and TPS(x0) (its
    value only) lies within ``tol`` of the target, the answer is x0 - (a r
    + b conj(r)), r that residual (a step by the interpolated inverse
    Jacobian, no derivatives taken); elsewhere the solve above."""
    if seed is not None:
        x0, a, b = seed
        res = tps_core(x0, rows, n, dtype, paired)[0] - target
        quick = np.abs(res) <= tol  # NaN seeds: False
        out = np.where(quick, x0 - (a * res + b * np.conj(res)), np.nan).astype(target.dtype)
        if not quick.all():  # per point, so the rest alone gives the same numbers
            out[~quick] = newton(target[~quick], rows, n, iters, tol, dtype, paired)
        return out
    mu1, mu2, mu3 = complex_at(rows[ROW_MU12], 0), complex_at(rows[ROW_MU12], 2), complex_at(rows[ROW_MU3], 0)
    start = mu1 * target + mu2 * np.conj(target) + mu3
    correction = seed_correction(target, rows, dtype)
    out = _newton_from(start + correction, target, rows, n, iters, tol, dtype, paired)
    again = np.isnan(out) & (correction != 0)
    if again.any():  # per point, so the restarted points alone give the same numbers
        out[again] = _newton_from(start[again], target[again], rows, n, iters, tol, dtype, paired)
    return out


def _newton_from(x, target, rows, n, iters, tol, dtype, paired):
    """Newton's iterates for TPS(x) = target from ``x``: x where within
    ``tol`` (a point stops once it is), NaN where not after ``iters`` steps."""
    done = np.zeros(target.shape, dtype=bool)
    for _ in range(iters):
        val, dz, dzb = tps_core(x, rows, n, dtype, paired)
        res = val - target
        done = np.abs(res) <= tol
        if done.all():
            break
        det = np.abs(dz) ** 2 - np.abs(dzb) ** 2
        step = (np.conj(dz) * res - dzb * np.conj(res)) / det
        x = np.where(done, x, x - step)
    else:
        val = tps_core(x, rows, n, dtype, paired)[0]
        done = np.abs(val - target) <= tol
    return np.where(done, x, np.nan)
