"""The sampler in NVIDIA Warp: one for every kernel.

Mirrors :mod:`fpiwarp.sampling.sampler` (orders 0/1/3, border modes,
non-finite positions or positions beyond COORD_LIMIT give ``cval``,
integer outputs rounded with floor(v + 0.5) and clipped) and
:mod:`fpiwarp.sampling.antialias` (the footprint spanned by the
Jacobian's columns: its shorter edge picks a level of the source pyramid,
:mod:`fpiwarp.sampling.pyramid`, where nx × ny sub-samples are each
sampled like one position and averaged, blended into the next level in
the last AA_BLEND of each octave; level 0 is the source in its dtype with
the call's order, levels >= 1 float32, bilinear, each with the border
mode on its own size). The functions are generic in the pixel type (Warp makes one
overload per dtype) and take the order, border mode and channel count as
arguments: a kernel made for one kind of sampling passes constants
(:mod:`fpiwarp.kernels.nvwarp.factory`, through ``wp.static``) and the
compiler drops what that kind does not use.

An image is ``h`` rows starting at row ``src0`` of an (rows, W, C) array,
so the images of a batch are row offsets into one (N·H, W, C) array, and
the levels of their pyramids row offsets into one float32 array.
"""

from typing import Any

import warp as wp

from .contract import (
    AA_BLEND,
    AA_FAR_SPACING,
    AA_KNEE_TAPS,
    AA_LEVEL_SPAN,
    AA_MAX_TAPS,
    AA_SLACK,
    AA_SPACING,
    COORD_LIMIT,
    MODE_CONSTANT,
    MODE_REFLECT,
    MODE_WRAP,
)

wp.set_module_options({"enable_backward": False})


# --- border rules and weights -------------------------------------------------


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
def in_range(s: wp.vec2):
    """False for positions that are non-finite or beyond COORD_LIMIT: cval.
    (NaN fails every comparison and |inf| exceeds the limit, so the two
    comparisons are the whole test, without a call per component.)"""
    return wp.abs(s[0]) <= COORD_LIMIT and wp.abs(s[1]) <= COORD_LIMIT


@wp.func
def clip_coord(v: float):
    return wp.clamp(v, -COORD_LIMIT, COORD_LIMIT)


# --- one position ---------------------------------------------------------------
#
# Channel loops run over range(4) with ``c < channels`` inside: Warp
# unrolls a loop of constant length, and where ``channels`` is a constant
# of the kernel the compiler drops the channels it does not have. A tap
# footprint inside the image (the common case) calls the taps' function
# with its indices as they are and every tap inside (literal ``True``s, so
# the compiler drops the border's selects and index checks there); near
# the edges the border rule (``border_index``, ``inside``) gives the
# indices and flags. Both read the same values in the same arithmetic.


@wp.func
def nearest_tap(img: wp.array3d(dtype=Any), r: int, q: int, ok: bool, cval: wp.vec4, channels: int):
    """Order 0's one tap, pixel (r, q), for every channel (cval where not ``ok``)."""
    v = wp.vec4(0.0)
    for c in range(4):
        if c < channels:
            v[c] = tap(float(img[r, q, c]), cval[c], ok)
    return v


@wp.func
def bilinear_cell(s: wp.vec2):
    """Order 1's cell at s (in range): its top-left tap (x0, y0) and the
    fractions (tx, ty) of s past it."""
    sx = clip_coord(s[0])
    sy = clip_coord(s[1])
    fx = wp.floor(sx)
    fy = wp.floor(sy)
    return int(fx), int(fy), sx - fx, sy - fy


@wp.func
def nearest_cell(s: wp.vec2):
    """Order 0's one tap at s (in range): the nearest pixel, floor(s + 0.5)."""
    return int(wp.floor(clip_coord(s[0]) + 0.5)), int(wp.floor(clip_coord(s[1]) + 0.5))


#: The rows (and columns) of taps each order reads: its n × n taps.
TAP_SIDE = {0: 1, 1: 2, 3: 4}


@wp.func
def span_inside(x0: int, y0: int, n: int, w: int, h: int):
    """Whether the n × n taps from (x0, y0) (n: :data:`TAP_SIDE` of the
    order) all lie inside the w × h image, where the taps are read as they are."""
    return x0 >= 0 and x0 + n <= w and y0 >= 0 and y0 + n <= h


@wp.func
def cubic_cell(s: wp.vec2):
    """Order 3's taps at s (in range): the first of its 4 × 4 (x0, y0) and
    the weights of its columns and rows (:func:`cubic_weights`)."""
    sx = clip_coord(s[0])
    sy = clip_coord(s[1])
    fx = wp.floor(sx)
    fy = wp.floor(sy)
    return int(fx) - 1, int(fy) - 1, cubic_weights(sx - fx), cubic_weights(sy - fy)


@wp.func
def bilinear_mix(v00: float, v01: float, v10: float, v11: float, tx: float, ty: float):
    """Order 1's value from its four taps (rows first, then between them)."""
    return (1.0 - ty) * ((1.0 - tx) * v00 + tx * v01) + ty * ((1.0 - tx) * v10 + tx * v11)


@wp.func
def bilinear_taps(
    img: wp.array3d(dtype=Any), r0: int, r1: int, c0: int, c1: int, ok00: bool, ok01: bool, ok10: bool,
    ok11: bool, tx: float, ty: float, cval: wp.vec4, channels: int,
):
    """Order 1 over rows r0, r1 and columns c0, c1 (cval where a tap is not ``ok``)."""
    v = wp.vec4(0.0)
    for c in range(4):
        if c < channels:
            v00 = tap(float(img[r0, c0, c]), cval[c], ok00)
            v01 = tap(float(img[r0, c1, c]), cval[c], ok01)
            v10 = tap(float(img[r1, c0, c]), cval[c], ok10)
            v11 = tap(float(img[r1, c1, c]), cval[c], ok11)
            v[c] = bilinear_mix(v00, v01, v10, v11, tx, ty)
    return v


@wp.func
def cubic_taps(
    img: wp.array3d(dtype=Any), rows: wp.vec4i, cols: wp.vec4i, all_in: bool, row_in: wp.vec4i, col_in: wp.vec4i,
    wx: wp.vec4, wy: wp.vec4, cval: wp.vec4, channels: int,
):
    """Order 3 over 4 × 4 taps (cval where a tap's row or column is not
    inside, unless ``all_in``)."""
    v = wp.vec4(0.0)
    for j in range(4):
        row = rows[j]
        acc = wp.vec4(0.0)
        for i in range(4):
            col = cols[i]
            ok = all_in or (row_in[j] != 0 and col_in[i] != 0)
            for c in range(4):
                if c < channels:
                    acc[c] = acc[c] + wx[i] * tap(float(img[row, col, c]), cval[c], ok)
        v = v + wy[j] * acc
    return v


@wp.func
def sample(
    img: wp.array3d(dtype=Any), src0: int, h: int, w: int, s: wp.vec2, order: int, mode: int, cval: wp.vec4,
    channels: int,
):
    """sampler.sample of the first ``channels`` channels at s (in range) of
    the h × w image at rows [src0, src0 + h), columns [0, w) of ``img``:
    the taps' indices and weights computed once for all channels."""
    if order == 0:
        ix, iy = nearest_cell(s)
        if span_inside(ix, iy, 1, w, h):
            return nearest_tap(img, src0 + iy, ix, True, cval, channels)
        ok = inside(ix, w, mode) and inside(iy, h, mode)
        return nearest_tap(img, src0 + border_index(iy, h, mode), border_index(ix, w, mode), ok, cval, channels)
    if order == 1:
        x0, y0, tx, ty = bilinear_cell(s)
        if span_inside(x0, y0, 2, w, h):
            return bilinear_taps(img, src0 + y0, src0 + y0 + 1, x0, x0 + 1, True, True, True, True, tx, ty, cval,
                                 channels)
        in_x0 = inside(x0, w, mode)  # all True but in constant mode
        in_x1 = inside(x0 + 1, w, mode)
        in_y0 = inside(y0, h, mode)
        in_y1 = inside(y0 + 1, h, mode)
        return bilinear_taps(img, src0 + border_index(y0, h, mode), src0 + border_index(y0 + 1, h, mode),
                             border_index(x0, w, mode), border_index(x0 + 1, w, mode), in_y0 and in_x0,
                             in_y0 and in_x1, in_y1 and in_x0, in_y1 and in_x1, tx, ty, cval, channels)
    x0, y0, wx, wy = cubic_cell(s)
    if span_inside(x0, y0, 4, w, h):
        rows = wp.vec4i(src0 + y0, src0 + y0 + 1, src0 + y0 + 2, src0 + y0 + 3)
        ones = wp.vec4i(1, 1, 1, 1)
        return cubic_taps(img, rows, wp.vec4i(x0, x0 + 1, x0 + 2, x0 + 3), True, ones, ones, wx, wy, cval, channels)
    cols = wp.vec4i(0)
    rows = wp.vec4i(0)
    col_in = wp.vec4i(0)
    row_in = wp.vec4i(0)
    for i in range(4):
        cols[i] = border_index(x0 + i, w, mode)
        rows[i] = src0 + border_index(y0 + i, h, mode)
        col_in[i] = int(inside(x0 + i, w, mode))
        row_in[i] = int(inside(y0 + i, h, mode))
    return cubic_taps(img, rows, cols, False, row_in, col_in, wx, wy, cval, channels)


# --- antialiasing: the footprint's sub-samples ------------------------------------


@wp.func
def tap_count(length: float):
    """antialias.tap_counts: 1 for length <= 1 + AA_SLACK or NaN, else
    ceil(min(length / AA_SPACING, max(AA_KNEE_TAPS, length / AA_FAR_SPACING))
    - AA_SLACK) in 2..AA_MAX_TAPS."""
    if length != length or length <= 1.0 + AA_SLACK:
        return 1
    n = wp.min(length / AA_SPACING, wp.max(float(AA_KNEE_TAPS), length / AA_FAR_SPACING))
    return int(wp.clamp(wp.ceil(n - AA_SLACK), 2.0, float(AA_MAX_TAPS)))


@wp.func
def edge_length(e: wp.vec2):
    return wp.sqrt(e[0] * e[0] + e[1] * e[1])


@wp.func
def footprint_mean(
    img: wp.array3d(dtype=Any), src0: int, h: int, w: int, level: int, s: wp.vec2, ex: wp.vec2, ey: wp.vec2,
    order: int, mode: int, cval: wp.vec4, channels: int,
):
    """antialias.supersample at pyramid level ``level``, whose h × w texels
    are rows [src0, src0 + h) of ``img``: nx × ny sub-samples (tap_count of
    the edges in level texels) at source positions s + ex·sub + ey·t, each
    read at its level coordinate (p + 0.5) / 2^level - 0.5 with ``order``
    (cval beyond COORD_LIMIT), averaged."""
    inv_scale = 1.0 / float(1 << level)
    nx = tap_count(edge_length(ex) * inv_scale)
    ny = tap_count(edge_length(ey) * inv_scale)
    fnx = float(nx)
    fny = float(ny)
    inv = 1.0 / (fnx * fny)
    acc = wp.vec4(0.0)
    half = wp.vec2(0.5, 0.5)
    for j in range(ny):
        t = (2.0 * float(j) + 1.0 - fny) / (2.0 * fny)
        for i in range(nx):
            sub = (2.0 * float(i) + 1.0 - fnx) / (2.0 * fnx)
            p = s + (ex * sub + ey * t)
            if level > 0:
                p = (p + half) * inv_scale - half
            if in_range(p):
                acc = acc + sample(img, src0, h, w, p, order, mode, cval, channels)
            else:
                acc = acc + cval
    return acc * inv


@wp.func
def level_mean(
    img: wp.array3d(dtype=Any), src0: int, h: int, pyr: wp.array3d(dtype=float), levels: wp.array(dtype=wp.vec3i),
    n: int, k: int, s: wp.vec2, ex: wp.vec2, ey: wp.vec2, order: int, mode: int, cval: wp.vec4, channels: int,
):
    """The footprint's mean at level k: the source itself (its dtype, the
    call's order) for k = 0, else image n's level k of the float32 pyramid
    ``pyr`` (:func:`fpiwarp.kernels.nvwarp.factory.pyramid_kernel`), bilinearly.
    ``levels[k]`` is (first row, rows, columns) of level k in one image's
    pyramid, ``levels[0][0]`` the rows between images' pyramids (0: one
    pyramid for all)."""
    if k == 0:
        return footprint_mean(img, src0, h, img.shape[1], 0, s, ex, ey, order, mode, cval, channels)
    lv = levels[k]
    return footprint_mean(pyr, n * levels[0][0] + lv[0], lv[1], lv[2], k, s, ex, ey, 1, mode, cval, channels)


@wp.func
def sample_footprint(
    img: wp.array3d(dtype=Any), src0: int, h: int, pyr: wp.array3d(dtype=float), levels: wp.array(dtype=wp.vec3i),
    n: int, s: wp.vec2, dz: wp.vec2, dzb: wp.vec2, order: int, mode: int, cval: wp.vec4, channels: int,
):
    """antialias.sample_antialiased at s (in range), whose map has the
    Wirtinger derivatives dz, dzb there: one :func:`sample` where both
    level-0 counts are 1, else the footprint's mean at pyramid level k
    (antialias.pyramid_levels: the shorter edge picks it), blended with
    weight u into level k + 1 in the last AA_BLEND of each octave."""
    ex = dz + dzb
    ey = wp.vec2(dzb[1] - dz[1], dz[0] - dzb[0])
    lx = edge_length(ex)
    ly = edge_length(ey)
    if tap_count(lx) == 1 and tap_count(ly) == 1:
        return sample(img, src0, h, img.shape[1], s, order, mode, cval, channels)
    top = levels.shape[0] - 1
    short = wp.min(lx, ly)
    if lx != lx or ly != ly:  # NaN counts as 0 (numpy's minimum keeps a NaN, Warp's min would not)
        short = 0.0
    lod = wp.clamp(wp.log2(wp.max(short * (1.0 + AA_SLACK) / AA_LEVEL_SPAN, 1.0)), 0.0, float(top))
    k = int(wp.floor(lod))
    u = wp.clamp((lod - float(k) - 1.0 + AA_BLEND) / AA_BLEND, 0.0, 1.0)
    v = level_mean(img, src0, h, pyr, levels, n, k, s, ex, ey, order, mode, cval, channels)
    if k < top and u > 0.0:
        v = (1.0 - u) * v + u * level_mean(img, src0, h, pyr, levels, n, k + 1, s, ex, ey, order, mode, cval,
                                           channels)
    return v


@wp.func
def level_texel(src: wp.array3d(dtype=Any), r0: int, r1: int, c0: int, c1: int, c: int):
    """pyramid.halve's texel: the mean of rows r0, r1 and columns c0, c1 of
    channel c, as ((r0c0 + r0c1) + (r1c0 + r1c1)) / 4 in float32."""
    top = float(src[r0, c0, c]) + float(src[r0, c1, c])
    bottom = float(src[r1, c0, c]) + float(src[r1, c1, c])
    return 0.25 * (top + bottom)


# --- writing a pixel --------------------------------------------------------------


@wp.func
def pixel_value(value: float, top: float):
    """A value as written to an image: integer images (top > 0) round
    floor(v + 0.5) and clip to [0, top]; float images take it as it is."""
    if top > 0.0:
        return wp.clamp(wp.floor(value + 0.5), 0.0, top)
    return value


@wp.func
def store_pixel(out: wp.array3d(dtype=Any), y: int, x: int, v: wp.vec4, channels: int, top: float):
    """Write the first ``channels`` values of v at (y, x): integer images
    (top > 0) round floor(v + 0.5) and clip to [0, top]."""
    for c in range(4):
        if c < channels:
            out[y, x, c] = out.dtype(pixel_value(v[c], top))
