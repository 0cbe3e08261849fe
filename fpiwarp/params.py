"""The parameter block under its first name: ``fpiwarp.params`` keeps every
name it always had, now defined in the package :mod:`fpiwarp.block`.

The documented block layout (rows, offsets, evaluation steps) is the
docstring of ``fpiwarp/block/layout.py``; the numpy reference every kernel
mirrors is ``fpiwarp/block/reference.py``.
"""

from .block import (
    CORE_AFFINE,
    CORE_TPS,
    CORE_TPS_INVERSE,
    LAYOUT_VERSION,
    MAX_CENTERS,
    MAX_REGIONS,
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
    STAGE_ROWS,
    LinearPart,
    MobiusPart,
    Region,
    Stage,
    describe,
    evaluate,
    n_stages,
    pack,
)

__all__ = [
    "CORE_AFFINE",
    "CORE_TPS",
    "CORE_TPS_INVERSE",
    "LAYOUT_VERSION",
    "MAX_CENTERS",
    "MAX_REGIONS",
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
    "STAGE_ROWS",
    "LinearPart",
    "MobiusPart",
    "Region",
    "Stage",
    "describe",
    "evaluate",
    "n_stages",
    "pack",
]
