"""The block contract's numbers as Warp constants, for every NVIDIA Warp kernel.

Each is bound by name from the one table of :mod:`fpiwarp.block.codegen`
(``KERNEL_CONSTANTS``), which also writes them for OpenCL and GLSL: no
kernel writes a contract number by hand (``tests/block/test_block.py``
checks this file).
"""

import warp as wp

from fpiwarp.block.codegen import KERNEL_CONSTANTS as CONTRACT

STAGE_ROWS = wp.constant(CONTRACT["STAGE_ROWS"])
ROW_HEADER = wp.constant(CONTRACT["ROW_HEADER"])
ROW_PRE = wp.constant(CONTRACT["ROW_PRE"])
ROW_SCALE = wp.constant(CONTRACT["ROW_SCALE"])
ROW_POST = wp.constant(CONTRACT["ROW_POST"])
ROW_L12 = wp.constant(CONTRACT["ROW_L12"])
ROW_L3 = wp.constant(CONTRACT["ROW_L3"])
ROW_MU12 = wp.constant(CONTRACT["ROW_MU12"])
ROW_MU3 = wp.constant(CONTRACT["ROW_MU3"])
ROW_REGIONS = wp.constant(CONTRACT["ROW_REGIONS"])
ROW_CENTERS = wp.constant(CONTRACT["ROW_CENTERS"])
ROW_SEED = wp.constant(CONTRACT["ROW_SEED"])
ROW_SEED_GRID = wp.constant(CONTRACT["ROW_SEED_GRID"])
SEED_N = wp.constant(CONTRACT["SEED_N"])
CORE_AFFINE = wp.constant(CONTRACT["CORE_AFFINE"])
CORE_TPS = wp.constant(CONTRACT["CORE_TPS"])
CORE_TPS_INVERSE = wp.constant(CONTRACT["CORE_TPS_INVERSE"])
CORE_TPS_PAIRS = wp.constant(CONTRACT["CORE_TPS_PAIRS"])
CORE_TPS_PAIRS_INVERSE = wp.constant(CONTRACT["CORE_TPS_PAIRS_INVERSE"])
MODE_CONSTANT = wp.constant(CONTRACT["MODE_CONSTANT"])
MODE_EDGE = wp.constant(CONTRACT["MODE_EDGE"])
MODE_REFLECT = wp.constant(CONTRACT["MODE_REFLECT"])
MODE_WRAP = wp.constant(CONTRACT["MODE_WRAP"])
COORD_LIMIT = wp.constant(CONTRACT["COORD_LIMIT"])

# Antialiasing's footprint (fpiwarp.sampling.antialias).
AA_MAX_TAPS = wp.constant(CONTRACT["AA_MAX_TAPS"])
AA_SLACK = wp.constant(CONTRACT["AA_SLACK"])
AA_SPACING = wp.constant(CONTRACT["AA_SPACING"])
AA_KNEE_TAPS = wp.constant(CONTRACT["AA_KNEE_TAPS"])
AA_FAR_SPACING = wp.constant(CONTRACT["AA_FAR_SPACING"])
# Antialiasing over the source pyramid (fpiwarp.sampling.pyramid).
AA_LEVEL_SPAN = wp.constant(CONTRACT["AA_LEVEL_SPAN"])
AA_BLEND = wp.constant(CONTRACT["AA_BLEND"])
AA_MAX_LEVEL = wp.constant(CONTRACT["AA_MAX_LEVEL"])
