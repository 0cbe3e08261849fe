"""The block kind in the words the GL code has used: thin views of
:func:`fpiwarp.block.describe`, the one decoder of a block's kind of map.

Kept as public names of the gl backend (``stage_kinds``, ``is_short_map``,
``constant_dilation``); new code calls ``describe`` directly.
"""

from ...block import describe


def stage_kinds(block):
    """(core, number of regions) of each stage of a parameter block."""
    return [(s.core, s.n_regions) for s in describe(block).stages]


def is_short_map(block):
    """Whether the block is an FPI-like map (see ``BlockKind.is_short``)."""
    return describe(block).is_short


def constant_dilation(block):
    """|f_zbar| / |f_z| of the block's map where it is the same everywhere,
    else None (see ``BlockKind.constant_dilation``)."""
    return describe(block).constant_dilation
