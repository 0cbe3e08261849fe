"""What the GL code needs to know about a parameter block's kind of map.

The block layout is defined in :mod:`fpiwarp.params`; these helpers read
the per-stage header (core, number of regions) to choose a specialized
program, whether a map is short enough to inline several times, and the
constant dilation the preview shows for an FPI. They are kept together
here so that one block-layer description can replace them in one place.
"""

import numpy as np

from ... import params as P


def stage_kinds(block):
    """(core, number of regions) of each stage of a parameter block."""
    block = np.asarray(block)
    rows = [block[1 + k * P.STAGE_ROWS + P.ROW_HEADER] for k in range(P.n_stages(block))]
    return [(int(row[0]), int(row[2])) for row in rows]


def is_short_map(block):
    """Whether every stage of the block has the affine core and no regions
    (FPIs, Möbius and R-linear maps and their compounds): a few dozen
    operations per pixel, cheap to inline several times in one shader."""
    return all(core == P.CORE_AFFINE and n_regions == 0 for core, n_regions in stage_kinds(block))


def constant_dilation(block):
    """The dilation |f_zbar| / |f_z| of the map of a parameter block when it
    is the same everywhere (one stage, affine core, no regions: an FPI, a
    Möbius or R-linear map, whose Möbius parts are conformal), else None."""
    block = np.asarray(block, dtype=np.float64)
    if P.n_stages(block) != 1:
        return None
    core, _, n_regions, _ = (int(v) for v in block[1 + P.ROW_HEADER])
    if core != P.CORE_AFFINE or n_regions:
        return None
    l1re, l1im, l2re, l2im = block[1 + P.ROW_L12]
    return float(np.hypot(l2re, l2im) / np.hypot(l1re, l1im))
