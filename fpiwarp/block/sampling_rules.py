"""The sampling rules every kernel shares, as numbers kernels compare with.

The rules themselves are described in :mod:`fpiwarp.sampling.sampler` (the numpy
reference); this module holds the numbers they reach the kernels by, so
that :mod:`fpiwarp.block.codegen` generates them for every language.
"""

#: Border modes; a mode's number in every kernel is its index here.
MODES = ("constant", "edge", "reflect", "wrap")
MODE_CONSTANT, MODE_EDGE, MODE_REFLECT, MODE_WRAP = (MODES.index(m) for m in ("constant", "edge", "reflect", "wrap"))
#: Interpolation orders (kernels receive the order itself: 0, 1 or 3).
ORDERS = (0, 1, 3)
#: Source positions beyond this many pixels count as "outside" (cval).
COORD_LIMIT = float(2**24)
#: Antialiasing: at most this many sub-samples per axis of an output pixel's
#: footprint (so at most its square per pixel; see fpiwarp.sampling.antialias).
AA_MAX_TAPS = 16
#: Antialiasing: a footprint axis of length L source pixels gets one
#: sub-sample where L <= 1 + AA_SLACK (no shrinking: plain interpolation),
#: else ceil(min(L / AA_SPACING, max(AA_KNEE_TAPS, L / AA_FAR_SPACING)) -
#: AA_SLACK) but at least 2: sub-samples at most AA_SPACING source pixels
#: apart up to AA_KNEE_TAPS of them, then at most AA_FAR_SPACING apart.
#: The slack makes exact shrinks get the same counts in float32 and
#: float64 alike.
AA_SLACK = 0.01
#: Antialiasing: the largest spacing of sub-samples, in source pixels. 1.25
#: rather than 1: the taps' own low-pass covers the gaps (FPI 1/3 of a zone
#: plate: 35.97 dB against the exact box, 35.99 at spacing 1; 1/2: 31.1 vs
#: 31.7) with half the sub-samples at a typical 1/2 (footprints a little
#: over 2 pixels: 2 per edge, not 3). 1.5 loses more (a period-2 pattern
#: shrunk 1/4 keeps 12% of its contrast) for little more speed.
AA_SPACING = 1.25
#: Antialiasing: beyond this many sub-samples per edge (footprints longer
#: than 6.25 pixels), sub-samples may lie up to AA_FAR_SPACING pixels
#: apart: half the samples at 1/8 (32 rather than 61 per pixel), for a
#: picture that stays far from aliasing (FPI 1/8 of the zone plate: 34.9 dB
#: against the exact box, 43.0 with AA_SPACING throughout, 12.6 without
#: antialiasing; the astronaut: 53.9, 62.7 and 23.5 dB).
AA_KNEE_TAPS = 5
AA_FAR_SPACING = 1.75
#: Antialiasing over the source pyramid (fpiwarp.sampling.pyramid): the
#: footprint is supersampled as above at the level where its shorter edge
#: spans AA_LEVEL_SPAN to 2 * AA_LEVEL_SPAN texels: level
#: floor(lod), lod = log2(L_short * (1 + AA_SLACK) / AA_LEVEL_SPAN) clamped
#: to [0, the top level]. Below a shrink of AA_LEVEL_SPAN that is level 0,
#: the source itself (the supersampling of earlier releases, bit for bit);
#: beyond it every edge has at most 2 * AA_LEVEL_SPAN / AA_SPACING + 1
#: sub-samples per unit of anisotropy, whatever the shrink.
AA_LEVEL_SPAN = 2.0
#: Antialiasing: in the last AA_BLEND of each octave of lod the result
#: blends linearly into the next level's (weight (frac(lod) - 1 + AA_BLEND)
#: / AA_BLEND), so that a smoothly varying shrink never switches level with
#: a step; elsewhere one level is read.
AA_BLEND = 0.25
#: Antialiasing: the coarsest pyramid level built (a shrink of 2**15).
AA_MAX_LEVEL = 15
