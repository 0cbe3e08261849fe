"""Thin-plate splines of the complex plane and their Newton inverse (paper eq. 13-14).

phi(p) = sum_j b_j U(|p - c_j|) + l1 p + l2 conj(p) + l3,  U(r) = r² log r,

with complex centers c_j and weights b_j. Fitting to constraints
phi(c_j) = d_j solves the usual (J + 3) × (J + 3) real system once, with
the real and imaginary parts of d as two right-hand sides. The side
conditions sum b_j = sum b_j x_j = sum b_j y_j = 0 make phi affine plus
O(log |p|) far away, so Newton's method seeded with the inverse of the
affine part converges quickly wherever phi is close to affine.

Wirtinger derivatives of one term, with d = p - c and r² = |d|²:
d/dp [½ r² log r²] = ½ (log r² + 1) conj(d), d/dconj(p) = ½ (log r² + 1) d,
exactly what the block's TPS cores (:func:`fpiwarp.block.reference.tps_core`) evaluate on the device.
"""

import numpy as np
from numpy.typing import ArrayLike

from ..block import (
    CORE_TPS,
    CORE_TPS_INVERSE,
    CORE_TPS_PAIRS,
    CORE_TPS_PAIRS_INVERSE,
    MAX_CENTERS,
    SEED_N,
    LinearPart,
    SeedTable,
    Stage,
    rlinear_inverse,
)
from ..errors import ArgumentError, InverseNotConvergedError
from .rlinear import RLinear
from .transform import Transform, unsolved_are_nan, unsolved_as_nan


# --- A thin-plate spline's centers as pairs for the block's paired TPS cores.
def paired_fields(centers, weights, partner):
    """(c, W, d, b2), complex arrays with one entry per pair, or None when
    the pairs do not fit the block (2 rows each, MAX_CENTERS rows).

    ``partner[i]``: the index of the center that center i is the offset
    copy of, -1 for the others (each a pair's first center). A center
    with several offset copies (a shared corner of adjacent constrained
    edges) heads one pair per copy and its weight is split among them in
    proportion to the copies' weights, so each W stays of the order of
    the sum of the group's weights; one without copies is a pair with
    d = 0 and b2 = 0.
    """
    centers = np.asarray(centers, dtype=np.complex128)
    weights = np.asarray(weights, dtype=np.complex128)
    partner = np.asarray(partner, dtype=int)
    c, w, d, b2 = [], [], [], []
    for a in np.flatnonzero(partner < 0):
        copies = np.flatnonzero(partner == a)
        if copies.size == 0:
            c.append(centers[a]), w.append(weights[a]), d.append(0j), b2.append(0j)
            continue
        total, spread = weights[a] + weights[copies].sum(), weights[copies].sum()
        for o in copies:
            share = weights[o] / spread if spread != 0 else 1.0 / copies.size
            c.append(centers[a]), w.append(total * share), d.append(centers[o] - centers[a]), b2.append(weights[o])
    if 2 * len(c) > MAX_CENTERS:
        return None
    return tuple(np.array(v, dtype=np.complex128) for v in (c, w, d, b2))


# --- The device Newton's seed table (block rows ``ROW_SEED``, see
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


# --- Thin-plate splines of the complex plane and their Newton inverse (paper eq. 13-14).
#: Points evaluated per chunk (bounds the (chunk, centers) work arrays,
#: small enough to stay in cache).
CHUNK = 1 << 12
#: Centers per (points, 3) @ (3, centers) product in _terms: OpenBLAS takes
#: its threaded matrix-matrix path from 48 columns on, measured 0.08 ms for
#: 44 columns and 8-10 ms for 48 to 64 (4096 points, two busy cores).
MATMUL_COLUMNS = 32
#: Points per Newton batch (its per-iteration bookkeeping is per batch).
NEWTON_CHUNK = 1 << 17
#: Host Newton: aim for |phi(x) - p| <= HOST_AIM * max(scale, |p - mid|) and
#: raise InverseNotConvergedError where even HOST_RTOL is not reached.
HOST_AIM = 1e-13
HOST_RTOL = 1e-9
HOST_MAX_ITERS = 60
#: Where Newton from the affine seed fails (the seed can sit in a fold of
#: phi just outside the region, where Newton stalls at a local minimum of
#: the residual), it restarts from the SEEDS points of a SEED_GRID² grid
#: over the centers whose images lie nearest the target.
SEED_GRID = 48
SEEDS = 6
#: Device Newton (float32): iterations and tolerance, in units of the
#: spline's scale (the radius of its targets, 1 in parallelogram
#: coordinates). float32 evaluation of a 40-center spline there carries
#: up to ~1e-5 of rounding noise (measured: 2e-6 to 2e-5 for moderate
#: deformations), so 5e-5 is reached reliably. Newton converges
#: quadratically, so the last step usually lands at the noise floor; the
#: worst case, 5e-5 of the region's radius, is 0.05 px for a region 2000 px
#: across.
DEVICE_RTOL = 5e-5
DEVICE_ITERS = 12


def _kernel_terms(p, centers):
    """r² and ½ (log r² + 1) for every (point, center) pair; U = ½ r² log r²."""
    d = p[:, None] - centers[None, :]
    r2 = d.real**2 + d.imag**2
    pos = r2 > 0
    lg = np.log(np.where(pos, r2, 1.0))
    return d, r2, lg


class ThinPlateSpline(Transform):
    """``phi(p) = sum_j b_j U(|p - c_j|) + l1 p + l2 conj(p) + l3``, ``U(r) = r² log r``.

    Build it with :meth:`fit` from centers and targets (complex or (J, 2)),
    or directly from ``centers``, ``weights`` and the R-linear part
    ``lam = (l1, l2, l3)``. The map is smooth everywhere; ``inverse`` is
    numerical (Newton), see :class:`InverseThinPlateSpline`.

    >>> tps = ThinPlateSpline.fit([0, 1, 1j, 1 + 1j, 0.5 + 0.5j],
    ...                           [0, 1, 1j, 1 + 1j, 0.6 + 0.5j])
    >>> (np.round(tps([[0.5, 0.5], [1.0, 0.0]]), 12) + 0.0).tolist()  # + 0.0: no -0.0
    [[0.6, 0.5], [1.0, 0.0]]
    >>> ThinPlateSpline.fit([0, 1, 2], [0, 1, 2])
    Traceback (most recent call last):
    ...
    fpiwarp.ArgumentError: thin-plate spline centers are collinear or coincide: the fit is singular
    """

    def __init__(self, centers: ArrayLike, weights: ArrayLike, lam: tuple[complex, complex, complex]):
        self.centers = np.asarray(centers, dtype=np.complex128).reshape(-1)
        self.weights = np.asarray(weights, dtype=np.complex128).reshape(-1)
        if self.centers.shape != self.weights.shape:
            raise ArgumentError("one weight per center is needed")
        if len(self.centers) > MAX_CENTERS:
            raise ArgumentError(
                f"a thin-plate spline packs at most {MAX_CENTERS} centers, got {len(self.centers)}"
            )
        self.l1, self.l2, self.l3 = (complex(v) for v in lam)
        #: None, or per center the index of the center it is the offset copy
        #: of (-1: none): then the block stores the centers as pairs
        #: (``fpiwarp.maps.thin_plate_spline``), which float32 evaluates exactly
        self.partner = None
        if abs(abs(self.l1) - abs(self.l2)) <= 1e-14 * (abs(self.l1) + abs(self.l2)):
            raise ArgumentError("singular affine part of the thin-plate spline: |l1| == |l2|")

    @classmethod
    def fit(cls, centers, targets):
        """The interpolating spline with phi(c_j) = d_j of least bending energy."""
        c = _as_complex_1d(centers, "centers")
        d = _as_complex_1d(targets, "targets")
        if c.shape != d.shape:
            raise ArgumentError(f"need one target per center, got {c.shape[0]} and {d.shape[0]}")
        n = len(c)
        if n < 3:
            raise ArgumentError(f"a thin-plate spline needs at least 3 centers, got {n}")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(d))):
            raise ArgumentError("thin-plate spline centers and targets must be finite")
        # Solve in coordinates centered and scaled by the data: same spline
        # (the TPS is similarity invariant), better conditioned system.
        mid = c.mean()
        scale = float(np.max(np.abs(c - mid))) or 1.0
        cs = (c - mid) / scale
        _, r2, lg = _kernel_terms(cs, cs)
        a = np.zeros((n + 3, n + 3))
        a[:n, :n] = 0.5 * r2 * lg
        a[:n, n] = a[n, :n] = 1.0
        a[:n, n + 1] = a[n + 1, :n] = cs.real
        a[:n, n + 2] = a[n + 2, :n] = cs.imag
        rhs = np.zeros((n + 3, 2))
        rhs[:n, 0], rhs[:n, 1] = d.real, d.imag
        close = r2[~np.eye(n, dtype=bool)]
        if close.size and close.min() <= 1e-24:
            raise ArgumentError("thin-plate spline centers repeat: the fit is singular")
        if np.linalg.matrix_rank(a[:n, n:], tol=1e-9) < 3:
            raise ArgumentError("thin-plate spline centers are collinear or coincide: the fit is singular")
        try:
            sol = np.linalg.solve(a, rhs)
        except np.linalg.LinAlgError:
            sol = None
        if sol is None or not np.all(np.isfinite(sol)):
            raise ArgumentError("thin-plate spline system is singular (repeated centers?)")
        coef = sol[:, 0] + 1j * sol[:, 1]
        b, a0, ax, ay = coef[:n], coef[n], coef[n + 1], coef[n + 2]
        # In scaled coordinates s = (p - mid) / scale: U(|s - cs|) =
        # (U(|p - c|) - r² log(scale)) / scale², and the r² terms sum to a
        # constant under the side conditions: fold it into l3.
        weights = b / scale**2
        l1s, l2s = 0.5 * (ax - 1j * ay), 0.5 * (ax + 1j * ay)
        l1, l2 = l1s / scale, l2s / scale
        l3 = a0 - l1 * mid - l2 * np.conj(mid)
        tps = cls(c, weights, (l1, l2, l3))
        # exact constant: make phi(c) match d on average (absorbs the log(scale) term)
        tps.l3 += complex(np.mean(d - tps.map_complex(c)))
        return tps

    @property
    def lam(self):
        return (self.l1, self.l2, self.l3)

    def _prepare(self):
        """Real matrices that turn the sums over centers into matmuls."""
        c, b = self.centers, self.weights
        # r² = |p|² + |c|² - 2 (x xc + y yc) = [x, y, 1] @ cmat + |p|²
        self._cmat = np.stack([-2 * c.real, -2 * c.imag, np.abs(c) ** 2])
        # weights as rows, applied one matrix-vector product each: for a
        # handful of columns OpenBLAS's threaded matrix-matrix path is up to
        # 20x slower than gemv when threads compete for cores
        self._wval = np.stack([b.real, b.imag])
        bcc, bc = b * np.conj(c), b * c
        self._wder = np.stack([b.real, b.imag, bcc.real, bcc.imag, bc.real, bc.imag])
        self._sums = (b.sum(), bcc.sum(), bc.sum())

    def _terms(self, p):
        """U = ½ r² log r² and L = log r² for every (point, center) pair."""
        if not hasattr(self, "_cmat"):
            self._prepare()
        xy1 = np.stack([p.real, p.imag, np.ones(p.shape)], axis=1)
        cols = self._cmat.shape[1]
        if cols <= MATMUL_COLUMNS:
            r2 = xy1 @ self._cmat
        else:  # same numbers, column blocks: OpenBLAS's threaded path is ~100x slower for 48+
            r2 = np.concatenate([xy1 @ self._cmat[:, s : s + MATMUL_COLUMNS] for s in range(0, cols, MATMUL_COLUMNS)],
                                axis=1)
        r2 += (p.real**2 + p.imag**2)[:, None]
        np.maximum(r2, 1e-300, out=r2)  # rounding can make it slightly negative at a center
        lg = np.log(r2)
        return r2, lg

    def _value(self, p, r2, lg):
        """phi(p) from the pair terms of _terms (r2 is not modified)."""
        u = [(r2 * lg) @ v for v in self._wval]
        return self.l1 * p + self.l2 * np.conj(p) + self.l3 + 0.5 * (u[0] + 1j * u[1])

    def _map(self, z):
        z = np.asarray(z, dtype=np.complex128)
        flat = z.reshape(-1)
        out = np.empty_like(flat)
        for s in range(0, flat.size, CHUNK):
            p = flat[s : s + CHUNK]
            out[s : s + CHUNK] = self._value(p, *self._terms(p))
        return out.reshape(z.shape)

    def _wirtinger(self, z):
        z = np.asarray(z, dtype=np.complex128)
        flat = z.reshape(-1)
        val = np.empty_like(flat)
        fz = np.empty_like(flat)
        fzb = np.empty_like(flat)
        for s in range(0, flat.size, CHUNK):
            p = flat[s : s + CHUNK]
            r2, lg = self._terms(p)
            val[s : s + CHUNK] = self._value(p, r2, lg)
            # sum_j ½ (L_j + 1) b_j conj(p - c_j), and the same with (p - c_j)
            g = [lg @ v for v in self._wder]
            sb, sbcc, sbc = self._sums
            gb = g[0] + 1j * g[1] + sb
            gbcc = g[2] + 1j * g[3] + sbcc
            gbc = g[4] + 1j * g[5] + sbc
            fz[s : s + CHUNK] = self.l1 + 0.5 * (np.conj(p) * gb - gbcc)
            fzb[s : s + CHUNK] = self.l2 + 0.5 * (p * gb - gbc)
        return val.reshape(z.shape), fz.reshape(z.shape), fzb.reshape(z.shape)

    @property
    def affine_inverse(self):
        """(mu1, mu2, mu3): the inverse of the R-linear part, the Newton seed."""
        mu = RLinear(self.l1, self.l2, self.l3).inverse
        return mu.l1, mu.l2, mu.l3

    @property
    def inverse(self):
        return InverseThinPlateSpline(self)

    def conjugated(self) -> "ThinPlateSpline":
        """p -> conj(phi(conj p)): the same spline in the mirrored plane."""
        out = ThinPlateSpline(
            np.conj(self.centers), np.conj(self.weights), tuple(np.conj(v) for v in self.lam)
        )
        out.partner = self.partner
        return out

    def block_terms(self, inverse: bool = False) -> tuple[int, dict]:
        """The core number and Stage fields of the spline's terms: paired
        (``CORE_TPS_PAIRS``) where :attr:`partner` is set and the pairs fit
        the block, else plain (``CORE_TPS``); the Newton inverse's cores
        with ``inverse``."""
        pairs = None if self.partner is None else paired_fields(self.centers, self.weights, self.partner)
        if pairs is None:
            return (CORE_TPS_INVERSE if inverse else CORE_TPS), {"centers": self.centers, "weights": self.weights}
        c, w, d, b2 = pairs
        core = CORE_TPS_PAIRS_INVERSE if inverse else CORE_TPS_PAIRS
        return core, {"centers": c, "weights": w, "offsets": d, "offset_weights": b2}

    def stage(self, **kw) -> Stage:
        """The parameter-block stage of this spline (extra Stage fields in ``kw``)."""
        core, terms = self.block_terms()
        return Stage(core=core, linear=LinearPart(*self.lam), **terms, **kw)

    def stages(self) -> list[Stage]:
        return [self.stage()]

    def __repr__(self):
        return f"ThinPlateSpline(<{len(self.centers)} centers>, lam={self.lam!r})"


class InverseThinPlateSpline(Transform):
    """phi⁻¹ by Newton's method, seeded with the inverse of phi's affine part
    plus the bilinear correction of a table of exact inverses (devices; the
    host for large point sets: :mod:`fpiwarp.maps.thin_plate_spline`).

    On the host the iteration (with step halving when a step does not
    reduce the residual) aims at |phi(x) - p| <= 1e-13 · max(scale,
    |p - mid|) (scale: radius of the spline's targets, mid: their mean),
    accepts 1e-9 where rounding stops it earlier, and raises
    :class:`~fpiwarp.InverseNotConvergedError` naming how many points
    failed otherwise. Where the affine seed fails (it can sit in a fold of
    phi just outside the region, where Newton stalls), Newton restarts from
    the grid points with the shortest first step; the answer always solves
    phi(x) = p, but where phi is not one-to-one (it folds outside the
    region and the fold's image overlaps the region's) it can be a
    preimage outside the region. Non-finite
    inputs (the image of a pole) give non-finite outputs.

    On the device (``CORE_TPS_INVERSE``) plain Newton from that seed runs at most
    ``DEVICE_ITERS`` steps to the float32-sane tolerance ``DEVICE_RTOL ·
    scale``; points that do not get there come out NaN, i.e. "outside".
    """

    #: Optional, set by ConstrainedFPI: an object whose ``wants(target)`` says
    #: which targets have a preimage in the region and ``holds(x)`` which
    #: points lie in it; an answer outside the region for a target that
    #: wants one inside is solved again from grid seeds inside the region.
    region = None

    def __init__(self, tps):
        self.tps = tps
        t = tps.map_complex(tps.centers)
        self.mid = complex(np.mean(t))
        self.scale = float(np.max(np.abs(t - self.mid))) or 1.0

    def _map(self, p):
        p = np.asarray(p, dtype=np.complex128)
        flat = p.reshape(-1)
        out = np.full(flat.shape, np.nan + 0j)
        ok = np.isfinite(flat)
        out[~ok] = flat[~ok]  # the pole's image stays at infinity
        idx = np.flatnonzero(ok)
        for s in range(0, idx.size, NEWTON_CHUNK):
            sel = idx[s : s + NEWTON_CHUNK]
            out[sel] = self._solve(flat[sel])
        return out.reshape(p.shape)

    def _solve(self, target):
        size = np.maximum(self.scale, np.abs(target - self.mid))
        tol = HOST_AIM * size
        x, err = self._newton(host_seed(self, target), target, tol)
        bad = ~(err <= HOST_RTOL * size)
        if bad.any():  # the affine seed can sit in a fold outside the region: seed again
            idx = np.flatnonzero(bad)
            x[idx], err[idx] = self._reseed(target[idx], tol[idx], x[idx], err[idx])
            bad = ~(err <= HOST_RTOL * size)
        if self.region is not None:  # phi may not be one-to-one: prefer the region's preimage
            idx = np.flatnonzero(bad)
            done = np.flatnonzero(~bad)
            idx = np.union1d(idx, done[~self.region.holds(x[done])])
            idx = idx[self.region.wants(target[idx])]
            if idx.size:
                x[idx], err[idx] = self._reseed(target[idx], tol[idx], x[idx], err[idx], inside=True)
                bad = ~(err <= HOST_RTOL * size)
        if bad.any() and unsolved_are_nan():
            x[bad] = np.nan
        elif bad.any():
            first = target[np.flatnonzero(bad)[0]]
            raise InverseNotConvergedError(
                f"Newton inverse of the thin-plate spline did not converge for {int(bad.sum())} "
                f"of {target.size} points (first at spline coordinate {first:.6g}, residual "
                f"{float(err[bad].max()):.3g}): the map is not invertible there "
                "(fold-over or far outside its region)"
            )
        return x

    def _newton(self, x, target, tol):
        """Damped Newton from seeds x towards phi(x) = target: (x, |phi(x) - target|)."""
        tps = self.tps
        x = np.array(x, dtype=np.complex128)
        val, fz, fzb = tps.wirtinger(x)
        res = val - target
        err = np.abs(res)
        active = np.flatnonzero(err > tol)
        for _ in range(HOST_MAX_ITERS):
            if active.size == 0:
                break
            a_fz, a_fzb, a_res = fz[active], fzb[active], res[active]
            det = np.abs(a_fz) ** 2 - np.abs(a_fzb) ** 2
            step = (np.conj(a_fz) * a_res - a_fzb * np.conj(a_res)) / det
            step = np.where(np.isfinite(step), step, 0)
            t = np.ones(active.size)
            for _half in range(8):  # backtracking: accept the first step that helps
                trial = x[active] - t * step
                v2, fz2, fzb2 = tps.wirtinger(trial)
                r2 = v2 - target[active]
                better = np.abs(r2) < err[active]
                if better.all():
                    break
                t = np.where(better, t, 0.5 * t)
            x[active] = np.where(better, trial, x[active])
            val[active] = np.where(better, v2, val[active])
            fz[active] = np.where(better, fz2, fz[active])
            fzb[active] = np.where(better, fzb2, fzb[active])
            res[active] = np.where(better, r2, res[active])
            err[active] = np.abs(res[active])
            # points no step improves have reached their rounding floor
            active = active[(err[active] > tol[active]) & better]
        return x, err

    def _seed_grid(self):
        """A SEED_GRID² grid over the centers' box, grown by half its size, where
        phi's Jacobian is positive: (points, images, fz, fzb, det), cached."""
        if not hasattr(self, "_grid"):
            c = self.tps.centers
            lo, hi = complex(c.real.min(), c.imag.min()), complex(c.real.max(), c.imag.max())
            pad = 0.5 * max(hi.real - lo.real, hi.imag - lo.imag, 1e-300)
            xs = np.linspace(lo.real - pad, hi.real + pad, SEED_GRID)
            ys = np.linspace(lo.imag - pad, hi.imag + pad, SEED_GRID)
            g = (xs[None, :] + 1j * ys[:, None]).ravel()
            val, fz, fzb = self.tps.wirtinger(g)
            det = np.abs(fz) ** 2 - np.abs(fzb) ** 2
            keep = (det > 0) & np.isfinite(val)
            self._grid = (g[keep], val[keep], fz[keep], fzb[keep], det[keep])
        return self._grid

    def _reseed(self, target, tol, x, err, inside=False):
        """Newton again from the SEEDS grid points whose first Newton step
        towards each target is shortest (not those whose images lie nearest:
        where phi compresses strongly, far points map near the target); the
        solution from the best seed that converges wins, else (x, err) stay;
        they stay too where two seeds find different preimages."""
        g, img, fz, fzb, det = self._seed_grid()
        if inside:  # only seeds in the region, only answers in it
            keep = self.region.holds(g)
            g, img, fz, fzb, det = g[keep], img[keep], fz[keep], fzb[keep], det[keep]
        k = min(SEEDS * (3 if inside else 1), g.size)
        if k == 0:
            return x, err
        rows_per = max(1, CHUNK // g.size)
        for s in range(0, target.size, rows_per):
            sl = slice(s, s + rows_per)
            r = img[None, :] - target[sl, None]
            step = np.abs((np.conj(fz) * r - fzb * np.conj(r)) / det)
            near = np.argsort(step, axis=1)[:, :k]
            xs, es = self._newton(g[near].ravel(), np.repeat(target[sl], k), np.repeat(tol[sl], k))
            xs, es = xs.reshape(-1, k), es.reshape(-1, k)
            ok = es <= (HOST_RTOL / HOST_AIM) * tol[sl, None]
            if inside:
                ok &= self.region.holds(xs.ravel()).reshape(xs.shape)
            first = np.argmax(ok, axis=1)
            pick = xs[np.arange(len(xs)), first]
            # two different preimages: phi is not one-to-one there, refuse to guess
            same = np.where(ok, np.abs(xs - pick[:, None]), 0).max(axis=1) <= 1e-6 * self.scale
            rows = np.flatnonzero(ok.any(axis=1) & same)
            x[sl][rows] = xs[rows, first[rows]]
            err[sl][rows] = es[rows, first[rows]]
        return x, err

    def _wirtinger(self, p):
        x = self._map(p)
        _, fz, fzb = self.tps.wirtinger(x)
        det = np.abs(fz) ** 2 - np.abs(fzb) ** 2
        return x, np.conj(fz) / det, -fzb / det

    @property
    def inverse(self):
        return self.tps

    def stage(self, **kw) -> Stage:
        t = self.tps
        core, terms = t.block_terms(inverse=True)
        return Stage(
            core=core,
            linear=LinearPart(*t.lam),
            **terms,
            newton_iters=DEVICE_ITERS, newton_tol=DEVICE_RTOL * self.scale, seed=cached_seed_table(self),
            **kw,
        )

    def stages(self) -> list[Stage]:
        return [self.stage()]

    def __repr__(self):
        return f"InverseThinPlateSpline({self.tps!r})"


def _as_complex_1d(values, name):
    arr = np.asarray(values)
    if np.iscomplexobj(arr):
        return arr.astype(np.complex128).reshape(-1)
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim == 1:
        return arr.astype(np.complex128)
    if arr.ndim != 2 or arr.shape[-1] != 2:
        raise ArgumentError(f"{name} must be complex (J,) or (x, y) pairs (J, 2), got shape {arr.shape}")
    return arr[:, 0] + 1j * arr[:, 1]
