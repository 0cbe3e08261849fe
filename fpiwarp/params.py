"""The one parameter block that every backend reads.

Coefficients are solved on the host in float64 and packed into one flat
float32 array of vec4 rows. GLSL reads it as a uniform block of ``vec4``
(no std140 padding traps), OpenCL as a ``__constant float4 *`` buffer,
Warp as an array of ``vec4``. Changing values never changes the layout,
so one compiled program serves every map of a kind.

Block layout (rows of 4 float32)
--------------------------------
Row 0, the block header: ``[n_stages, LAYOUT_VERSION, 0, 0]``.
Then ``n_stages`` stages of ``STAGE_ROWS`` rows each, applied in order:
stage ``k`` starts at row ``1 + k * STAGE_ROWS``. Complex numbers are
stored as (re, im). Offsets within a stage:

====  ==========================================================
row   contents
====  ==========================================================
0     ``[core, n_centers, n_regions, newton_iters]`` (small ints)
1     ``[q1.re, q1.im, s1.re, s1.im]``   pre-Möbius center and pole
2     ``[k1.re, k1.im, k2.re, k2.im]``   pre and post scale
3     ``[s2.re, s2.im, q2.re, q2.im]``   post-Möbius pole and offset
4     ``[l1.re, l1.im, l2.re, l2.im]``   R-linear part of the core
5     ``[l3.re, l3.im, newton_tol, 0]``
6     ``[mu1.re, mu1.im, mu2.re, mu2.im]`` inverse of the R-linear part
7     ``[mu3.re, mu3.im, 0, 0]``           (seed of the Newton inverse)
8+2r  ``[o.re, o.im, n.re, n.im]``       region r: a point on its line
                                          and the outward normal
9+2r  ``[a.re, a.im, b.re, b.im]``       region r's similarity a z + b
12+j  ``[c.re, c.im, b.re, b.im]``       TPS center j and its weight
====  ==========================================================

Evaluating one stage on a point z (``evaluate`` below is the reference
every kernel mirrors line by line):

1. Regions: for each region r, depth = Re((z - o) * conj(n)). If some
   depth is > 0, the region with the largest depth wins and the stage
   returns a * z + b. Otherwise:
2. pre-Möbius: u = z - q1; p = k1 * u / (1 - s1 * u)
3. core (``CORE_AFFINE``): p = l1 p + l2 conj(p) + l3;
   (``CORE_TPS``) p = sum_j b_j r² log r + l1 p + l2 conj(p) + l3, r = |p - c_j|;
   (``CORE_TPS_INVERSE``) solve TPS(x) = p by Newton from
   x0 = mu1 p + mu2 conj(p) + mu3, at most newton_iters steps, stopping
   once |TPS(x) - p| <= newton_tol; not converged: NaN (outside).
4. post-Möbius: w = q2 + k2 * p / (1 - s2 * p)

A result that is not finite is "outside": images give it the border
treatment (cval).
"""

from dataclasses import dataclass, field

import numpy as np

from ._linear import RLinear

LAYOUT_VERSION = 1
STAGE_ROWS = 12 + 64
MAX_CENTERS = 64
MAX_REGIONS = 2
MAX_STAGES = 8
CORE_AFFINE, CORE_TPS, CORE_TPS_INVERSE = 0, 1, 2

ROW_HEADER, ROW_PRE, ROW_SCALE, ROW_POST = 0, 1, 2, 3
ROW_L12, ROW_L3, ROW_MU12, ROW_MU3 = 4, 5, 6, 7
ROW_REGIONS, ROW_CENTERS = 8, 12


@dataclass(frozen=True)
class Region:
    """A half-plane beyond a line, mapped by the similarity z -> a z + b."""

    origin: complex
    normal: complex
    a: complex
    b: complex


@dataclass(frozen=True)
class Stage:
    """One evaluation stage: regions, pre-Möbius, core, post-Möbius.

    Defaults give the identity. ``pre`` is (q1, s1, k1) and ``post`` is
    (s2, k2, q2), see the module docstring.
    """

    pre: tuple = (0j, 0j, 1 + 0j)
    lam: tuple = (1 + 0j, 0j, 0j)
    post: tuple = (0j, 1 + 0j, 0j)
    core: int = CORE_AFFINE
    centers: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    weights: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    regions: tuple = ()
    newton_iters: int = 0
    newton_tol: float = 0.0


def _put(row, *values):
    flat = []
    for v in values:
        v = complex(v)
        flat += [v.real, v.imag]
    row[: len(flat)] = flat


def pack(stages):
    """Pack a list of :class:`Stage` into the float32 block, shape (rows, 4)."""
    stages = list(stages)
    if not 1 <= len(stages) <= MAX_STAGES:
        raise ValueError(f"a map packs into 1 to {MAX_STAGES} stages, this one needs {len(stages)}")
    block = np.zeros((1 + len(stages) * STAGE_ROWS, 4), dtype=np.float64)
    block[0, :2] = (len(stages), LAYOUT_VERSION)
    for k, st in enumerate(stages):
        rows = block[1 + k * STAGE_ROWS : 1 + (k + 1) * STAGE_ROWS]
        n = len(st.centers)
        if n > MAX_CENTERS:
            raise ValueError(f"at most {MAX_CENTERS} TPS centers, got {n}")
        if len(st.regions) > MAX_REGIONS:
            raise ValueError(f"at most {MAX_REGIONS} regions, got {len(st.regions)}")
        rows[ROW_HEADER] = (st.core, n, len(st.regions), st.newton_iters)
        q1, s1, k1 = st.pre
        s2, k2, q2 = st.post
        l1, l2, l3 = st.lam
        _put(rows[ROW_PRE], q1, s1)
        _put(rows[ROW_SCALE], k1, k2)
        _put(rows[ROW_POST], s2, q2)
        _put(rows[ROW_L12], l1, l2)
        _put(rows[ROW_L3], l3)
        rows[ROW_L3, 2] = st.newton_tol
        mu = RLinear(l1, l2, l3).inverse  # the Newton seed
        _put(rows[ROW_MU12], mu.l1, mu.l2)
        _put(rows[ROW_MU3], mu.l3)
        for r, reg in enumerate(st.regions):
            _put(rows[ROW_REGIONS + 2 * r], reg.origin, reg.normal)
            _put(rows[ROW_REGIONS + 2 * r + 1], reg.a, reg.b)
        for j in range(n):
            _put(rows[ROW_CENTERS + j], st.centers[j], st.weights[j])
    return block.astype(np.float32)


def n_stages(block):
    return int(block[0, 0])


def _c(row, i):
    return complex(row[i], row[i + 1])


def _tps(p, rows, n, dtype):
    """TPS core and its Wirtinger derivatives at p."""
    l1, l2, l3 = _c(rows[ROW_L12], 0), _c(rows[ROW_L12], 2), _c(rows[ROW_L3], 0)
    val = l1 * p + l2 * np.conj(p) + l3
    dz = np.full_like(p, l1)
    dzb = np.full_like(p, l2)
    for j in range(n):
        c, b = _c(rows[ROW_CENTERS + j], 0), _c(rows[ROW_CENTERS + j], 2)
        d = p - c
        r2 = (d.real**2 + d.imag**2).astype(dtype)
        safe = np.where(r2 > 0, r2, 1)
        lg = np.where(r2 > 0, np.log(safe), 0)
        val = val + b * (0.5 * r2 * lg)
        g = 0.5 * b * (lg + 1)
        dz = dz + g * np.conj(d)
        dzb = dzb + g * d
    return val, dz, dzb


def evaluate(block, points, dtype=np.float64):
    """Evaluate a parameter block on (..., 2) points: the reference that
    every kernel mirrors. ``dtype=np.float32`` imitates device precision."""
    cdt = np.complex64 if dtype == np.float32 else np.complex128
    block = np.asarray(block, dtype=dtype)
    pts = np.asarray(points, dtype=dtype)
    z = (pts[..., 0] + 1j * pts[..., 1]).astype(cdt)
    with np.errstate(all="ignore"):
        for k in range(n_stages(block)):
            z = _evaluate_stage(block[1 + k * STAGE_ROWS : 1 + (k + 1) * STAGE_ROWS], z, dtype)
    out = np.empty(z.shape + (2,), dtype=dtype)
    out[..., 0], out[..., 1] = z.real, z.imag
    return out


def _evaluate_stage(rows, z, dtype):
    core, n, n_regions, iters = (int(v) for v in rows[ROW_HEADER])
    best = np.zeros(z.shape, dtype=dtype)
    outside = np.full(z.shape, np.nan + 0j, dtype=z.dtype)
    for r in range(n_regions):
        o, nrm = _c(rows[ROW_REGIONS + 2 * r], 0), _c(rows[ROW_REGIONS + 2 * r], 2)
        a, b = _c(rows[ROW_REGIONS + 2 * r + 1], 0), _c(rows[ROW_REGIONS + 2 * r + 1], 2)
        depth = ((z - o) * np.conj(nrm)).real
        win = depth > best
        best = np.where(win, depth, best)
        outside = np.where(win, a * z + b, outside)
    u = z - _c(rows[ROW_PRE], 0)
    p = _c(rows[ROW_SCALE], 0) * u / (1 - _c(rows[ROW_PRE], 2) * u)
    if core == CORE_AFFINE:
        l1, l2, l3 = _c(rows[ROW_L12], 0), _c(rows[ROW_L12], 2), _c(rows[ROW_L3], 0)
        p = l1 * p + l2 * np.conj(p) + l3
    elif core == CORE_TPS:
        p = _tps(p, rows, n, dtype)[0]
    else:
        p = _newton(p, rows, n, iters, rows[ROW_L3, 2], dtype)
    w = _c(rows[ROW_POST], 2) + _c(rows[ROW_SCALE], 2) * p / (1 - _c(rows[ROW_POST], 0) * p)
    return np.where(best > 0, outside, w)


def _newton(target, rows, n, iters, tol, dtype):
    mu1, mu2, mu3 = _c(rows[ROW_MU12], 0), _c(rows[ROW_MU12], 2), _c(rows[ROW_MU3], 0)
    x = mu1 * target + mu2 * np.conj(target) + mu3
    done = np.zeros(target.shape, dtype=bool)
    for _ in range(iters):
        val, dz, dzb = _tps(x, rows, n, dtype)
        res = val - target
        done = np.abs(res) <= tol
        if done.all():
            break
        det = np.abs(dz) ** 2 - np.abs(dzb) ** 2
        step = (np.conj(dz) * res - dzb * np.conj(res)) / det
        x = np.where(done, x, x - step)
    else:
        val = _tps(x, rows, n, dtype)[0]
        done = np.abs(val - target) <= tol
    return np.where(done, x, np.nan)
