"""NVIDIA Warp kernels: the parameter block per vertex and per pixel.

Everything here is module-level ``@wp.func`` / ``@wp.kernel`` code, so Warp
hashes and compiles this module once (per device) and caches the binary on
disk; the map's values travel in the parameter block, never in the source.

The functions mirror :func:`fpiwarp.block.reference.evaluate` line by line (regions,
pre-Möbius, core, post-Möbius, stage after stage) and the sampling of
:mod:`fpiwarp.sampling.sampler` (orders 0/1/3, border modes, non-finite positions
give ``cval``, integer outputs rounded with floor(v + 0.5) and clipped).
Complex numbers are ``wp.vec2`` (re, im) in float32.

Image kernels are generic in the pixel type and overloaded for uint8,
uint16 and float32 images of shape (H, W, C), C in 1..4. Thread (y, x)
writes output pixel (x, y + row0): the host may launch bands of rows (and
ranges of points, from ``first``) from several threads, since Warp's CPU
device runs each launch on one thread.
"""

from typing import Any

import warp as wp

from fpiwarp.block.codegen import KERNEL_CONSTANTS as CONTRACT

# Forward evaluation only: no adjoint code, which halves the compile time.
wp.set_module_options({"enable_backward": False})

# The block contract's numbers, bound by name from the one table of
# fpiwarp.block.codegen (the kernels below read them as Warp constants).
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


# Accumulators start as ``float(0.0)``: Warp treats a bare literal as a
# constant that loops and branches may not reassign.

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


# --- the parameter block (mirrors fpiwarp.block.reference) ------------------


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
def tps_value(blk: wp.array(dtype=wp.vec4), s0: int, n: int, p: wp.vec2, paired: bool):
    """TPS core value at p: sum_j b_j r² log r + l1 p + l2 conj(p) + l3
    (``paired``: the paired terms)."""
    l1 = lo(blk[s0 + ROW_L12])
    l2 = hi(blk[s0 + ROW_L12])
    l3 = lo(blk[s0 + ROW_L3])
    val = cmul(l1, p) + cmul(l2, conj(p)) + l3
    if paired:
        pv, pdz, pdzb = tps_pairs_sum(blk, s0, n, p, False)
        return val + pv
    for j in range(n):
        row = blk[s0 + ROW_CENTERS + j]
        d = p - lo(row)
        r2 = abs2(d)
        lg = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
        if r2 > 0.0:
            lg = wp.log(r2)
        val = val + hi(row) * (0.5 * r2 * lg)
    return val


@wp.func
def tps_wirtinger(blk: wp.array(dtype=wp.vec4), s0: int, n: int, p: wp.vec2, paired: bool):
    """TPS core value and its Wirtinger derivatives f_z, f_zbar at p
    (``paired``: the paired terms)."""
    l1 = lo(blk[s0 + ROW_L12])
    l2 = hi(blk[s0 + ROW_L12])
    l3 = lo(blk[s0 + ROW_L3])
    val = cmul(l1, p) + cmul(l2, conj(p)) + l3
    dz = l1
    dzb = l2
    if paired:
        pv, pdz, pdzb = tps_pairs_sum(blk, s0, n, p, True)
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
        g = b * (0.5 * (lg + 1.0))
        dz = dz + cmul(g, conj(d))
        dzb = dzb + cmul(g, d)
    return val, dz, dzb


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
def tps_newton(blk: wp.array(dtype=wp.vec4), s0: int, n: int, iters: int, target: wp.vec2, paired: bool):
    """Solve TPS(x) = target by Newton from the inverse of the R-linear part
    plus the seed table's correction; NaN when not within newton_tol after ``iters`` steps."""
    tol = blk[s0 + ROW_L3][2]
    mu1 = lo(blk[s0 + ROW_MU12])
    mu2 = hi(blk[s0 + ROW_MU12])
    mu3 = lo(blk[s0 + ROW_MU3])
    x = cmul(mu1, target) + cmul(mu2, conj(target)) + mu3 + seed_correction(blk, s0, target)
    nan2 = wp.vec2(wp.nan, wp.nan)
    for k in range(iters):
        # the seed is rarely within tol: its pass takes the derivatives at
        # once; a later pass checks the value first and takes them only for
        # a point that goes on (the same iterates, fewer terms)
        if k > 0:
            if wp.sqrt(abs2(tps_value(blk, s0, n, x, paired) - target)) <= tol:
                return x
        val, dz, dzb = tps_wirtinger(blk, s0, n, x, paired)
        res = val - target
        if k == 0 and wp.sqrt(abs2(res)) <= tol:
            return x
        det = abs2(dz) - abs2(dzb)
        step = (cmul(conj(dz), res) - cmul(dzb, conj(res))) / det
        x = x - step
    if wp.sqrt(abs2(tps_value(blk, s0, n, x, paired) - target)) <= tol:
        return x
    return nan2


@wp.func
def evaluate_stage(blk: wp.array(dtype=wp.vec4), s0: int, z: wp.vec2):
    """One stage starting at block row s0: regions, pre-Möbius, core, post-Möbius."""
    hdr = blk[s0 + ROW_HEADER]
    core = int(hdr[0])
    n = int(hdr[1])
    n_regions = int(hdr[2])
    iters = int(hdr[3])
    best = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
    outside = wp.vec2(wp.nan, wp.nan)
    for r in range(n_regions):
        line = blk[s0 + ROW_REGIONS + 2 * r]
        sim = blk[s0 + ROW_REGIONS + 2 * r + 1]
        dz = z - lo(line)
        nrm = hi(line)
        depth = dz[0] * nrm[0] + dz[1] * nrm[1]
        if depth > best:
            best = depth
            outside = cmul(lo(sim), z) + hi(sim)
    if best > 0.0:
        return outside
    u = z - lo(blk[s0 + ROW_PRE])
    p = cdiv(cmul(lo(blk[s0 + ROW_SCALE]), u), wp.vec2(1.0, 0.0) - cmul(hi(blk[s0 + ROW_PRE]), u))
    if core == CORE_AFFINE:
        p = cmul(lo(blk[s0 + ROW_L12]), p) + cmul(hi(blk[s0 + ROW_L12]), conj(p)) + lo(blk[s0 + ROW_L3])
    elif core == CORE_TPS or core == CORE_TPS_PAIRS:
        p = tps_value(blk, s0, n, p, core == CORE_TPS_PAIRS)
    elif core == CORE_TPS_INVERSE or core == CORE_TPS_PAIRS_INVERSE:
        p = tps_newton(blk, s0, n, iters, p, core == CORE_TPS_PAIRS_INVERSE)
    else:  # a core this kernel does not know: outside (the host refuses it first)
        return wp.vec2(wp.nan, wp.nan)
    post = blk[s0 + ROW_POST]
    return hi(post) + cdiv(cmul(hi(blk[s0 + ROW_SCALE]), p), wp.vec2(1.0, 0.0) - cmul(lo(post), p))


@wp.func
def evaluate(blk: wp.array(dtype=wp.vec4), z: wp.vec2):
    """The whole block on one point: its stages in order."""
    n_stages = int(blk[0][0])
    w = z
    for k in range(n_stages):
        w = evaluate_stage(blk, 1 + k * STAGE_ROWS, w)
    return w


@wp.kernel
def map_points_kernel(
    blk: wp.array(dtype=wp.vec4), pts: wp.array(dtype=wp.vec2d), out: wp.array(dtype=wp.vec2d), first: int
):
    """Per vertex: float64 in and out, float32 inside; thread i maps point first + i."""
    i = wp.tid() + first
    p = pts[i]
    w = evaluate(blk, wp.vec2(wp.float32(p[0]), wp.float32(p[1])))
    out[i] = wp.vec2d(wp.float64(w[0]), wp.float64(w[1]))


# --- sampling (mirrors fpiwarp.sampling.sampler) -----------------------------------


@wp.func
def border_index(i: int, n: int, mode: int):
    """A tap's integer index made valid for ``mode``; constant mode clamps
    (its outside taps are replaced by cval through ``inside``)."""
    if mode == MODE_WRAP:
        m = i % n
        if m < 0:
            m = m + n
        return m
    if mode == MODE_REFLECT:
        if n == 1:
            return 0
        period = 2 * (n - 1)
        m = i % period
        if m < 0:
            m = m + period
        if m >= n:
            m = period - m
        return m
    return wp.clamp(i, 0, n - 1)


@wp.func
def inside(i: int, n: int, mode: int):
    """Whether a tap reads the image: always, except outside it in constant mode."""
    return mode != MODE_CONSTANT or (i >= 0 and i < n)


@wp.func
def tap(value: float, cval: float, is_inside: bool):
    """A tap's value: the pixel, or cval for a constant-mode tap outside."""
    if is_inside:
        return value
    return cval


@wp.func
def bilinear_indices(x0: int, y0: int, w: int, h: int, mode: int):
    """Columns c0, c1 and rows r0, r1 of order 1's four taps, whose top-left
    pixel is (x0, y0), in a w × h image (the border rule of ``mode``)."""
    return border_index(x0, w, mode), border_index(x0 + 1, w, mode), border_index(y0, h, mode), border_index(
        y0 + 1, h, mode)


@wp.func
def cubic_weights(t: float):
    """Keys' cubic convolution weights (a = -0.5) for offsets -1, 0, 1, 2."""
    t2 = t * t
    t3 = t2 * t
    return wp.vec4(
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    )


@wp.func
def source_position(blk: wp.array(dtype=wp.vec4), x: int, y: int):
    """Where output pixel (x, y) samples the source (block = the inverse map)."""
    return evaluate(blk, wp.vec2(float(x), float(y)))


@wp.func
def in_range(s: wp.vec2):
    """False for positions that are non-finite or beyond COORD_LIMIT: cval."""
    return wp.isfinite(s) and wp.abs(s[0]) <= COORD_LIMIT and wp.abs(s[1]) <= COORD_LIMIT


@wp.func
def clip_coord(v: float):
    return wp.clamp(v, -COORD_LIMIT, COORD_LIMIT)


@wp.func
def store(out: wp.array3d(dtype=Any), y: int, x: int, c: int, v: float, top: float):
    """Write one value: integer images (top > 0) round floor(v + 0.5) and clip."""
    if top > 0.0:
        v = wp.clamp(wp.floor(v + 0.5), 0.0, top)
    out[y, x, c] = out.dtype(v)


@wp.func
def store_cval(out: wp.array3d(dtype=Any), y: int, x: int, cval: wp.vec4, top: float):
    for c in range(out.shape[2]):
        store(out, y, x, c, cval[c], top)


@wp.func
def pixel_nearest(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    y: int,
    x: int,
    mode: int,
    cval: wp.vec4,
    top: float,
):
    """Order 0: the pixel at floor(x + 0.5), floor(y + 0.5)."""
    s = source_position(blk, x, y)
    if not in_range(s):
        store_cval(out, y, x, cval, top)
        return
    h = img.shape[0]
    w = img.shape[1]
    ix = int(wp.floor(clip_coord(s[0]) + 0.5))
    iy = int(wp.floor(clip_coord(s[1]) + 0.5))
    ok = inside(ix, w, mode) and inside(iy, h, mode)
    col = border_index(ix, w, mode)
    row = border_index(iy, h, mode)
    for c in range(img.shape[2]):
        store(out, y, x, c, tap(float(img[row, col, c]), cval[c], ok), top)


@wp.kernel
def warp_nearest(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """Order 0: the pixel at floor(x + 0.5), floor(y + 0.5)."""
    y, x = wp.tid()
    y = y + row0
    pixel_nearest(blk, img, out, y, x, mode, cval, top)


@wp.func
def pixel_linear(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    y: int,
    x: int,
    mode: int,
    cval: wp.vec4,
    top: float,
):
    """Order 1: bilinear over the four surrounding pixels, weights in software."""
    s = source_position(blk, x, y)
    if not in_range(s):
        store_cval(out, y, x, cval, top)
        return
    h = img.shape[0]
    w = img.shape[1]
    sx = clip_coord(s[0])
    sy = clip_coord(s[1])
    fx = wp.floor(sx)
    fy = wp.floor(sy)
    tx = sx - fx
    ty = sy - fy
    x0 = int(fx)
    y0 = int(fy)
    c0, c1, r0, r1 = bilinear_indices(x0, y0, w, h, mode)
    in_x0 = inside(x0, w, mode)  # all True but in constant mode
    in_x1 = inside(x0 + 1, w, mode)
    in_y0 = inside(y0, h, mode)
    in_y1 = inside(y0 + 1, h, mode)
    for c in range(img.shape[2]):
        cv = cval[c]
        v00 = tap(float(img[r0, c0, c]), cv, in_y0 and in_x0)
        v01 = tap(float(img[r0, c1, c]), cv, in_y0 and in_x1)
        v10 = tap(float(img[r1, c0, c]), cv, in_y1 and in_x0)
        v11 = tap(float(img[r1, c1, c]), cv, in_y1 and in_x1)
        v = (1.0 - ty) * ((1.0 - tx) * v00 + tx * v01) + ty * ((1.0 - tx) * v10 + tx * v11)
        store(out, y, x, c, v, top)


@wp.kernel
def warp_linear(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """Order 1: bilinear over the four surrounding pixels, weights in software."""
    y, x = wp.tid()
    y = y + row0
    pixel_linear(blk, img, out, y, x, mode, cval, top)


@wp.func
def pixel_cubic(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    y: int,
    x: int,
    mode: int,
    cval: wp.vec4,
    top: float,
):
    """Order 3: Keys' cubic convolution over 4×4 pixels."""
    s = source_position(blk, x, y)
    if not in_range(s):
        store_cval(out, y, x, cval, top)
        return
    h = img.shape[0]
    w = img.shape[1]
    sx = clip_coord(s[0])
    sy = clip_coord(s[1])
    fx = wp.floor(sx)
    fy = wp.floor(sy)
    wx = cubic_weights(sx - fx)
    wy = cubic_weights(sy - fy)
    x0 = int(fx) - 1
    y0 = int(fy) - 1
    cols = wp.vec4i(
        border_index(x0, w, mode),
        border_index(x0 + 1, w, mode),
        border_index(x0 + 2, w, mode),
        border_index(x0 + 3, w, mode),
    )
    rows = wp.vec4i(
        border_index(y0, h, mode),
        border_index(y0 + 1, h, mode),
        border_index(y0 + 2, h, mode),
        border_index(y0 + 3, h, mode),
    )
    for c in range(img.shape[2]):
        cv = cval[c]
        v = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
        for j in range(4):
            acc = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
            for i in range(4):
                ok = inside(y0 + j, h, mode) and inside(x0 + i, w, mode)
                acc = acc + wx[i] * tap(float(img[rows[j], cols[i], c]), cv, ok)
            v = v + wy[j] * acc
        store(out, y, x, c, v, top)


@wp.kernel
def warp_cubic(
    blk: wp.array(dtype=wp.vec4),
    img: wp.array3d(dtype=Any),
    out: wp.array3d(dtype=Any),
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """Order 3: Keys' cubic convolution over 4×4 pixels."""
    y, x = wp.tid()
    y = y + row0
    pixel_cubic(blk, img, out, y, x, mode, cval, top)


#: The image kernels by interpolation order.
IMAGE_KERNELS = {0: warp_nearest, 1: warp_linear, 3: warp_cubic}

for _kernel in IMAGE_KERNELS.values():
    for _dtype in (wp.uint8, wp.uint16, wp.float32):
        wp.overload(_kernel, {"img": wp.array3d(dtype=_dtype), "out": wp.array3d(dtype=_dtype)})
del _kernel, _dtype
