"""NVIDIA Warp kernels for antialiased warps: the block's derivatives and
the footprint's sub-samples.

Mirrors :mod:`fpiwarp.block.jacobian` (each stage's Wirtinger derivatives
chained stage after stage) and :mod:`fpiwarp.sampling.antialias` (nx × ny
sub-samples of the footprint spanned by the Jacobian's columns, each
interpolated like :mod:`fpiwarp.sampling.sampler`, averaged). The map's values
and the plain samplers' helpers come from :mod:`fpiwarp.kernels.nvwarp.map`;
this module is loaded only when a warp asks for antialiasing.
"""

from typing import Any

import warp as wp

from fpiwarp.block.codegen import KERNEL_CONSTANTS as CONTRACT

from .map import (
    CORE_AFFINE,
    CORE_TPS,
    CORE_TPS_INVERSE,
    CORE_TPS_PAIRS,
    CORE_TPS_PAIRS_INVERSE,
    ROW_HEADER,
    ROW_L3,
    ROW_L12,
    ROW_POST,
    ROW_PRE,
    ROW_REGIONS,
    ROW_SCALE,
    STAGE_ROWS,
    abs2,
    bilinear_indices,
    border_index,
    cdiv,
    clip_coord,
    cmul,
    conj,
    cubic_weights,
    hi,
    in_range,
    inside,
    lo,
    source_position,
    store,
    store_cval,
    tap,
    tps_newton,
    tps_wirtinger,
)

wp.set_module_options({"enable_backward": False})

AA_MAX_TAPS = wp.constant(CONTRACT["AA_MAX_TAPS"])
AA_SLACK = wp.constant(CONTRACT["AA_SLACK"])
AA_SPACING = wp.constant(CONTRACT["AA_SPACING"])
AA_KNEE_TAPS = wp.constant(float(CONTRACT["AA_KNEE_TAPS"]))
AA_FAR_SPACING = wp.constant(CONTRACT["AA_FAR_SPACING"])


@wp.func
def chain_dz(gw: wp.vec2, gwb: wp.vec2, dz: wp.vec2, dzb: wp.vec2):
    """(g o f)_z from g's derivatives and f's (jacobian.chain)."""
    return cmul(gw, dz) + cmul(gwb, conj(dzb))


@wp.func
def chain_dzb(gw: wp.vec2, gwb: wp.vec2, dz: wp.vec2, dzb: wp.vec2):
    """(g o f)_zbar from g's derivatives and f's (jacobian.chain)."""
    return cmul(gw, dzb) + cmul(gwb, conj(dz))


@wp.func
def stage_wirtinger(blk: wp.array(dtype=wp.vec4), s0: int, z: wp.vec2):
    """jacobian.stage_wirtinger: one stage's value and derivatives (w, g_z, g_zbar)."""
    hdr = blk[s0 + ROW_HEADER]
    core = int(hdr[0])
    n = int(hdr[1])
    n_regions = int(hdr[2])
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
    dz = cdiv(k1, cmul(den, den))
    dzb = zero
    if core == CORE_AFFINE:
        l1 = lo(blk[s0 + ROW_L12])
        l2 = hi(blk[s0 + ROW_L12])
        p = cmul(l1, p) + cmul(l2, conj(p)) + lo(blk[s0 + ROW_L3])
        a = chain_dz(l1, l2, dz, dzb)
        dzb = chain_dzb(l1, l2, dz, dzb)
        dz = a
    elif core == CORE_TPS or core == CORE_TPS_PAIRS:
        val, gz, gzb = tps_wirtinger(blk, s0, n, p, core == CORE_TPS_PAIRS)
        p = val
        a = chain_dz(gz, gzb, dz, dzb)
        dzb = chain_dzb(gz, gzb, dz, dzb)
        dz = a
    elif core == CORE_TPS_INVERSE or core == CORE_TPS_PAIRS_INVERSE:
        paired = core == CORE_TPS_PAIRS_INVERSE
        p = tps_newton(blk, s0, n, iters, p, paired)
        val, gz, gzb = tps_wirtinger(blk, s0, n, p, paired)
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
    g = cdiv(k2, cmul(den2, den2))
    return hi(post) + cdiv(cmul(k2, p), den2), cmul(g, dz), cmul(g, dzb)


@wp.func
def block_wirtinger(blk: wp.array(dtype=wp.vec4), z: wp.vec2):
    """jacobian.wirtinger on one point: value, f_z, f_zbar."""
    n_stages = int(blk[0][0])
    w = z
    dz = wp.vec2(1.0, 0.0)
    dzb = wp.vec2(0.0, 0.0)
    for k in range(n_stages):
        w2, gz, gzb = stage_wirtinger(blk, 1 + k * STAGE_ROWS, w)
        a = chain_dz(gz, gzb, dz, dzb)
        dzb = chain_dzb(gz, gzb, dz, dzb)
        dz = a
        w = w2
    return w, dz, dzb


@wp.func
def tap_count(length: float):
    """_antialias.tap_counts: 1 for length <= 1 + AA_SLACK or NaN, else
    ceil(min(length / AA_SPACING, max(AA_KNEE_TAPS, length / AA_FAR_SPACING))
    - AA_SLACK) in 2..AA_MAX_TAPS."""
    if length != length or length <= 1.0 + AA_SLACK:
        return 1
    n = wp.min(length / AA_SPACING, wp.max(AA_KNEE_TAPS, length / AA_FAR_SPACING))
    return int(wp.clamp(wp.ceil(n - AA_SLACK), 2.0, float(AA_MAX_TAPS)))


@wp.func
def sample_pixel(img: wp.array3d(dtype=Any), s: wp.vec2, order: int, mode: int, cval: wp.vec4):
    """_sampling.sample of every channel at s (in range), the taps' indices
    and weights computed once for all channels."""
    h = img.shape[0]
    w = img.shape[1]
    sx = clip_coord(s[0])
    sy = clip_coord(s[1])
    v = wp.vec4(0.0)
    if order == 0:
        ix = int(wp.floor(sx + 0.5))
        iy = int(wp.floor(sy + 0.5))
        ok = inside(ix, w, mode) and inside(iy, h, mode)
        r = border_index(iy, h, mode)
        q = border_index(ix, w, mode)
        for c in range(img.shape[2]):
            v[c] = tap(float(img[r, q, c]), cval[c], ok)
        return v
    fx = wp.floor(sx)
    fy = wp.floor(sy)
    tx = sx - fx
    ty = sy - fy
    if order == 1:
        x0 = int(fx)
        y0 = int(fy)
        c0, c1, r0, r1 = bilinear_indices(x0, y0, w, h, mode)
        ok00 = inside(y0, h, mode) and inside(x0, w, mode)
        ok01 = inside(y0, h, mode) and inside(x0 + 1, w, mode)
        ok10 = inside(y0 + 1, h, mode) and inside(x0, w, mode)
        ok11 = inside(y0 + 1, h, mode) and inside(x0 + 1, w, mode)
        for c in range(img.shape[2]):
            v00 = tap(float(img[r0, c0, c]), cval[c], ok00)
            v01 = tap(float(img[r0, c1, c]), cval[c], ok01)
            v10 = tap(float(img[r1, c0, c]), cval[c], ok10)
            v11 = tap(float(img[r1, c1, c]), cval[c], ok11)
            v[c] = (1.0 - ty) * ((1.0 - tx) * v00 + tx * v01) + ty * ((1.0 - tx) * v10 + tx * v11)
        return v
    wx = cubic_weights(tx)
    wy = cubic_weights(ty)
    x0 = int(fx) - 1
    y0 = int(fy) - 1
    for j in range(4):
        row = border_index(y0 + j, h, mode)
        row_in = inside(y0 + j, h, mode)
        acc = wp.vec4(0.0)
        for i in range(4):
            col = border_index(x0 + i, w, mode)
            ok = row_in and inside(x0 + i, w, mode)
            for c in range(img.shape[2]):
                acc[c] = acc[c] + wx[i] * tap(float(img[row, col, c]), cval[c], ok)
        v = v + wy[j] * acc
    return v


@wp.func
def pixel_antialias(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    y: int,
    x: int,
    order: int,
    mode: int,
    cval: wp.vec4,
    top: float,
):
    """_antialias.sample_antialiased for output pixel (x, y)."""
    s = source_position(blk, x, y)
    w, dz, dzb = block_wirtinger(blk, wp.vec2(float(x), float(y)))
    ex = dz + dzb
    ey = wp.vec2(dzb[1] - dz[1], dz[0] - dzb[0])
    nx = tap_count(wp.sqrt(ex[0] * ex[0] + ex[1] * ex[1]))
    ny = tap_count(wp.sqrt(ey[0] * ey[0] + ey[1] * ey[1]))
    if not in_range(s):
        store_cval(out, y, x, cval, top)
        return
    if nx == 1 and ny == 1:
        v = sample_pixel(img, s, order, mode, cval)
        for c in range(img.shape[2]):
            store(out, y, x, c, v[c], top)
        return
    fnx = float(nx)
    fny = float(ny)
    inv = 1.0 / (fnx * fny)
    acc = wp.vec4(0.0)
    for j in range(ny):
        t = (2.0 * float(j) + 1.0 - fny) / (2.0 * fny)
        for i in range(nx):
            sub = (2.0 * float(i) + 1.0 - fnx) / (2.0 * fnx)
            p = s + (ex * sub + ey * t)
            if in_range(p):
                acc = acc + sample_pixel(img, p, order, mode, cval)
            else:
                acc = acc + cval
    for c in range(img.shape[2]):
        store(out, y, x, c, acc[c] * inv, top)


@wp.kernel
def warp_antialias(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    order: int,
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """_antialias.sample_antialiased for output pixel (x, y + row0)."""
    y, x = wp.tid()
    y = y + row0
    pixel_antialias(blk, img, out, y, x, order, mode, cval, top)


for _dtype in (wp.uint8, wp.uint16, wp.float32):
    wp.overload(warp_antialias, {"img": wp.array3d(dtype=_dtype), "out": wp.array3d(dtype=_dtype)})
del _dtype
