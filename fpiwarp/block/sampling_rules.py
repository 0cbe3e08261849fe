"""The sampling rules every kernel shares, as numbers kernels compare with.

The rules themselves are described in :mod:`fpiwarp._sampling` (the numpy
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
#: footprint (so at most its square per pixel; see fpiwarp._antialias).
AA_MAX_TAPS = 16
#: Antialiasing: a footprint axis of length L source pixels gets
#: ceil(L - AA_SLACK) sub-samples, so that exact shrinks by 1/n (L = n up to
#: rounding) get n sub-samples in float32 and float64 alike.
AA_SLACK = 0.01
