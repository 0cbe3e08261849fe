"""Packing stages into the float32 parameter block (layout in
:mod:`fpiwarp.block.layout`), solved in float64 and rounded once."""

import numpy as np

from .layout import (
    CORES,
    LAYOUT_VERSION,
    MAX_CENTERS,
    MAX_REGIONS,
    MAX_STAGES,
    PAIRED_CORES,
    ROW_CENTERS,
    ROW_REGIONS,
    ROW_SEED,
    ROW_SEED_GRID,
    SEED_N,
    STAGE_ROWS,
)
from .stage import LinearPart


def rlinear_inverse(linear):
    """The inverse of an R-linear part, the seed of the device Newton.

    The same formula as :attr:`fpiwarp.RLinear.inverse`, in plain complex
    arithmetic (the block layer imports no map class); RLinear.inverse
    calls it. Raises ValueError for a singular or non-finite part, or one
    whose |l1|² - |l2|² under- or overflows float64.
    """
    l1, l2, l3 = complex(linear.l1), complex(linear.l2), complex(linear.l3)
    # abs(v) < inf: finite (False for inf and nan), cheaper than np.isfinite on six scalars
    if not all(abs(v) < np.inf for v in (l1.real, l1.imag, l2.real, l2.imag, l3.real, l3.imag)):
        raise ValueError("R-linear coefficients must be finite")
    if abs(abs(l1) - abs(l2)) <= 1e-14 * (abs(l1) + abs(l2)):
        raise ValueError("singular R-linear map: |l1| == |l2|")
    try:
        det = abs(l1) ** 2 - abs(l2) ** 2
    except OverflowError:
        det = np.inf
    if not np.inf > abs(det) >= np.finfo(np.float64).tiny:  # |l|² under- or overflows float64
        raise ValueError(f"cannot invert the R-linear map ({l1}, {l2}, {l3}): |l1|² - |l2|² = {det:g} is outside "
                         "float64's normal range; rescale the map's coefficients")
    m1 = np.conj(l1) / det
    m2 = -l2 / det
    return LinearPart(complex(m1), complex(m2), complex(-(m1 * l3 + m2 * np.conj(l3))))


def _put(row, *values):
    """Write complex values into a row as (re, im) pairs."""
    flat = []
    for v in values:
        v = complex(v)
        flat += [v.real, v.imag]
    row[: len(flat)] = flat


def _center_rows(stage):
    """Rows the stage's centers take: two per pair for the paired cores."""
    return len(stage.centers) * (2 if stage.core in PAIRED_CORES else 1)


def _put_seed(rows, seed):
    """The seed table's rows (layout: ROW_SEED, ROW_SEED_GRID)."""
    corr = np.asarray(seed.corrections, dtype=np.complex128)
    if corr.shape != (SEED_N, SEED_N):
        raise ValueError(f"a seed table has {SEED_N}x{SEED_N} corrections, got shape {corr.shape}")
    step = complex(seed.step)
    if not (step.real > 0 and step.imag > 0 and np.isfinite(step) and np.isfinite(complex(seed.lo))):
        raise ValueError(f"a seed table needs a finite start and positive steps, got {seed.lo!r}, {seed.step!r}")
    rows[ROW_SEED] = (seed.lo.real, seed.lo.imag, 1 / step.real, 1 / step.imag)
    flat = np.where(np.isfinite(corr), corr, 0).reshape(-1)
    grid = rows[ROW_SEED_GRID : ROW_SEED_GRID + SEED_N * SEED_N // 2]
    grid[:, 0], grid[:, 1] = flat[0::2].real, flat[0::2].imag
    grid[:, 2], grid[:, 3] = flat[1::2].real, flat[1::2].imag


def check_stage(stage):
    """Refuse a stage the block cannot hold (ValueError naming the problem)."""
    if stage.core not in CORES.values():
        raise ValueError(f"unknown core {stage.core!r}; the kernels know {CORES}")
    if _center_rows(stage) > MAX_CENTERS:
        raise ValueError(f"at most {MAX_CENTERS} TPS center rows, got {_center_rows(stage)}")
    if stage.core in PAIRED_CORES and not len(stage.centers) == len(stage.offsets) == len(stage.offset_weights):
        raise ValueError("a paired TPS stage needs one offset and one offset weight per center")
    if len(stage.regions) > MAX_REGIONS:
        raise ValueError(f"at most {MAX_REGIONS} regions, got {len(stage.regions)}")
    if stage.pre.offset != 0:
        raise ValueError(f"a stage's pre-Möbius has no offset (the block has no row for it), got {stage.pre}")
    if stage.post.center != 0:
        raise ValueError(f"a stage's post-Möbius is centered at 0, got {stage.post}")


def fixed_values(st):
    """The ROW_REGIONS * 4 float64 values of a stage's fixed rows (header,
    Möbius parts, R-linear part and its inverse, the Newton seed), in row
    order: the one definition of those rows, for :func:`pack` and for
    :func:`fpiwarp.block.many.pack_many` (a flat tuple: cheaper than
    writing row by row when many maps are packed)."""
    pre, post, lin = st.pre, st.post, st.linear
    center, pole, pre_scale = complex(pre.center), complex(pre.inverse_pole), complex(pre.scale)
    post_scale, post_pole, offset = complex(post.scale), complex(post.inverse_pole), complex(post.offset)
    l1, l2, l3 = complex(lin.l1), complex(lin.l2), complex(lin.l3)
    mu = rlinear_inverse(lin)  # the Newton seed
    m1, m2, m3 = complex(mu.l1), complex(mu.l2), complex(mu.l3)
    values = (st.core, _center_rows(st), len(st.regions), st.newton_iters,  # ROW_HEADER
              center.real, center.imag, pole.real, pole.imag,  # ROW_PRE
              pre_scale.real, pre_scale.imag, post_scale.real, post_scale.imag,  # ROW_SCALE
              post_pole.real, post_pole.imag, offset.real, offset.imag,  # ROW_POST
              l1.real, l1.imag, l2.real, l2.imag,  # ROW_L12
              l3.real, l3.imag, st.newton_tol, 0.0,  # ROW_L3
              m1.real, m1.imag, m2.real, m2.imag,  # ROW_MU12
              m3.real, m3.imag, 0.0, 0.0)  # ROW_MU3
    return values


def write_tables(rows, st):
    """Write stage ``st``'s seed table, regions and TPS centers into its
    rows (float64, zero where the stage has none); the rows before
    ROW_REGIONS are :func:`pack`'s."""
    n = _center_rows(st)
    if st.seed is not None:
        _put_seed(rows, st.seed)
    for r, reg in enumerate(st.regions):
        _put(rows[ROW_REGIONS + 2 * r], reg.origin, reg.normal)
        _put(rows[ROW_REGIONS + 2 * r + 1], reg.a, reg.b)
    if st.core in PAIRED_CORES:
        for j in range(len(st.centers)):
            _put(rows[ROW_CENTERS + 2 * j], st.centers[j], st.weights[j])
            _put(rows[ROW_CENTERS + 2 * j + 1], st.offsets[j], st.offset_weights[j])
    else:
        for j in range(n):
            _put(rows[ROW_CENTERS + j], st.centers[j], st.weights[j])


def pack(stages, dtype=np.float32):
    """Pack a list of :class:`~fpiwarp.block.Stage` into the block, shape (rows, 4).

    Kernels read float32 (the default). ``dtype=np.float64`` keeps the
    coefficients unrounded, for checking the reference's formulas apart
    from the float32 rounding of the coefficients.
    """
    stages = list(stages)
    if not 1 <= len(stages) <= MAX_STAGES:
        raise ValueError(f"a map packs into 1 to {MAX_STAGES} stages, this one needs {len(stages)}")
    block = np.zeros((1 + len(stages) * STAGE_ROWS, 4), dtype=np.float64)
    block[0, :2] = (len(stages), LAYOUT_VERSION)
    for k, st in enumerate(stages):
        check_stage(st)
        rows = block[1 + k * STAGE_ROWS : 1 + (k + 1) * STAGE_ROWS]
        rows[:ROW_REGIONS] = np.reshape(fixed_values(st), (ROW_REGIONS, 4))
        write_tables(rows, st)
    return block.astype(dtype)
