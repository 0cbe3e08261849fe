"""What kind of map a parameter block holds: the one decoder of its header.

Backends and the renderer choose programs by a block's kind (the header row
of each stage), never by its values; :func:`describe` reads that kind once
and refuses a block no kernel can evaluate (wrong layout version, too many
stages, centers or regions, an unknown core) before anything is launched.
"""

from dataclasses import dataclass

import numpy as np

from .layout import (
    CORE_AFFINE,
    CORES,
    LAYOUT_VERSION,
    MAX_CENTERS,
    MAX_REGIONS,
    MAX_STAGES,
    PAIRED_CORES,
    ROW_HEADER,
    ROW_L12,
    STAGE_ROWS,
)


@dataclass(frozen=True)
class StageKind:
    """One stage's header row: what a kernel specializes on."""

    core: int
    n_centers: int
    n_regions: int
    newton_iters: int

    @property
    def header(self):
        """(core, n_centers, n_regions, newton_iters), the row's order."""
        return (self.core, self.n_centers, self.n_regions, self.newton_iters)


@dataclass(frozen=True)
class BlockKind:
    """The kind of map of a block.

    ``stages``: the :class:`StageKind` of each stage, in order.
    ``is_short``: every stage has the affine core and no regions (FPIs,
    Möbius and R-linear maps and their compounds): a few dozen operations
    per point, cheap to inline several times in one shader.
    ``constant_dilation``: |f_zbar| / |f_z| where it is the same everywhere
    (one stage, affine core, no regions: its Möbius parts are conformal),
    else None.
    """

    stages: tuple
    is_short: bool
    constant_dilation: float | None

    @property
    def n_stages(self):
        return len(self.stages)


def n_stages(block):
    """The number of stages a block declares in its header."""
    return int(block[0, 0])


def stage_rows(block, k):
    """The rows of stage ``k`` of a block."""
    return block[1 + k * STAGE_ROWS : 1 + (k + 1) * STAGE_ROWS]


def _stage_kind(block, k):
    core, n_centers, n_regions, iters = (int(v) for v in stage_rows(block, k)[ROW_HEADER])
    if core not in CORES.values():
        raise ValueError(f"stage {k} of the parameter block has the unknown core {core}; the kernels know {CORES}")
    if not 0 <= n_centers <= MAX_CENTERS or not 0 <= n_regions <= MAX_REGIONS or iters < 0:
        raise ValueError(
            f"stage {k} of the parameter block has {n_centers} centers, {n_regions} regions and "
            f"{iters} Newton steps (at most {MAX_CENTERS} centers and {MAX_REGIONS} regions)"
        )
    if core in PAIRED_CORES and n_centers % 2:
        raise ValueError(
            f"stage {k} of the parameter block has the paired core {core} and an odd {n_centers} center rows"
        )
    return StageKind(core, n_centers, n_regions, iters)


def describe(block):
    """The :class:`BlockKind` of a parameter block (``Transform.params()``).

    Raises ValueError for a block no kernel can evaluate: not (rows, 4),
    another layout version, 0 or more than MAX_STAGES stages, fewer rows
    than its stages need, an unknown core, too many centers or regions.
    """
    block = np.asarray(block)
    if block.ndim != 2 or block.shape[1] != 4 or block.shape[0] < 1:
        raise ValueError(f"a parameter block is a (rows, 4) array, got shape {block.shape}")
    if int(block[0, 1]) != LAYOUT_VERSION:
        raise ValueError(f"parameter block of layout version {block[0, 1]}, this fpiwarp reads {LAYOUT_VERSION}")
    count = n_stages(block)
    if not 1 <= count <= MAX_STAGES or block.shape[0] < 1 + count * STAGE_ROWS:
        raise ValueError(f"parameter block of {block.shape[0]} rows declares {count} stages of {STAGE_ROWS} rows")
    stages = tuple(_stage_kind(block, k) for k in range(count))
    is_short = all(s.core == CORE_AFFINE and s.n_regions == 0 for s in stages)
    dilation = None
    if count == 1 and is_short:
        l1re, l1im, l2re, l2im = np.asarray(block[1 + ROW_L12], dtype=np.float64)
        dilation = float(np.hypot(l2re, l2im) / np.hypot(l1re, l1im))
    return BlockKind(stages=stages, is_short=is_short, constant_dilation=dilation)
