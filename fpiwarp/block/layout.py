"""The layout of the parameter block: the one contract every kernel reads.

Coefficients are solved on the host in float64 and packed into one flat
float32 array of vec4 rows. GLSL reads it as a uniform block of ``vec4``
(no std140 padding traps), OpenCL as a ``__constant float4 *`` buffer,
Warp as an array of ``vec4``. Changing values never changes the layout,
so one compiled program serves every map of a kind. Every number below
reaches the kernels through :mod:`fpiwarp.block.codegen`, never by hand.

Block layout (rows of 4 float32)
--------------------------------
Row 0, the block header: ``[n_stages, LAYOUT_VERSION, 0, 0]``.
Then ``n_stages`` stages of ``STAGE_ROWS`` rows each, applied in order:
stage ``k`` starts at row ``1 + k * STAGE_ROWS``. Complex numbers are
stored as (re, im). Offsets within a stage, with the :class:`Stage`
fields they come from:

====  ==========================================================
row   contents
====  ==========================================================
0     ``[core, n_centers, n_regions, newton_iters]`` (small ints)
1     ``[q1.re, q1.im, s1.re, s1.im]``   pre.center, pre.inverse_pole
2     ``[k1.re, k1.im, k2.re, k2.im]``   pre.scale, post.scale
3     ``[s2.re, s2.im, q2.re, q2.im]``   post.inverse_pole, post.offset
4     ``[l1.re, l1.im, l2.re, l2.im]``   linear.l1, linear.l2 (R-linear part of the core)
5     ``[l3.re, l3.im, newton_tol, 0]``  linear.l3, newton_tol
6     ``[mu1.re, mu1.im, mu2.re, mu2.im]`` inverse of the R-linear part
7     ``[mu3.re, mu3.im, 0, 0]``           (seed of the Newton inverse)
8+2r  ``[o.re, o.im, n.re, n.im]``       region r: a point on its line
                                          and the outward normal
9+2r  ``[a.re, a.im, b.re, b.im]``       region r's similarity a z + b
12+j  ``[c.re, c.im, b.re, b.im]``       TPS center j and its weight
====  ==========================================================

The paired TPS cores (``CORE_TPS_PAIRS``, ``CORE_TPS_PAIRS_INVERSE``) read
the same center rows two at a time: pair j is rows 12+2j and 13+2j,

=====  ==========================================================
row    contents
=====  ==========================================================
12+2j  ``[c.re, c.im, W.re, W.im]``       the pair's first center c and
                                           the summed weight W = b1 + b2
13+2j  ``[d.re, d.im, b2.re, b2.im]``     the offset d of its second center
                                           c + d, and that center's weight
=====  ==========================================================

(``n_centers`` counts rows: twice the pairs). A constrained FPI's spline
has an edge point and its offset copy a distance δ apart with nearly
opposite weights of order 1 / δ; summed as two float32 terms they cancel
catastrophically. The pair's term
``W U(|p - c|) + b2 (U(|p - c - d|) - U(|p - c|))`` holds W (of order 1,
summed in float64 on the host), d (full relative precision) and the
difference of U computed without cancellation
(``fpiwarp.block.tps_pairs.pair_terms``). A center without a partner
is a pair with d = 0 and b2 = 0: its term is exactly the plain one.

The Newton cores (``CORE_TPS_INVERSE``, ``CORE_TPS_PAIRS_INVERSE``) seed
from a table of exact inverses, after the center rows
(``ROW_SEED = ROW_CENTERS + MAX_CENTERS``):

=============  ==========================================================
row            contents
=============  ==========================================================
ROW_SEED       ``[lo.re, lo.im, gx, gy]``: the table's box in the core's
               target plane starts at lo; node (i, j) lies at
               lo + i / gx + 1j j / gy, i, j in 0 .. SEED_N - 1
ROW_SEED + 1   ``[c(k).re, c(k).im, c(k+1).re, c(k+1).im]``, k = 2 h:
  + h          the correction x - (mu1 t + mu2 conj(t) + mu3) at node
               k = j SEED_N + i, x the host's float64 inverse at the
               node t (0 where the host has none)
=============  ==========================================================

The seed at a target t is the R-linear seed plus the bilinear interpolation
of the corrections, with fx = (t.re - lo.re) gx clamped to [0, SEED_N - 1]
(NaN: 0), i = min(floor(fx), SEED_N - 2) (fy, j alike): beyond the box the
edge's corrections continue. All-zero rows (gx = gy = 0, no corrections)
give the plain R-linear seed. With the table a Newton point typically
converges on its second evaluation (one step) instead of its third, and the
seed lies on the right branch where the R-linear one may start in a fold.

Evaluating one stage on a point z (:func:`fpiwarp.block.reference.evaluate`
is the reference every kernel mirrors line by line):

1. Regions: for each region r, depth = Re((z - o) * conj(n)). If some
   depth is > 0, the region with the largest depth wins and the stage
   returns a * z + b. Otherwise:
2. pre-Möbius: u = z - q1; p = k1 * u / (1 - s1 * u)
3. core (``CORE_AFFINE``): p = l1 p + l2 conj(p) + l3;
   (``CORE_TPS``) ``p = sum_j b_j r² log r + l1 p + l2 conj(p) + l3``, ``r = |p - c_j|``;
   (``CORE_TPS_PAIRS``, ``CORE_TPS_PAIRS_INVERSE``) the same with the
   paired terms above;
   (``CORE_TPS_INVERSE``) solve TPS(x) = p by Newton from
   x0 = mu1 p + mu2 conj(p) + mu3 + the table's correction at p (above),
   at most newton_iters steps, stopping
   once ``|TPS(x) - p| <= newton_tol``; not converged: NaN (outside);
   any other core: the host refuses the block (:func:`describe` raises),
   and a kernel given one anyway returns NaN (outside).
4. post-Möbius: w = q2 + k2 * p / (1 - s2 * p)

A result that is not finite is "outside": images give it the border
treatment (cval).
"""

LAYOUT_VERSION = 2
MAX_CENTERS = 64
MAX_REGIONS = 2
MAX_STAGES = 8
#: Nodes per side of a Newton core's seed table (SEED_N² corrections).
SEED_N = 8

#: A warp's coarse pass (:mod:`fpiwarp.block.coarse`): output pixels between
#: its nodes, and floats per node (x, a, b: the Newton solution and the
#: inverse Jacobian's Wirtinger parts there).
COARSE_STEP = 8
COARSE_FLOATS = 6

# Row offsets within a stage (see the table above).
ROW_HEADER, ROW_PRE, ROW_SCALE, ROW_POST = 0, 1, 2, 3
ROW_L12, ROW_L3, ROW_MU12, ROW_MU3 = 4, 5, 6, 7
ROW_REGIONS = 8
ROW_CENTERS = ROW_REGIONS + 2 * MAX_REGIONS
ROW_SEED = ROW_CENTERS + MAX_CENTERS
ROW_SEED_GRID = ROW_SEED + 1
STAGE_ROWS = ROW_SEED_GRID + SEED_N * SEED_N // 2
#: Rows of the largest block: the header and MAX_STAGES stages.
MAX_ROWS = 1 + MAX_STAGES * STAGE_ROWS

# The cores, by number (header column 0).
CORE_AFFINE, CORE_TPS, CORE_TPS_INVERSE = 0, 1, 2
#: The TPS cores with paired center rows (see the second table above).
CORE_TPS_PAIRS, CORE_TPS_PAIRS_INVERSE = 3, 4
#: Every core a kernel knows, by name; any other number is refused.
CORES = {
    "affine": CORE_AFFINE,
    "tps": CORE_TPS,
    "tps_inverse": CORE_TPS_INVERSE,
    "tps_pairs": CORE_TPS_PAIRS,
    "tps_pairs_inverse": CORE_TPS_PAIRS_INVERSE,
}
#: The cores whose center rows are read in pairs.
PAIRED_CORES = (CORE_TPS_PAIRS, CORE_TPS_PAIRS_INVERSE)
#: The Newton cores (a warp's coarse pass seeds the first one's per-pixel solve).
NEWTON_CORES = (CORE_TPS_INVERSE, CORE_TPS_PAIRS_INVERSE)
