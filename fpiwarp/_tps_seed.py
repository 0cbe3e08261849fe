"""The device Newton's seed table (block rows ``ROW_SEED``, see
:mod:`fpiwarp.block.layout`): the host's float64 inverse of a thin-plate
spline at the nodes of a ``SEED_N``² grid over its targets, stored as
corrections to the R-linear seed.

Why: from the R-linear seed alone the device Newton needs three spline
evaluations for most pixels of a local deformation (measured on the
benchmark's 1080p ``LocalDeformation``: 21 % converge on the second, 79 %
on the third; the seed is 0.07-0.12 off), and a seed that starts in a fold
of the spline can end unsolved or on another branch than the host's. The
table's bilinear seed is 1e-3 off there and nearly every pixel converges
on its second evaluation, on the host's branch.
"""

import numpy as np

from ._transform import unsolved_as_nan
from .block import SEED_N, LinearPart, SeedTable, rlinear_inverse

#: The table's box: the bounding box of the spline's targets (its images
#: of the centers), grown on each side by this part of its larger side
#: (as the host's restart grid, in the target plane).
SEED_PAD = 0.5
#: The table is kept only where it helps: at its cells' centers its
#: bilinear seed must lie no farther from the host's inverse than the
#: R-linear seed plus this part of the box's larger side. Where the spline
#: folds near its targets (strong deformations), the nodes' preimages can
#: lie on different branches and their interpolation is no seed at all:
#: such a stage keeps the plain R-linear seed (all-zero table rows).
SEED_SLACK = 0.01
#: From this many targets on, the host Newton builds the table first (some
#: 120 host inverses, tens of ms) to seed from it; fewer use it only where
#: it exists already (a block was packed).
HOST_TABLE_POINTS = 50_000


def seed_table(inverse, targets: np.ndarray, linear: LinearPart) -> SeedTable:
    """The seed table of ``inverse`` (a transform solving spline(x) = t on
    complex targets t, NaN where it cannot) over the box of ``targets``;
    ``linear`` is the spline's R-linear part, whose inverse is the seed
    the corrections add to. Nodes the host leaves unsolved get no
    correction (the plain R-linear seed)."""
    t = np.asarray(targets, dtype=np.complex128).reshape(-1)
    t = t[np.isfinite(t)]
    lo = complex(t.real.min(), t.imag.min()) if t.size else 0j
    hi = complex(t.real.max(), t.imag.max()) if t.size else 0j
    side = max(hi.real - lo.real, hi.imag - lo.imag)
    side = side if side > 0 else 1.0
    pad = SEED_PAD * side
    lo, hi = lo - pad * (1 + 1j), hi + pad * (1 + 1j)
    step = complex((hi.real - lo.real) / (SEED_N - 1), (hi.imag - lo.imag) / (SEED_N - 1))
    k = np.arange(SEED_N)
    nodes = (lo.real + step.real * k)[None, :] + 1j * (lo.imag + step.imag * k)[:, None]
    mu = rlinear_inverse(linear)

    def solve(t):
        with unsolved_as_nan(), np.errstate(all="ignore"):
            x = inverse.map_complex(t)
        return x, x - (mu.l1 * t + mu.l2 * np.conj(t) + mu.l3)

    x, corr = solve(nodes)
    corr = np.where(np.isfinite(corr), corr, 0)
    # the check: the cells' centers, bilinear there = the mean of 4 corrections
    _, want = solve(0.5 * (nodes[:-1, :-1] + nodes[1:, 1:]))
    got = 0.25 * (corr[:-1, :-1] + corr[:-1, 1:] + corr[1:, :-1] + corr[1:, 1:])
    ok = np.isfinite(want)
    worse = np.abs(got - want)[ok] - np.abs(want)[ok]
    if worse.size and worse.max() > SEED_SLACK * (SEED_N - 1) * max(step.real, step.imag):
        corr = np.zeros_like(corr)
    return SeedTable(lo=lo, step=step, corrections=corr)


def cached_seed_table(inverse) -> SeedTable:
    """The seed table of an ``InverseThinPlateSpline`` (its ``tps``, and
    ``region`` if set), computed once per spline: the inverse object is
    made anew on every ``.inverse``, the spline is not, and the table costs
    some 120 host inverses (tens of ms)."""
    tps = inverse.tps
    cache = tps.__dict__.setdefault("seed_tables", {})
    key = inverse.region is None
    if key not in cache:
        cache[key] = seed_table(inverse, tps.map_complex(tps.centers), LinearPart(*tps.lam))
    return cache[key]


def table_correction(table: SeedTable, target: np.ndarray) -> np.ndarray:
    """The table's bilinear correction at complex targets, in float64 (the
    rule of :func:`fpiwarp.block.reference.seed_correction`: clamped to the
    box, NaN read as its first node)."""
    last = SEED_N - 1

    def axis(v, lo, step):
        with np.errstate(invalid="ignore"):
            f = (v - lo) / step
            f = np.where(f > 0, np.minimum(f, last), 0.0)
        i = np.minimum(np.floor(f), last - 1).astype(np.intp)
        return i, f - i

    i, tx = axis(target.real, table.lo.real, table.step.real)
    j, ty = axis(target.imag, table.lo.imag, table.step.imag)
    c = table.corrections
    bottom = c[j, i] + tx * (c[j, i + 1] - c[j, i])
    top = c[j + 1, i] + tx * (c[j + 1, i + 1] - c[j + 1, i])
    return bottom + ty * (top - bottom)


def host_seed(inverse, target: np.ndarray) -> np.ndarray:
    """The host Newton's first seed: the R-linear inverse, plus the table's
    correction where the spline's table exists or ``target`` has at least
    HOST_TABLE_POINTS points (the table's own nodes are solved from the
    plain seed). The same gain as on the devices: a step or two fewer per
    point."""
    mu1, mu2, mu3 = inverse.tps.affine_inverse
    x = mu1 * target + mu2 * np.conj(target) + mu3
    table = inverse.tps.__dict__.get("seed_tables", {}).get(inverse.region is None)
    if table is None and target.size >= HOST_TABLE_POINTS:
        table = cached_seed_table(inverse)
    if table is None or not np.any(table.corrections):
        return x
    return x + table_correction(table, target)
