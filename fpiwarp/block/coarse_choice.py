"""Whether a warp takes the coarse pass (:mod:`fpiwarp.block.coarse`): the
one rule every backend asks, per map and output shape.

The pass costs the nodes' solves and one value-only spline evaluation per
band pixel (the pixels no region takes), and saves the per-pixel Newton
(about 2.2 evaluations) only where a pixel's seed passes the check. So it
wins only where most seeds pass, and that share depends on how smooth the
map is across COARSE_STEP output pixels against the Newton tolerance, not
on the size alone: on the benchmark's local deformation 8 % of the band
passes at 128², 61 % at 512², 96 % at 1080p, while a quad of 48 px
passes 31 % at 128² and 60 % at 1080p.

:func:`takes_coarse_pass` compares a predicted share with the share the
pass needs on the backend (:func:`share_needed`): :data:`BREAK_EVEN`
(measured: where the two paths' CPU times cross over for a band over the
whole output, benchmarks/local_pick.py) plus the nodes' cost, which grows
as the band shrinks (the nodes cover the output, the saving is the
band's: a quad of 48 px in 1080², band 4 %, passes 60 % and still solves
faster per pixel). The share is predicted on the host in float64 in two
steps, both from up to :data:`SAMPLE_CELLS` node cells spread over the
band:

* :func:`curvature_share` (about 0.3 ms): at each cell's center, the
  bilinear interpolation's error from the map's second derivatives,
  without a Newton solve. Over the 27 maps of benchmarks/local_pick.py
  against the float32 reference's share it is off by 0.10 on average,
  overestimates by up to 0.36 where the band reaches far from the
  spline's centers and underestimates by at most 0.18: below the share
  needed by more than
  :data:`SCREEN_MARGIN` the warp solves per pixel without the second step,
  above it by :data:`SURE_MARGIN` or more (or at :data:`SURE_SHARE`) it
  takes the pass without it, and for a band of fewer than
  :data:`SAMPLE_MIN_BAND_PIXELS` pixels it solves per pixel otherwise
  (the second step would cost about what the pass saves);
* :func:`seed_pass_share` (about 1 ms): the cells' nodes solved by Newton
  as the pass solves them, and the check at :data:`SAMPLE_OFFSETS` ² pixels
  of each: the pass itself on a sample (off by 0.04 on average, at most
  0.16, on the same maps).

Both are remembered for the last few (block, shape): a bound map warping
many images decides once.
"""

import numpy as np

from .coarse import coarse_shape, newton_stage
from .describe import describe, stage_rows
from .layout import COARSE_STEP, PAIRED_CORES, ROW_CENTERS, ROW_L3, ROW_L12, ROW_MU3, ROW_MU12
from .reference import complex_at, evaluate_stage, newton, pre_mobius, region_winner, seed_correction, tps_core

#: The predicted share of band pixels whose seed passes the check from
#: which a backend's warp of a band covering its output takes the coarse
#: pass (:func:`share_needed` adds the nodes' cost for a smaller band):
#: where its coarse-pass and per-pixel CPU times crossed over, measured
#: over map families and sizes (benchmarks/local_pick.py; the benchmark's
#: map, band 20 %: opencl between 384² (42 % pass, per-pixel / coarse CPU
#: time 1.06) and 256² (21 %, 0.86); gl between 768² (85 %, 1.14) and 512²
#: (61 %, 0.93)). gl's single warps since their seeded draws are split
#: (fpiwarp/backends/gl/band.py: the region pass, then the band, and no
#: node solved where a region holds every pixel reading it), from one quiet
#: run of benchmarks/local_pick.py on the merged code (results/local_pick.md):
#: the benchmark's map between 384² (42 %, 0.98) and 512² (61 %, 1.16), and
#: no node cost beyond the band's (:data:`NODE_COST`); "gl batch": gl's
#: batches, drawn unsplit, as measured before. Backends not listed: "default".
BREAK_EVEN = {"opencl": 0.35, "gl": 0.45, "gl batch": 0.62, "default": 0.4}
#: Backends whose share needed does not grow as the band shrinks: gl's
#: split draw solves only the nodes the band reads, and its per-pixel draw
#: (unsplit) runs the Newton code for every SIMD group, region pixels
#: included, so a small band does not favour per-pixel Newton there (a
#: 24 px quad in 512², band 5 %, 15 % of its seeds passing: the pass took
#: 0.88 of per-pixel's CPU time; a 48 px quad in 1080², band 4 %: 0.69).
NODE_COST = {"gl": False}
#: True: every Newton map's warp takes the pass, the rule not asked (tests
#: of the pass itself, and benchmarks' forced "after"; the backends'
#: COARSE_PASS switches still turn it off).
ALWAYS = False
#: How far below the break-even curvature_share may lie and still be
#: checked by seed_pass_share (it underestimated by at most 0.2).
SCREEN_MARGIN = 0.25
#: How far above the share needed curvature_share must lie for the pass
#: to be taken without seed_pass_share (it overestimated by at most 0.36).
SURE_MARGIN = 0.4
#: ... or where it reaches this share (the most it overestimated was 0.36).
SURE_SHARE = 0.95
#: Band pixels below which the screen decides alone (the pass only where
#: it is sure, above): there seed_pass_share (about 1 ms of CPU) costs
#: about what the pass could save (a 128² warp with a band of half the
#: frame saved 0.7-1.3 ms where nearly every seed passed; batches of 64
#: fresh 128² maps took 1.17x the per-pixel CPU time with the sample
#: asked, and the screen alone against the share needed overestimated
#: enough to take the pass for half of them, 1.2x).
SAMPLE_MIN_BAND_PIXELS = 16384
#: Node cells of the band sampled (evenly by index among the band's).
SAMPLE_CELLS = 16
#: Pixel offsets within a sampled cell (x and y) at which seed_pass_share checks.
SAMPLE_OFFSETS = tuple(range(1, COARSE_STEP, 2))
#: At most about this many node cells are tested for the band (a strided
#: subset of a large output's).
CANDIDATE_CELLS = 4096
#: Output pixels between the points whose difference gives the target's steps per pixel.
STEP_EPS = 1e-3


#: (block, shape) answers each estimate remembers, least recently used dropped.
REMEMBERED = 64


def _remembered(fn):
    """``fn`` of hashable arguments, its last REMEMBERED answers kept (the
    block layer imports only numpy: a dict keeps insertion order);
    ``.cache_clear()`` forgets them, ``.__wrapped__`` is ``fn``."""
    kept = {}

    def remembered(*key):
        if key in kept:
            kept[key] = kept.pop(key)  # now the most recent
            return kept[key]
        value = kept[key] = fn(*key)
        if len(kept) > REMEMBERED:
            del kept[next(iter(kept))]
        return value

    remembered.cache_clear, remembered.__wrapped__, remembered.__doc__ = kept.clear, fn, fn.__doc__
    return remembered


def forget():
    """Forget the remembered estimates (of every block and shape): the next
    question about any map estimates again (benchmarks time the rule on
    fresh maps with it)."""
    for remembered in (_band, _curvature_share, _seed_pass_share):
        remembered.cache_clear()


def takes_coarse_pass(block, width, height, backend="default"):
    """Whether a warp by ``block`` to ``width`` x ``height`` on ``backend``
    (a :data:`BREAK_EVEN` name) takes the coarse pass: the block has a
    Newton core and its predicted share of passing seeds reaches
    :func:`share_needed` (see the module docstring). The backends'
    COARSE_PASS switches still turn the pass off before this is asked."""
    if ALWAYS:
        return newton_stage(describe(np.asarray(block, np.float32))) is not None
    screen = curvature_share(block, width, height)
    if screen is None:
        return False
    line = share_needed(block, width, height, backend)
    if screen < line - SCREEN_MARGIN:
        return False
    if screen >= min(line + SURE_MARGIN, SURE_SHARE):
        return True
    if _band_pixels(block, width, height) < SAMPLE_MIN_BAND_PIXELS:  # the sample would cost about what it could save
        return False
    return seed_pass_share(block, width, height) >= line


def _band_pixels(block, width, height):
    """About how many output pixels the band of ``block`` covers."""
    block = np.ascontiguousarray(block, dtype=np.float32)
    return _band(block.tobytes(), block.shape, int(width), int(height))[2] * int(width) * int(height)


def share_needed(block, width, height, backend="default"):
    """The share of passing seeds from which the pass wins for a warp of
    ``block`` (a Newton map's) to ``width`` x ``height`` on ``backend``:
    BREAK_EVEN's (a band over the whole output) plus the nodes' cost
    against the band's saving, nodes per output pixel over the band's
    share of the output (the nodes cover the whole output, the saving is
    the band's): a band of 4 % of 1080² needs 0.39 more."""
    block = np.ascontiguousarray(block, dtype=np.float32)
    band = _band(block.tobytes(), block.shape, int(width), int(height))[2]
    if band <= 0:
        return np.inf
    line = BREAK_EVEN.get(backend, BREAK_EVEN["default"])
    if not NODE_COST.get(backend, True):
        return line
    ny, nx = coarse_shape(width, height)
    return line + ny * nx / (int(width) * int(height)) / band


def curvature_share(block, width, height):
    """The share of band pixels whose seed passes the check as the map's
    second derivatives predict it, in [0, 1]; None for a block without a
    Newton core, 0.0 for an output without band pixels (the regions take
    every pixel: the pass would solve its nodes for nothing).

    At the centers of the sampled cells (:func:`_band_cells`), x the seed
    table's approximate preimage of the center's target t, the steps τ of
    t per output pixel along x and y give the inverse's steps
    δ = a τ + b conj(τ) (a, b as the pass's records), and a seed
    interpolated at fractions (u, v) of a cell of side h = COARSE_STEP
    misses by the residual r = -(u (h - u) D²f(δx, δx) + v (h - v) D²f(δy, δy)) / 2
    (the bilinear interpolation's error; its cross term is exact), with
    D²f(δ, δ) = f_zz δ² + 2 f_zzbar |δ|² + f_zbarzbar conj(δ)²: the share
    of (cell, u, v) with |r| within the Newton tolerance."""
    block = np.ascontiguousarray(block, dtype=np.float32)
    return _curvature_share(block.tobytes(), block.shape, int(width), int(height))


def seed_pass_share(block, width, height):
    """The share of band pixels whose seed passes the check, measured on a
    sample: the sampled cells' (:func:`_band_cells`) four nodes solved in
    float64 by Newton from the seed table, each stopping within the
    tolerance as the pass's do, and the check at SAMPLE_OFFSETS x
    SAMPLE_OFFSETS pixels of each cell that no region takes. None and 0.0
    as :func:`curvature_share`."""
    block = np.ascontiguousarray(block, dtype=np.float32)
    return _seed_pass_share(block.tobytes(), block.shape, int(width), int(height))


class _Stage:
    """The float64 Newton stage of a block and the output pixels at its input."""

    def __init__(self, data, shape):
        self.block = np.frombuffer(data, np.float32).reshape(shape).astype(np.float64)
        self.kind = describe(self.block)
        self.k = newton_stage(self.kind)
        if self.k is None:
            return
        self.rows, self.stage = stage_rows(self.block, self.k), self.kind.stages[self.k]
        self.tol = self.rows[ROW_L3, 2]
        self.paired = self.stage.core in PAIRED_CORES
        self.spline = _spline64(self.rows, self.stage.n_centers, self.paired)

    def input(self, q):
        """Complex output pixels q at the Newton stage's input."""
        for s in range(self.k):
            q = evaluate_stage(stage_rows(self.block, s), self.kind.stages[s], q, np.float64)
        return q

    def band(self, z):
        """Where no region of the stage takes its input points z."""
        return ~region_winner(self.rows, self.stage, z, np.float64)[0] & np.isfinite(z)

    def seed(self, t):
        """The seed table's preimage of targets t (the Newton core's start)."""
        rows = self.rows
        mu1, mu2, mu3 = complex_at(rows[ROW_MU12], 0), complex_at(rows[ROW_MU12], 2), complex_at(rows[ROW_MU3], 0)
        return mu1 * t + mu2 * np.conj(t) + mu3 + seed_correction(t, rows, np.float64)


def _band_cells(stage, width, height):
    """(i, j, share): up to SAMPLE_CELLS node cells (cell (i, j) has nodes
    (i, j) to (i + 1, j + 1)) whose centers no region takes, spread evenly
    by index over them (the candidates: every cell, or a strided subset
    of about CANDIDATE_CELLS; empty arrays where there are none), and the
    share of the candidates they are drawn from (the band's share of the
    output)."""
    ny, nx = coarse_shape(width, height)
    stride = max(1, int(np.ceil(np.sqrt((ny - 1) * (nx - 1) / CANDIDATE_CELLS))))
    cj, ci = (g.reshape(-1) for g in np.mgrid[0:ny - 1:stride, 0:nx - 1:stride])
    h = COARSE_STEP
    centre = np.minimum(h * ci + h / 2, width - 1) + 1j * np.minimum(h * cj + h / 2, height - 1)
    with np.errstate(all="ignore"):
        band = np.flatnonzero(stage.band(stage.input(centre)))
    pick = band[np.unique(np.linspace(0, band.size - 1, min(SAMPLE_CELLS, band.size)).round().astype(int))]
    return ci[pick], cj[pick], band.size / ci.size


@_remembered
def _band(data, shape, width, height):
    """:func:`_band_cells` of a block's bytes (a Newton map's), remembered."""
    return _band_cells(_Stage(data, shape), width, height)


def _band_share(fn):
    """``fn(stage, i, j, width, height)``, the share of a sample of the band
    cells (i, j) of a block's bytes, as a remembered function of (data,
    shape, width, height), in numpy's errstate "ignore": None for a block
    without a Newton core, 0.0 for an empty band."""
    def share(data, shape, width, height):
        stage = _Stage(data, shape)
        if stage.k is None:
            return None
        with np.errstate(all="ignore"):
            i, j, _ = _band(data, shape, width, height)
            return fn(stage, i, j, width, height) if i.size else 0.0
    share.__doc__ = fn.__doc__
    return _remembered(share)


@_band_share
def _curvature_share(stage, i, j, width, height):
    h = COARSE_STEP
    centre = np.minimum(h * i + h / 2, width - 1) + 1j * np.minimum(h * j + h / 2, height - 1)
    t = pre_mobius(stage.rows, stage.input(centre))
    steps = [(pre_mobius(stage.rows, stage.input(centre + e)) - t) / abs(e) for e in (STEP_EPS, 1j * STEP_EPS)]
    fz, fzb, fzz, fzzb, fzbzb = _derivatives(stage.spline, stage.seed(t))
    jac = np.abs(fz) ** 2 - np.abs(fzb) ** 2
    a, b = np.conj(fz) / jac, -fzb / jac
    second = []
    for tau in steps:
        d = a * tau + b * np.conj(tau)
        second.append(fzz * d * d + 2 * fzzb * np.abs(d) ** 2 + fzbzb * np.conj(d) ** 2)
    frac = np.arange(h)
    weight = frac * (h - frac)
    r = -0.5 * (weight[None, None, :] * second[0][:, None, None] + weight[None, :, None] * second[1][:, None, None])
    passed = np.abs(r) <= stage.tol  # NaN: False
    return float(passed.mean())


@_band_share
def _seed_pass_share(stage, i, j, width, height):
    h = COARSE_STEP
    corners = ((0, 0), (1, 0), (0, 1), (1, 1))
    nodes = np.concatenate([h * (i + di) + 1j * h * (j + dj) for di, dj in corners])
    t = pre_mobius(stage.rows, stage.input(nodes))
    x = newton(t, stage.rows, stage.stage.n_centers, stage.stage.newton_iters, stage.tol, np.float64, stage.paired)
    x00, x10, x01, x11 = (x[m * i.size:(m + 1) * i.size, None] for m in range(4))
    off = np.asarray(SAMPLE_OFFSETS)
    u, v = (g.reshape(-1) for g in np.meshgrid(off, off))
    fx, fy = u / h, v / h
    bottom, top = x00 + fx * (x10 - x00), x01 + fx * (x11 - x01)
    seed = (bottom + fy * (top - bottom)).reshape(-1)
    px, py = (h * i[:, None] + u).reshape(-1), (h * j[:, None] + v).reshape(-1)
    z = stage.input(px + 1j * py)
    inside = (px < width) & (py < height) & stage.band(z)
    value = tps_core(seed, stage.rows, stage.stage.n_centers, np.float64, stage.paired)[0]
    passed = np.abs(value - pre_mobius(stage.rows, z)) <= stage.tol  # NaN seeds: False
    return float(passed[inside].mean()) if inside.any() else 0.0


def _spline64(rows, n, paired):
    """The float64 TPS core of a stage: (l1, l2, l3, centers (m,), weights
    (m,)), a paired core's pairs (c, W = b1 + b2), (d, b2) as their two
    plain centers c and c + d (in float64 the plain sum keeps the
    precision the pairs are for)."""
    l1, l2, l3 = complex_at(rows[ROW_L12], 0), complex_at(rows[ROW_L12], 2), complex_at(rows[ROW_L3], 0)
    cr = rows[ROW_CENTERS:ROW_CENTERS + n].astype(np.float64)
    c, w = cr[:, 0] + 1j * cr[:, 1], cr[:, 2] + 1j * cr[:, 3]
    if paired:
        c1, w1, d, b2 = c[0::2], w[0::2], c[1::2], w[1::2]
        c, w = np.concatenate([c1, c1 + d]), np.concatenate([w1 - b2, b2])
    return l1, l2, l3, c, w


def _radial(spline, p):
    """(p - c (points, centers), |p - c|² there, its log (0 at a center))."""
    d = p[:, None] - spline[3][None, :]
    a = d.real**2 + d.imag**2
    return d, a, np.log(np.where(a > 0, a, 1))


def _derivatives(spline, p):
    """The float64 spline's Wirtinger derivatives at complex p: (f_z,
    f_zbar, f_zz, f_zzbar, f_zbarzbar)."""
    l1, l2, _, _, w = spline
    d, a, lg = _radial(spline, p)
    hit = a > 0
    gw = 0.5 * (lg + 1) * hit * w
    first = (l1 + (gw * np.conj(d)).sum(axis=1), l2 + (gw * d).sum(axis=1))
    ratio = np.where(hit, np.conj(d) / np.where(hit, d, 1), 0)
    half = 0.5 * w
    return (*first, (half * ratio).sum(axis=1), (half * (lg + 2) * hit).sum(axis=1),
            (half * np.conj(ratio)).sum(axis=1))
