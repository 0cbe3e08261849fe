"""NVIDIA Warp image kernels specialized per kind of map and of sampling.

:mod:`fpiwarp.kernels.nvwarp.map` holds one generic kernel per order that
reads every decision from the parameter block and its arguments at run
time (stage count, core, regions, channels, border mode). Here a kernel is
generated for one :class:`fpiwarp.block.BlockKind` (the stages' cores and
region counts) and one kind of sampling (order, channels, border mode,
dtype), as the OpenCL program (``-DFW_KIND_k``) and the GL shaders
(``stages`` of a ProgramKey) are: the stage chain, the core's branch, the
region loop, the channel loop and the border rule are fixed when Warp
compiles it (``wp.static``), so the compiler drops what a kind does not use
and unrolls the rest. Numbers of TPS centers and Newton steps stay
run-time values (read from the block), so maps of one shape but another
number of centers share a kernel.

The arithmetic is :mod:`fpiwarp.kernels.nvwarp.map`'s own functions (the TPS
cores, the Möbius parts, the sampling helpers): these kernels only fix
what is constant for a kind, so they compute what the generic kernels
compute. Each kernel is a closure in a module of its own
(``module="unique"``), compiled on first use per kind and cached on disk
by Warp; :func:`image_kernel` (one image) and :func:`batch_kernel` (a
stack of images, one map each) share the per-pixel function of a kind and
keep the kernels made in this process.
"""

import threading

import warp as wp

from . import map as M

wp.set_module_options({"enable_backward": False})

_cache = {}
_lock = threading.Lock()


def kind_key(kind):
    """What a kernel specializes on for a :class:`fpiwarp.block.BlockKind`:
    each stage's (core, number of regions)."""
    return tuple((s.core, s.n_regions) for s in kind.stages)


def _stage_func(s0, core, n_regions):
    """The stage at block row ``s0`` for one (core, regions) kind."""
    S0 = wp.constant(s0)
    CORE = wp.constant(core)
    NREG = wp.constant(n_regions)

    @wp.func
    def stage(blk: wp.array(dtype=wp.vec4), z: wp.vec2):
        if wp.static(NREG > 0):
            best = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
            outside = wp.vec2(wp.nan, wp.nan)
            for r in range(NREG):
                line = blk[S0 + M.ROW_REGIONS + 2 * r]
                sim = blk[S0 + M.ROW_REGIONS + 2 * r + 1]
                dz = z - M.lo(line)
                nrm = M.hi(line)
                depth = dz[0] * nrm[0] + dz[1] * nrm[1]
                if depth > best:
                    best = depth
                    outside = M.cmul(M.lo(sim), z) + M.hi(sim)
            if best > 0.0:
                return outside
        u = z - M.lo(blk[S0 + M.ROW_PRE])
        p = M.cdiv(M.cmul(M.lo(blk[S0 + M.ROW_SCALE]), u), wp.vec2(1.0, 0.0) - M.cmul(M.hi(blk[S0 + M.ROW_PRE]), u))
        if wp.static(CORE == M.CORE_AFFINE):
            p = M.cmul(M.lo(blk[S0 + M.ROW_L12]), p) + M.cmul(M.hi(blk[S0 + M.ROW_L12]), M.conj(p)) + M.lo(
                blk[S0 + M.ROW_L3]
            )
        elif wp.static(CORE == M.CORE_TPS or CORE == M.CORE_TPS_PAIRS):
            hdr = blk[S0 + M.ROW_HEADER]
            p = M.tps_value(blk, S0, int(hdr[1]), p, wp.static(CORE == M.CORE_TPS_PAIRS))
        else:
            hdr = blk[S0 + M.ROW_HEADER]
            p = M.tps_newton(blk, S0, int(hdr[1]), int(hdr[3]), p, wp.static(CORE == M.CORE_TPS_PAIRS_INVERSE))
        post = blk[S0 + M.ROW_POST]
        return M.hi(post) + M.cdiv(M.cmul(M.hi(blk[S0 + M.ROW_SCALE]), p), wp.vec2(1.0, 0.0) - M.cmul(M.lo(post), p))

    return stage


def _then(first, second):
    """``second`` after ``first``: two stages in order."""

    @wp.func
    def chained(blk: wp.array(dtype=wp.vec4), z: wp.vec2):
        return second(blk, first(blk, z))

    return chained


def evaluate_func(key):
    """A ``wp.func`` (blk, z) -> w evaluating a block of kind ``key``."""
    ev = None
    for k, (core, n_regions) in enumerate(key):
        stage = _stage_func(1 + k * M.STAGE_ROWS, core, n_regions)
        ev = stage if ev is None else _then(ev, stage)
    return ev


def _pixel_func(key, order, channels, mode, dtype):
    """The per-pixel ``wp.func`` (blk, img, src0, h, out, dst0, y, x, cval)
    of one kind: output pixel (y, x) (at row dst0 + y of ``out``) sampled
    through the map of block ``blk`` from the image of ``h`` rows starting
    at row src0 of ``img``; the single-image and the batch kernels both
    call it. Images of a batch are row offsets into (N·H, W, C) arrays
    (no sub-array view per pixel)."""
    evaluate = evaluate_func(key)
    T = wp.dtype_from_numpy(dtype)
    C = wp.constant(channels)
    MODE = wp.constant(mode)
    ORDER = wp.constant(order)
    TOP = wp.constant(255.0 if T is wp.uint8 else 65535.0 if T is wp.uint16 else 0.0)

    @wp.func
    def put(out: wp.array3d(dtype=T), y: int, x: int, c: int, v: float):
        if wp.static(TOP > 0.0):
            v = wp.clamp(wp.floor(v + 0.5), 0.0, TOP)
        out[y, x, c] = T(v)

    @wp.func
    def pixel(blk: wp.array(dtype=wp.vec4), img: wp.array3d(dtype=T), src0: int, h: int, out: wp.array3d(dtype=T),
              dst0: int, y: int, x: int, cval: wp.vec4):
        s = evaluate(blk, wp.vec2(float(x), float(y)))
        oy = dst0 + y
        if not M.in_range(s):
            for c in range(C):
                put(out, oy, x, c, cval[c])
            return
        w = img.shape[1]
        sx = M.clip_coord(s[0])
        sy = M.clip_coord(s[1])
        if wp.static(ORDER == 0):
            ix = int(wp.floor(sx + 0.5))
            iy = int(wp.floor(sy + 0.5))
            ok = M.inside(ix, w, MODE) and M.inside(iy, h, MODE)
            col = M.border_index(ix, w, MODE)
            row = src0 + M.border_index(iy, h, MODE)
            for c in range(C):
                put(out, oy, x, c, M.tap(float(img[row, col, c]), cval[c], ok))
        elif wp.static(ORDER == 1):
            fx = wp.floor(sx)
            fy = wp.floor(sy)
            tx = sx - fx
            ty = sy - fy
            x0 = int(fx)
            y0 = int(fy)
            c0, c1, r0, r1 = M.bilinear_indices(x0, y0, w, h, MODE)
            r0 = src0 + r0
            r1 = src0 + r1
            in00 = M.inside(y0, h, MODE) and M.inside(x0, w, MODE)
            in01 = M.inside(y0, h, MODE) and M.inside(x0 + 1, w, MODE)
            in10 = M.inside(y0 + 1, h, MODE) and M.inside(x0, w, MODE)
            in11 = M.inside(y0 + 1, h, MODE) and M.inside(x0 + 1, w, MODE)
            for c in range(C):
                cv = cval[c]
                v00 = M.tap(float(img[r0, c0, c]), cv, in00)
                v01 = M.tap(float(img[r0, c1, c]), cv, in01)
                v10 = M.tap(float(img[r1, c0, c]), cv, in10)
                v11 = M.tap(float(img[r1, c1, c]), cv, in11)
                put(out, oy, x, c, (1.0 - ty) * ((1.0 - tx) * v00 + tx * v01) + ty * ((1.0 - tx) * v10 + tx * v11))
        else:
            fx = wp.floor(sx)
            fy = wp.floor(sy)
            wx = M.cubic_weights(sx - fx)
            wy = M.cubic_weights(sy - fy)
            x0 = int(fx) - 1
            y0 = int(fy) - 1
            cols = wp.vec4i(
                M.border_index(x0, w, MODE),
                M.border_index(x0 + 1, w, MODE),
                M.border_index(x0 + 2, w, MODE),
                M.border_index(x0 + 3, w, MODE),
            )
            rows = wp.vec4i(
                src0 + M.border_index(y0, h, MODE),
                src0 + M.border_index(y0 + 1, h, MODE),
                src0 + M.border_index(y0 + 2, h, MODE),
                src0 + M.border_index(y0 + 3, h, MODE),
            )
            for c in range(C):
                cv = cval[c]
                v = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
                for j in range(4):
                    acc = float(0.0)  # noqa: UP018 - a Warp variable, not a literal constant
                    for i in range(4):
                        ok = M.inside(y0 + j, h, MODE) and M.inside(x0 + i, w, MODE)
                        acc = acc + wx[i] * M.tap(float(img[rows[j], cols[i], c]), cv, ok)
                    v = v + wy[j] * acc
                put(out, oy, x, c, v)

    return pixel


def _make_image_kernel(key, order, channels, mode, dtype):
    pixel = _pixel_func(key, order, channels, mode, dtype)
    T = wp.dtype_from_numpy(dtype)

    @wp.kernel(module="unique")
    def warp_kind(
        blk: wp.array(dtype=wp.vec4),
        img: wp.array3d(dtype=T),
        out: wp.array3d(dtype=T),
        cval: wp.vec4,
        row0: int,
    ):
        y, x = wp.tid()
        pixel(blk, img, 0, img.shape[0], out, 0, y + row0, x, cval)

    return warp_kind


def _make_batch_kernel(key, order, channels, mode, dtype):
    pixel = _pixel_func(key, order, channels, mode, dtype)
    T = wp.dtype_from_numpy(dtype)

    @wp.kernel(module="unique")
    def warp_kind_batch(
        blks: wp.array2d(dtype=wp.vec4),
        images: wp.array(dtype=int),
        img: wp.array3d(dtype=T),
        out: wp.array3d(dtype=T),
        h: int,
        oh: int,
        step: int,
        cval: wp.vec4,
        row0: int,
    ):
        r, x = wp.tid()
        r = r + row0
        k = r / oh  # Warp's int division truncates, as floor for r >= 0
        n = images[k]
        pixel(blks[k * step], img, n * h, h, out, n * oh, r - k * oh, x, cval)

    return warp_kind_batch


def _make_strided_batch_kernel(key, order, channels, mode, dtype):
    pixel = _pixel_func(key, order, channels, mode, dtype)
    T = wp.dtype_from_numpy(dtype)

    @wp.kernel(module="unique")
    def warp_kind_batch_strided(
        blks: wp.array2d(dtype=wp.vec4),
        images: wp.array(dtype=int),
        img: wp.array4d(dtype=T),
        out: wp.array4d(dtype=T),
        step: int,
        cval: wp.vec4,
        row0: int,
    ):
        r, x = wp.tid()
        r = r + row0
        oh = out.shape[1]
        k = r / oh
        n = images[k]
        pixel(blks[k * step], img[n], 0, img.shape[1], out[n], 0, r - k * oh, x, cval)

    return warp_kind_batch_strided


def _make_row_batch_kernel(key, order, channels, mode, dtype):
    pixel = _pixel_func(key, order, channels, mode, dtype)
    T = wp.dtype_from_numpy(dtype)

    @wp.kernel(module="unique")
    def warp_kind_batch_rows(
        blks: wp.array2d(dtype=wp.vec4),
        images: wp.array(dtype=int),
        img: wp.array3d(dtype=T),
        out: wp.array3d(dtype=T),
        h: int,
        oh: int,
        step: int,
        cval: wp.vec4,
        row0: int,
    ):
        r = wp.tid() + row0
        k = r / oh
        n = images[k]
        blk = blks[k * step]
        y = r - k * oh
        for x in range(out.shape[1]):
            pixel(blk, img, n * h, h, out, n * oh, y, x, cval)

    return warp_kind_batch_rows


def _make_strided_row_batch_kernel(key, order, channels, mode, dtype):
    pixel = _pixel_func(key, order, channels, mode, dtype)
    T = wp.dtype_from_numpy(dtype)

    @wp.kernel(module="unique")
    def warp_kind_batch_strided_rows(
        blks: wp.array2d(dtype=wp.vec4),
        images: wp.array(dtype=int),
        img: wp.array4d(dtype=T),
        out: wp.array4d(dtype=T),
        step: int,
        cval: wp.vec4,
        row0: int,
    ):
        r = wp.tid() + row0
        oh = out.shape[1]
        k = r / oh
        n = images[k]
        blk = blks[k * step]
        src = img[n]
        dst = out[n]
        y = r - k * oh
        for x in range(out.shape[2]):
            pixel(blk, src, 0, img.shape[1], dst, 0, y, x, cval)

    return warp_kind_batch_strided_rows


def _cached(make, key, order, channels, mode, dtype):
    full = (make.__name__, tuple(key), int(order), int(channels), int(mode), str(dtype))
    with _lock:
        kernel = _cache.get(full)
        if kernel is None:
            kernel = _cache[full] = make(*full[1:5], dtype)
    return kernel


def image_kernel(key, order, channels, mode, dtype):
    """The image kernel for a map kind ``key`` (see :func:`kind_key`),
    ``order`` (0, 1, 3), ``channels`` (1-4), border ``mode`` (an index
    of :data:`fpiwarp.block.sampling_rules.MODES`) and a numpy ``dtype``;
    made once per process. Its arguments: (block, image, out, cval vec4,
    first row)."""
    return _cached(_make_image_kernel, key, order, channels, mode, dtype)


def batch_kernel(key, order, channels, mode, dtype):
    """The batch kernel of the same kind (see :func:`image_kernel`): the
    same per-pixel function on a stack, made once per process. Its
    arguments: (blocks (B, rows) vec4, images (K,) int, stack (N·H, W, C),
    out (N·oh, ow, C), H, oh, step (0: one block for all, 1: one each),
    cval vec4, first row); launched over (K·oh, ow), rows [k·oh, (k + 1)·oh)
    are output image ``images[k]`` warped by block ``k·step``, so that
    bands of rows split a batch like one tall image. (A block index array
    instead of ``step`` cost ~8 % per pixel on Warp's CPU device.)"""
    return _cached(_make_batch_kernel, key, order, channels, mode, dtype)


def strided_batch_kernel(key, order, channels, mode, dtype):
    """The batch kernel of the same kind on (N, H, W, C) stacks of any
    strides (a channels-first tensor's transposed view, say), whose
    images cannot be row offsets of one (N·H, W, C) array: image
    ``images[k]`` is the sub-array view ``img[n]``. Arguments: (blocks,
    images, stack (N, H, W, C), out (N, oh, ow, C), step, cval vec4,
    first row); launched over (K·oh, ow) like :func:`batch_kernel`."""
    return _cached(_make_strided_batch_kernel, key, order, channels, mode, dtype)


def row_batch_kernel(key, order, channels, mode, dtype, strided=False):
    """:func:`batch_kernel` (``strided``: :func:`strided_batch_kernel`)
    with one thread per output row, which runs along its row: launched
    over K·oh rows with the same arguments. For Warp's CPU device, where a
    thread per pixel pays the index arithmetic of the batch (a division by
    oh, the image and block lookups) for every pixel, about half again
    the image kernel's time; per row it is paid once (measured: 32 × 512²,
    one thread, 893 ms per pixel vs 568 ms per row vs 533 ms for 32 image
    kernels). The same per-pixel function: the same bits."""
    make = _make_strided_row_batch_kernel if strided else _make_row_batch_kernel
    return _cached(make, key, order, channels, mode, dtype)
