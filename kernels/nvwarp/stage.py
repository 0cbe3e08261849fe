"""The map in NVIDIA Warp: one stage walk for every kernel.

Mirrors :func:`fpiwarp.block.reference.evaluate` line by line (regions,
pre-Möbius, core, post-Möbius, stage after stage) and, where asked,
:mod:`fpiwarp.block.jacobian` (each stage's Wirtinger derivatives chained
stage after stage). Complex numbers are ``wp.vec2`` (re, im) in float32.

:func:`stage` is the one stage function: its ``core`` and ``n_regions``
come from the stage's header (:func:`walk`, kernels of any kind of map) or
are constants of a kernel made for one kind of map
(:mod:`fpiwarp.kernels.nvwarp.factory` passes them through ``wp.static``),
where the compiler drops the branches and the region loop that kind does
not use; ``deriv`` (a constant of each kernel) adds the derivatives
(antialiasing) or leaves them out (one value per point). The numbers of
TPS centers and Newton steps are always read from the block, so maps of
one kind but another number of centers share a kernel.

Accumulators start as ``float(0.0)``: Warp treats a bare literal as a
constant that loops and branches may not reassign.
"""

import warp as wp

from .contract import (
    CORE_AFFINE,
    CORE_TPS,
    CORE_TPS_INVERSE,
    CORE_TPS_PAIRS,
    CORE_TPS_PAIRS_INVERSE,
    ROW_CENTERS,
    ROW_HEADER,
    ROW_L3,
    ROW_L12,
    ROW_MU3,
    ROW_MU12,
    ROW_POST,
    ROW_PRE,
    ROW_REGIONS,
    ROW_SCALE,
    ROW_SEED,
    ROW_SEED_GRID,
    SEED_N,
    STAGE_ROWS,
)

# Forward evaluation only: no adjoint code, which halves the compile time.
wp.set_module_options({"enable_backward": False})

# --- complex arithmetic on vec2 ---------------------------------------------


@wp.func
def cmul(a: wp.vec2, b: wp.vec2):
    return wp.vec2(a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0])


@wp.func
def cdiv(a: wp.vec2, b: wp.vec2):
    inv = 1.0 / (b[0] * b[0] + b[1] * b[1])
    return wp.vec2((a[0] * b[0] + a[1] * b[1]) * inv, (a[1] * b[0] - a[0] * b[1]) * inv)


@wp.func
def conj(a: wp.vec2):
    return wp.vec2(a[0], -a[1])


@wp.func
def lo(row: wp.vec4):
    """The complex number in a row's first two floats."""
    return wp.vec2(row[0], row[1])


@wp.func
def hi(row: wp.vec4):
    """The complex number in a row's last two floats."""
    return wp.vec2(row[2], row[3])


@wp.func
def abs2(a: wp.vec2):
    return a[0] * a[0] + a[1] * a[1]


# --- TPS cores, their seed and Newton inverse (fpiwarp.block.reference) -----


@wp.func
def log0(v: float):
    """log v, 0 where v == 0 (a TPS term vanishes at its center)."""
    lg = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
    if v > 0.0:
        lg = wp.log(v)
    return lg


@wp.func
def tps_pairs_sum(blk: wp.array(dtype=wp.vec4), s0: int, n: int, p: wp.vec2, deriv: bool):
    """The paired TPS terms at p and, with ``deriv``, their Wirtinger
    derivatives (fpiwarp.block.tps_pairs.tps_pairs_core): n center rows,
    n / 2 pairs (without: zero derivatives, the value alone)."""
    val = wp.vec2(0.0, 0.0)
    dz = wp.vec2(0.0, 0.0)
    dzb = wp.vec2(0.0, 0.0)
    for jj in range(n // 2):
        r1 = blk[s0 + ROW_CENTERS + 2 * jj]
        r2 = blk[s0 + ROW_CENTERS + 2 * jj + 1]
        w = hi(r1)
        d = lo(r2)
        b2 = hi(r2)
        q = p - lo(r1)
        q2 = q - d
        a = abs2(q)
        b = abs2(q2)
        e = abs2(d) - 2.0 * (q[0] * d[0] + q[1] * d[1])
        s = b
        m = a
        qn = q2
        if a <= b:
            s = a
            m = b
            qn = q
        # fpiwarp.block.tps_pairs.pair_logs: log(max) from the series where it holds
        ae = wp.abs(e)
        ls = log0(s)
        lm = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
        mag = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
        if s > 0.0 and ae <= 0.25 * s:
            t = ae / (2.0 * s + ae)
            t2 = t * t
            mag = 2.0 * t * (1.0 + t2 * (0.33333333 + t2 * (0.2 + t2 * 0.14285714)))
            lm = ls + mag
        else:
            lm = log0(m)
            mag = lm - ls
        big_l = mag
        if e < 0.0:
            big_l = -mag
        la = lm
        if a <= b:
            la = ls
        val = val + w * (0.5 * a * la) + b2 * (0.5 * (e * lm + s * big_l))
        if deriv:
            g1 = 0.5 * (la + 1.0)
            gn = 0.5 * (lm + 1.0)  # g(b) where a <= b, else g(a)
            dz = dz + cmul(w, conj(q) * g1) + cmul(b2, conj(qn) * (0.5 * big_l) - conj(d) * gn)
            dzb = dzb + cmul(w, q * g1) + cmul(b2, qn * (0.5 * big_l) - d * gn)
    return val, dz, dzb


@wp.func
def tps_core(blk: wp.array(dtype=wp.vec4), s0: int, n: int, p: wp.vec2, paired: bool, deriv: bool):
    """TPS core at p: sum_j b_j r² log r + l1 p + l2 conj(p) + l3
    (``paired``: the paired terms) and, with ``deriv``, its Wirtinger
    derivatives f_z, f_zbar (without: l1, l2, the value alone)."""
    l1 = lo(blk[s0 + ROW_L12])
    l2 = hi(blk[s0 + ROW_L12])
    l3 = lo(blk[s0 + ROW_L3])
    val = cmul(l1, p) + cmul(l2, conj(p)) + l3
    dz = l1
    dzb = l2
    if paired:
        pv, pdz, pdzb = tps_pairs_sum(blk, s0, n, p, deriv)
        return val + pv, dz + pdz, dzb + pdzb
    for j in range(n):
        row = blk[s0 + ROW_CENTERS + j]
        b = hi(row)
        d = p - lo(row)
        r2 = abs2(d)
        lg = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
        if r2 > 0.0:
            lg = wp.log(r2)
        val = val + b * (0.5 * r2 * lg)
        if deriv:
            g = b * (0.5 * (lg + 1.0))
            dz = dz + cmul(g, conj(d))
            dzb = dzb + cmul(g, d)
    return val, dz, dzb


@wp.func
def tps_miss(blk: wp.array(dtype=wp.vec4), s0: int, n: int, x: wp.vec2, paired: bool, target: wp.vec2):
    """|TPS(x) - target|, the value alone."""
    val, dz, dzb = tps_core(blk, s0, n, x, paired, False)
    return wp.sqrt(abs2(val - target))


@wp.func
def seed_axis(v: float, lo: float, g: float):
    """One axis of the seed table (fpiwarp.block.reference.seed_correction):
    the cell of the clamped node coordinate (NaN: 0) and the fraction."""
    f = (v - lo) * g
    if f > 0.0:
        f = wp.min(f, float(SEED_N - 1))
    else:
        f = 0.0
    i = wp.min(int(f), SEED_N - 2)
    return i, f - float(i)


@wp.func
def seed_node(blk: wp.array(dtype=wp.vec4), s0: int, k: int):
    """Correction k of the seed table."""
    r = blk[s0 + ROW_SEED_GRID + k // 2]
    if k % 2 == 0:
        return lo(r)
    return hi(r)


@wp.func
def seed_correction(blk: wp.array(dtype=wp.vec4), s0: int, t: wp.vec2):
    """The seed table's bilinear correction at t, added to the R-linear seed."""
    box = blk[s0 + ROW_SEED]
    i, tx = seed_axis(t[0], box[0], box[2])
    j, ty = seed_axis(t[1], box[1], box[3])
    k = j * SEED_N + i
    c00 = seed_node(blk, s0, k)
    c01 = seed_node(blk, s0, k + 1)
    c10 = seed_node(blk, s0, k + SEED_N)
    c11 = seed_node(blk, s0, k + SEED_N + 1)
    bottom = c00 + (c01 - c00) * tx
    top = c10 + (c11 - c10) * tx
    return bottom + (top - bottom) * ty


@wp.func
def tps_newton_from(blk: wp.array(dtype=wp.vec4), s0: int, n: int, iters: int, target: wp.vec2, paired: bool,
                    x: wp.vec2):
    """Newton's iterates for TPS(x) = target from ``x``: x once within
    newton_tol, NaN when not after ``iters`` steps."""
    tol = blk[s0 + ROW_L3][2]
    nan2 = wp.vec2(wp.nan, wp.nan)
    for k in range(iters):
        # the seed is rarely within tol: its pass takes the derivatives at
        # once; a later pass checks the value first and takes them only for
        # a point that goes on (the same iterates, fewer terms)
        if k > 0:
            if tps_miss(blk, s0, n, x, paired, target) <= tol:
                return x
        val, dz, dzb = tps_core(blk, s0, n, x, paired, True)
        res = val - target
        if k == 0 and wp.sqrt(abs2(res)) <= tol:
            return x
        det = abs2(dz) - abs2(dzb)
        step = (cmul(conj(dz), res) - cmul(dzb, conj(res))) / det
        x = x - step
    if tps_miss(blk, s0, n, x, paired, target) <= tol:
        return x
    return nan2


@wp.func
def tps_newton(blk: wp.array(dtype=wp.vec4), s0: int, n: int, iters: int, target: wp.vec2, paired: bool):
    """Solve TPS(x) = target by Newton from the inverse of the R-linear part
    plus the seed table's correction, and where that fails and the
    correction is not 0, from the R-linear inverse alone (the reference's
    restart); NaN when neither ends within newton_tol after ``iters`` steps."""
    mu1 = lo(blk[s0 + ROW_MU12])
    mu2 = hi(blk[s0 + ROW_MU12])
    mu3 = lo(blk[s0 + ROW_MU3])
    start = cmul(mu1, target) + cmul(mu2, conj(target)) + mu3
    correction = seed_correction(blk, s0, target)
    x = tps_newton_from(blk, s0, n, iters, target, paired, start + correction)
    if wp.isnan(x[0]) and (correction[0] != 0.0 or correction[1] != 0.0):
        x = tps_newton_from(blk, s0, n, iters, target, paired, start)
    return x


# --- one stage, and the walk over a block's stages ---------------------------


@wp.func
def chain_dz(gw: wp.vec2, gwb: wp.vec2, dz: wp.vec2, dzb: wp.vec2):
    """(g o f)_z from g's derivatives and f's (jacobian.chain)."""
    return cmul(gw, dz) + cmul(gwb, conj(dzb))


@wp.func
def chain_dzb(gw: wp.vec2, gwb: wp.vec2, dz: wp.vec2, dzb: wp.vec2):
    """(g o f)_zbar from g's derivatives and f's (jacobian.chain)."""
    return cmul(gw, dzb) + cmul(gwb, conj(dz))


@wp.func
def stage(blk: wp.array(dtype=wp.vec4), s0: int, z: wp.vec2, core: int, n_regions: int, deriv: bool):
    """The stage at block row s0 on z: regions, pre-Möbius, core,
    post-Möbius (reference.evaluate_stage). Returns (w, g_z, g_zbar): with
    ``deriv`` the stage's Wirtinger derivatives (jacobian.stage_wirtinger),
    else zeros. A core this function does not know gives NaN ("outside";
    the host refuses such a block first)."""
    hdr = blk[s0 + ROW_HEADER]
    n = int(hdr[1])
    iters = int(hdr[3])
    zero = wp.vec2(0.0, 0.0)
    best = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
    outside = wp.vec2(wp.nan, wp.nan)
    outside_dz = wp.vec2(wp.nan, wp.nan)
    for r in range(n_regions):
        line = blk[s0 + ROW_REGIONS + 2 * r]
        sim = blk[s0 + ROW_REGIONS + 2 * r + 1]
        d = z - lo(line)
        nrm = hi(line)
        depth = d[0] * nrm[0] + d[1] * nrm[1]
        if depth > best:
            best = depth
            outside = cmul(lo(sim), z) + hi(sim)
            outside_dz = lo(sim)
    if best > 0.0:
        return outside, outside_dz, zero
    u = z - lo(blk[s0 + ROW_PRE])
    den = wp.vec2(1.0, 0.0) - cmul(hi(blk[s0 + ROW_PRE]), u)
    k1 = lo(blk[s0 + ROW_SCALE])
    p = cdiv(cmul(k1, u), den)
    dz = zero
    dzb = zero
    if deriv:
        dz = cdiv(k1, cmul(den, den))
    if core == CORE_AFFINE:
        l1 = lo(blk[s0 + ROW_L12])
        l2 = hi(blk[s0 + ROW_L12])
        p = cmul(l1, p) + cmul(l2, conj(p)) + lo(blk[s0 + ROW_L3])
        if deriv:
            a = chain_dz(l1, l2, dz, dzb)
            dzb = chain_dzb(l1, l2, dz, dzb)
            dz = a
    elif core == CORE_TPS or core == CORE_TPS_PAIRS:
        val, gz, gzb = tps_core(blk, s0, n, p, core == CORE_TPS_PAIRS, deriv)
        p = val
        if deriv:
            a = chain_dz(gz, gzb, dz, dzb)
            dzb = chain_dzb(gz, gzb, dz, dzb)
            dz = a
    elif core == CORE_TPS_INVERSE or core == CORE_TPS_PAIRS_INVERSE:
        paired = core == CORE_TPS_PAIRS_INVERSE
        p = tps_newton(blk, s0, n, iters, p, paired)
        if deriv:
            val, gz, gzb = tps_core(blk, s0, n, p, paired, True)
            det = abs2(gz) - abs2(gzb)
            iz = conj(gz) / det
            izb = gzb * (-1.0 / det)
            a = chain_dz(iz, izb, dz, dzb)
            dzb = chain_dzb(iz, izb, dz, dzb)
            dz = a
    else:  # a core this kernel does not know: outside (the host refuses it first)
        return wp.vec2(wp.nan, wp.nan), wp.vec2(wp.nan, wp.nan), wp.vec2(wp.nan, wp.nan)
    post = blk[s0 + ROW_POST]
    den2 = wp.vec2(1.0, 0.0) - cmul(lo(post), p)
    k2 = hi(blk[s0 + ROW_SCALE])
    w = hi(post) + cdiv(cmul(k2, p), den2)
    if deriv:
        g = cdiv(k2, cmul(den2, den2))
        return w, cmul(g, dz), cmul(g, dzb)
    return w, zero, zero


@wp.func
def then_stage(
    blk: wp.array(dtype=wp.vec4), k: int, w: wp.vec2, dz: wp.vec2, dzb: wp.vec2, core: int, n_regions: int,
    deriv: bool,
):
    """Stage k after the stages before it: (w, f_z, f_zbar) of the walk so
    far in, the same after stage k out (derivatives chained with ``deriv``)."""
    w2, gz, gzb = stage(blk, 1 + k * STAGE_ROWS, w, core, n_regions, deriv)
    if deriv:
        a = chain_dz(gz, gzb, dz, dzb)
        dzb = chain_dzb(gz, gzb, dz, dzb)
        dz = a
    return w2, dz, dzb


@wp.func
def walk(blk: wp.array(dtype=wp.vec4), z: wp.vec2, deriv: bool):
    """The whole block on z, each stage's kind read from its header:
    (w, f_z, f_zbar), the derivatives with ``deriv`` (else (1, 0))."""
    n_stages = int(blk[0][0])
    w = z
    dz = wp.vec2(1.0, 0.0)
    dzb = wp.vec2(0.0, 0.0)
    for k in range(n_stages):
        hdr = blk[1 + k * STAGE_ROWS + ROW_HEADER]
        w, dz, dzb = then_stage(blk, k, w, dz, dzb, int(hdr[0]), int(hdr[2]), deriv)
    return w, dz, dzb
