"""A warp's coarse pass: the reference every kernel's warp mirrors for a
map with a Newton core (a local deformation or constrained FPI's inverse).

Per output pixel the Newton core solves TPS(x) = t from the seed table
(:func:`fpiwarp.block.reference.newton`): one spline evaluation with its
derivatives, a step, and a second evaluation that verifies, sometimes a
third. A warp knows its pixels lie on a grid, where the solution varies
smoothly, so it first solves exactly at every ``COARSE_STEP``-th pixel in
x and y (the nodes, (COARSE_STEP i, COARSE_STEP j) in output pixels,
i < nx, j < ny, covering every pixel) and keeps per node a record:

* x, the Newton solution from the table seed (NaN where it does not
  converge, or where the inverse Jacobian below is not finite);
* a = conj(f_z) / J and b = -f_zbar / J, the inverse Jacobian's Wirtinger
  parts there (f_z, f_zbar the spline's at x, J = |f_z|² - |f_zbar|²).

The nodes skip the stage's regions (a node beyond a constrained line still
solves the core, for the pixels between it and the line). Each pixel then
interpolates its four nodes' records bilinearly (pixel-space seeds:
fractions (px - COARSE_STEP i) / COARSE_STEP), evaluates the spline's
value once at x0 and, where the residual r = TPS(x0) - t lies within the
Newton tolerance, answers x0 - (a r + b conj(r)): a Newton step by the
interpolated inverse Jacobian, with no derivatives taken. Elsewhere (a
node that failed, a seed the check refuses) the pixel solves as without
the pass. On the benchmark's 1080p local deformation 99.94 % of the band's
pixels pass (benchmarks/results/local_speed.md), and the float32 answer
lies nearer the float64 inverse than the per-pixel Newton's, which stops
within the tolerance (measured p99 1e-4 px against 4e-2 px, at most 0.05
px either way: the pixels that fall back).

Only the block's first Newton stage is seeded (a compound with two local
deformations solves its later ones per pixel as before); map_points keeps
the per-point solve (its points need not lie on a grid).

Whether a warp takes the pass at all is decided per map and output shape
by :func:`fpiwarp.block.coarse_choice.takes_coarse_pass`, which every
backend asks: the pass wins only where most seeds pass the check.
"""

import numpy as np

from .describe import describe, stage_rows
from .layout import COARSE_STEP, NEWTON_CORES, PAIRED_CORES, ROW_L3
from .reference import evaluate_stage, newton, pre_mobius, tps_core


def coarse_shape(width, height, step=COARSE_STEP):
    """(ny, nx): the nodes covering an output of ``width`` x ``height`` pixels."""
    return (int(height) - 1) // step + 2, (int(width) - 1) // step + 2


def newton_stage(kind):
    """Index of the first stage of ``kind`` (a BlockKind) with a Newton core, or None."""
    for k, st in enumerate(kind.stages):
        if st.core in NEWTON_CORES:
            return k
    return None


def coarse_pass(block, width, height, dtype=np.float32):
    """The coarse pass of a warp by ``block`` to ``width`` x ``height``:
    records (ny, nx, 3) complex (x, a, b; see the module docstring), or
    None for a block without a Newton core."""
    kind = describe(block)
    k = newton_stage(kind)
    if k is None:
        return None
    block = np.asarray(block, dtype=dtype)
    cdt = np.complex64 if dtype == np.float32 else np.complex128
    ny, nx = coarse_shape(width, height)
    j, i = np.mgrid[0:ny, 0:nx]
    z = (COARSE_STEP * i + 1j * COARSE_STEP * j).astype(cdt).reshape(-1)
    with np.errstate(all="ignore"):
        for s in range(k):
            z = evaluate_stage(stage_rows(block, s), kind.stages[s], z, dtype)
        rows, st = stage_rows(block, k), kind.stages[k]
        paired = st.core in PAIRED_CORES
        x = newton(pre_mobius(rows, z), rows, st.n_centers, st.newton_iters, rows[ROW_L3, 2], dtype, paired)
        _, dz, dzb = tps_core(x, rows, st.n_centers, dtype, paired)
        inv = (1 / (np.abs(dz) ** 2 - np.abs(dzb) ** 2)).astype(dtype)
        a, b = np.conj(dz) * inv, -dzb * inv
        ok = np.isfinite(x) & np.isfinite(a) & np.isfinite(b)
        x = np.where(ok, x, np.nan)
    return np.stack([x, a, b], axis=-1).astype(cdt).reshape(ny, nx, 3)


def pixel_seeds(records, px, py, dtype=np.float32):
    """(x0, a, b) at integer output pixels (px, py): the bilinear
    interpolation of their four nodes' records."""
    nx = records.shape[1]
    i = np.minimum(px // COARSE_STEP, nx - 2)
    j = np.minimum(py // COARSE_STEP, records.shape[0] - 2)
    fx = ((px - COARSE_STEP * i) / COARSE_STEP).astype(dtype)[..., None]
    fy = ((py - COARSE_STEP * j) / COARSE_STEP).astype(dtype)[..., None]
    r00, r01, r10, r11 = records[j, i], records[j, i + 1], records[j + 1, i], records[j + 1, i + 1]
    bottom = r00 + fx * (r01 - r00)
    top = r10 + fx * (r11 - r10)
    seed = bottom + fy * (top - bottom)
    return seed[..., 0], seed[..., 1], seed[..., 2]


def evaluate_pixels(block, width, height, dtype=np.float32, rows=None):
    """The source positions (len(rows), width, 2) a warp by ``block`` to
    ``width`` x ``height`` samples at, as the kernels' warps compute them
    (output rows ``rows``, default all): the coarse pass, then each pixel's
    seeded solve."""
    kind = describe(block)
    k = newton_stage(kind)
    records = coarse_pass(block, width, height, dtype)
    block = np.asarray(block, dtype=dtype)
    cdt = np.complex64 if dtype == np.float32 else np.complex128
    ys = np.arange(height) if rows is None else np.asarray(rows)
    py, px = np.meshgrid(ys, np.arange(width), indexing="ij")
    z = (px + 1j * py).astype(cdt)
    with np.errstate(all="ignore"):
        for s, st in enumerate(kind.stages):
            seed = pixel_seeds(records, px, py, dtype) if s == k else None
            z = evaluate_stage(stage_rows(block, s), st, z, dtype, seed)
    out = np.empty(z.shape + (2,), dtype=dtype)
    out[..., 0], out[..., 1] = z.real, z.imag
    return out
