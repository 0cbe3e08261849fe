"""The parameter block: the one contract between the host and every kernel.

A leaf layer: it imports no map class, so every map imports it at top
level. One module per job:

* :mod:`~fpiwarp.block.layout`: the documented layout, its row offsets,
  limits and cores (the table every kernel mirrors);
* :mod:`~fpiwarp.block.sampling_rules`: the numbers of the border modes
  and the coordinate limit;
* :mod:`~fpiwarp.block.stage`: :class:`Stage` and its named parts
  (:class:`MobiusPart`, :class:`LinearPart`, :class:`Region`);
* :mod:`~fpiwarp.block.pack`: :func:`pack`, stages to the float32 block;
* :mod:`~fpiwarp.block.many`: the blocks of a batch's maps packed in one
  pass and grouped by kind (each distinct kind described once);
* :mod:`~fpiwarp.block.describe`: :func:`describe`, the kind of map a
  block holds, which every backend and the renderer choose programs by;
* :mod:`~fpiwarp.block.reference`: :func:`evaluate`, the numpy reference
  every kernel mirrors (its paired TPS terms in
  :mod:`~fpiwarp.block.tps_pairs`);
* :mod:`~fpiwarp.block.codegen`: the contract's numbers for OpenCL, GLSL
  and Warp.
"""

from .describe import BlockKind, StageKind, describe, n_stages, stage_rows
from .layout import (
    CORE_AFFINE,
    CORE_TPS,
    CORE_TPS_INVERSE,
    CORE_TPS_PAIRS,
    CORE_TPS_PAIRS_INVERSE,
    CORES,
    LAYOUT_VERSION,
    MAX_CENTERS,
    MAX_REGIONS,
    MAX_ROWS,
    MAX_STAGES,
    ROW_CENTERS,
    ROW_HEADER,
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
    STAGE_ROWS,
)
from .pack import pack, rlinear_inverse
from .reference import evaluate
from .stage import LinearPart, MobiusPart, Region, SeedTable, Stage

__all__ = [
    "CORES",
    "CORE_AFFINE",
    "CORE_TPS",
    "CORE_TPS_INVERSE",
    "CORE_TPS_PAIRS",
    "CORE_TPS_PAIRS_INVERSE",
    "LAYOUT_VERSION",
    "MAX_CENTERS",
    "MAX_REGIONS",
    "MAX_ROWS",
    "MAX_STAGES",
    "ROW_CENTERS",
    "ROW_HEADER",
    "ROW_L12",
    "ROW_L3",
    "ROW_MU12",
    "ROW_MU3",
    "ROW_POST",
    "ROW_PRE",
    "ROW_REGIONS",
    "ROW_SCALE",
    "ROW_SEED",
    "ROW_SEED_GRID",
    "SEED_N",
    "STAGE_ROWS",
    "BlockKind",
    "LinearPart",
    "MobiusPart",
    "Region",
    "SeedTable",
    "Stage",
    "StageKind",
    "describe",
    "evaluate",
    "n_stages",
    "pack",
    "rlinear_inverse",
    "stage_rows",
]
