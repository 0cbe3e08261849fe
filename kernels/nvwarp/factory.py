"""Every NVIDIA Warp kernel of fpiwarp, made by one factory from one stage
walk and one sampler, cached by what it specializes on.

:func:`image_kernel` makes the image kernels (one image, a batch, on
contiguous stacks or on 4-D views of any strides, plain or antialiased)
and :func:`point_kernel` the point kernels (one set, a batch of sets) from
the module-level functions of :mod:`.stage` (:func:`~.stage.stage`,
:func:`~.stage.walk`) and :mod:`.sample` (:func:`~.sample.sample`,
:func:`~.sample.sample_footprint`, :func:`~.sample.store_pixel`). What a
kernel specializes on is its :class:`ImageKernel` (or :class:`PointKernel`)
key: each field is a constant of the kernel (``wp.static``: the compiler
drops the code the key does not use and unrolls the rest) or, where
``None``, a run-time value (read from the block or passed as an argument),
so one kernel serves every value. The kernel for a key is made once per
process (:func:`image_kernel` keeps it) in a Warp module of its own whose
name says what it is and whose hash is stable, so Warp compiles it once
per device and caches the binary on disk (as ``warp.fem``'s
``dynamic_kernel`` does: a specialization is named by its key, never a
fresh closure per call).

One image is a batch of one: every image kernel takes (blocks (B, rows)
vec4, images (K,) int, img, out, H, oh, step, order, mode, cval vec4,
pyramid, levels, first row); the pyramid (float32 levels >= 1 of every
source, :func:`pyramid_kernel`) and its level table are read by
antialiased kernels only (plain ones get a placeholder). Rows [k·oh, (k + 1)·oh) of the launch are output image
``images[k]`` warped by block ``k·step`` (step 0: one block for all, 1:
one each), so that bands of rows split a batch like one tall image. With
``rows`` a thread runs along one output row (Warp's CPU device: the
index arithmetic of the batch and the kernel's arguments are paid once a
row, not once a pixel), else a thread is one pixel (CUDA). A plain row
kernel takes its row in chunks of :data:`ROW_CHUNK` pixels, each in four
loops: the map and each pixel's taps and weights, into local arrays (a
loop that neither reads the image nor writes a pixel, which the C++
compiler vectorizes across pixels: 16 lanes with AVX-512; the one loop of
map, sampler and store it did not); the taps inside the image read into a
local array (the only data-dependent reads; pixels whose taps cross the
border or whose positions are out of range sampled whole by
:func:`~.sample.sample`); each pixel's value mixed from its taps and
rounded (vectorized); the values written.
"""

import hashlib
import threading
from typing import NamedTuple

import numpy as np
import warp as wp

from .sample import (
    TAP_SIDE,
    bilinear_cell,
    bilinear_mix,
    cubic_cell,
    in_range,
    level_texel,
    nearest_cell,
    pixel_value,
    sample,
    sample_footprint,
    span_inside,
    store_pixel,
)
from .stage import then_stage, walk

_cache = {}
_lock = threading.Lock()

#: Pixels of a row whose map a row kernel (Warp's CPU device) evaluates in
#: one vectorized loop before it samples them (measured: 8 and 16 slower
#: than 32; 64 no faster than 32 for the map alone, 4 % faster once the
#: sampler was split too).
ROW_CHUNK = 64

#: ``index & NONNEG`` is ``index`` for an index that is not negative, and
#: tells the C++ compiler so: Warp's array reads and writes add the axis's
#: length to a negative index (Python's rule), and a compiler that knows the
#: index is not negative drops that from the row kernels' scalar loops.
NONNEG = 0x7FFFFFFF

#: The numpy dtypes of images the kernels read and write, with their top value
#: (integer outputs are rounded and clipped to [0, top]; 0: float, not clipped).
DTYPES = {"uint8": 255.0, "uint16": 65535.0, "float32": 0.0}


class ImageKernel(NamedTuple):
    """What an image kernel specializes on (``None``: a run-time value).

    kind: each stage's (core, number of regions) (:func:`kind_key`), or
        None for a kernel that reads every stage's kind from the block
        (maps of any kind in one launch).
    order, mode: interpolation order (0, 1, 3) and border mode (an index
        of :data:`fpiwarp.block.sampling_rules.MODES`), or None (taken
        from the kernel's ``order`` / ``mode`` arguments).
    channels: 1-4, or None (the image's last axis).
    dtype: "uint8", "uint16" or "float32".
    strided: (N, H, W, C) stacks of any strides, image n the view ``img[n]``
        (else (N·H, W, C) arrays, image n rows [n·H, (n + 1)·H)).
    rows: a thread per output row (else per pixel).
    antialias: average over the footprint of the map's Jacobian.
    """

    kind: tuple | None
    order: int | None
    mode: int | None
    channels: int | None
    dtype: str
    strided: bool = False
    rows: bool = False
    antialias: bool = False


class PointKernel(NamedTuple):
    """What a point kernel specializes on: ``sets``: (N, P) point sets,
    set n mapped by block ``which[n]`` (else one (P,) set by block 0)."""

    sets: bool = False


def kind_key(kind):
    """What a kernel specializes on for a :class:`fpiwarp.block.BlockKind`:
    each stage's (core, number of regions)."""
    return tuple((int(s.core), int(s.n_regions)) for s in kind.stages)


def image_spec(kind, order, mode, channels, dtype, *, strided=False, rows=False, antialias=False):
    """An :class:`ImageKernel` with its fields normalized (numpy dtypes by
    name, numbers as ints), so equal requests share a kernel."""
    return ImageKernel(
        None if kind is None else tuple((int(c), int(r)) for c, r in kind),
        None if order is None else int(order),
        None if mode is None else int(mode),
        None if channels is None else int(channels),
        np.dtype(dtype).name,
        bool(strided),
        bool(rows),
        bool(antialias),
    )


def _module_name(prefix, key):
    """A Warp module name that says what is inside and is unique per key."""
    digest = hashlib.blake2b(repr(tuple(key)).encode(), digest_size=5).hexdigest()
    return f"fpiwarp_nvwarp_{prefix}_{digest}"


def _cached(key, make):
    with _lock:
        kernel = _cache.get(key)
        if kernel is None:
            kernel = _cache[key] = make(key)
    return kernel


def image_kernel(spec):
    """The image kernel for an :class:`ImageKernel` (see :func:`image_spec`), made once per process."""
    if not isinstance(spec, ImageKernel):
        raise TypeError(f"image_kernel takes an ImageKernel, got {type(spec).__name__}")
    if spec.dtype not in DTYPES:
        raise ValueError(f"no image kernel for dtype {spec.dtype}; the kernels read {sorted(DTYPES)}")
    return _cached(spec, _make_image_kernel)


def point_kernel(spec=None):
    """The point kernel for a :class:`PointKernel`, made once per process.
    Arguments: (blocks (B, rows) vec4, which (N,) int, points, out, first);
    float64 in and out, float32 inside; thread i maps point first + i
    (of the flattened (N, P) sets). Default: one set."""
    spec = PointKernel() if spec is None else spec
    if not isinstance(spec, PointKernel):
        raise TypeError(f"point_kernel takes a PointKernel, got {type(spec).__name__}")
    return _cached(spec, _make_point_kernel)


def _make_image_kernel(spec):
    KIND = spec.kind
    ORDER, MODE, CHANNELS = spec.order, spec.mode, spec.channels
    T = wp.dtype_from_numpy(np.dtype(spec.dtype))
    TOP = DTYPES[spec.dtype]
    STRIDED, ROWS, AA = spec.strided, spec.rows, spec.antialias
    Stack = wp.array4d(dtype=T) if STRIDED else wp.array3d(dtype=T)
    label = f"image_{spec.dtype}_o{ORDER}_m{MODE}_c{CHANNELS}{'_aa' if AA else ''}{'_rows' if ROWS else ''}"
    CHUNK = ROW_CHUNK if ROWS and not AA else 0
    SPLIT = CHUNK > 0 and ORDER in TAP_SIDE  # the split row chunks (else a pixel at a time)
    SIDE = TAP_SIDE.get(ORDER, 1)
    mname = _module_name(label, spec)

    @wp.func(module=mname)
    def map_at(blk: wp.array(dtype=wp.vec4), z: wp.vec2):
        """The map of this kernel's kind at z: (w, f_z, f_zbar) of the stage walk."""
        if wp.static(KIND is None):
            return walk(blk, z, wp.static(AA))
        s = z
        dz = wp.vec2(1.0, 0.0)
        dzb = wp.vec2(0.0, 0.0)
        for i in range(wp.static(len(KIND or ()))):
            s, dz, dzb = then_stage(blk, i, s, dz, dzb, wp.static(KIND[i][0]), wp.static(KIND[i][1]),
                                    wp.static(AA))
        return s, dz, dzb

    def warp_image(
        blks: wp.array2d(dtype=wp.vec4),
        images: wp.array(dtype=int),
        img: Stack,
        out: Stack,
        h: int,
        oh: int,
        step: int,
        order: int,
        mode: int,
        cval: wp.vec4,
        pyr: wp.array3d(dtype=float),
        levels: wp.array(dtype=wp.vec3i),
        row0: int,
    ):
        if wp.static(ROWS):
            r = wp.tid() + row0
            x_first = 0
        else:
            r, x_first = wp.tid()
            r = r + row0
        if wp.static(STRIDED):
            oh = out.shape[1]
        k = r / oh  # Warp's int division truncates, as floor for r >= 0
        n = images[k]
        blk = blks[k * step]
        y = r - k * oh
        if wp.static(STRIDED):
            src = img[n]
            dst = out[n]
            src0 = 0
            dst0 = 0
            h = img.shape[1]
        else:
            src = img
            dst = out
            src0 = n * h
            dst0 = n * oh
        x_last = x_first + 1
        if wp.static(ROWS):
            x_last = dst.shape[1]
        if wp.static(ORDER is not None):
            order = wp.static(ORDER)
        if wp.static(MODE is not None):
            mode = wp.static(MODE)
        channels = src.shape[2]
        if wp.static(CHANNELS is not None):
            channels = wp.static(CHANNELS)
        oy = dst0 + y
        x = x_first
        if wp.static(SPLIT):
            # Warp's CPU device: the row in chunks, each in loops such that
            # only the taps' reads and the pixels' writes are scalar
            # (data-dependent addresses, the image's strides): the map and
            # each pixel's taps and weights (vectorized); the taps of each
            # pixel whose taps lie inside the image read into a local array
            # (a pixel whose taps do not, or whose position is out of range,
            # sampled whole by the one sampler, with its border rule); each
            # pixel's value mixed from its taps and rounded (vectorized); the
            # values written. The same arithmetic per pixel as the loop below.
            fy = float(y)
            w = src.shape[1]
            sx = wp.vector(dtype=float, length=wp.static(CHUNK))
            sy = wp.vector(dtype=float, length=wp.static(CHUNK))
            x0 = wp.vector(dtype=int, length=wp.static(CHUNK))
            y0 = wp.vector(dtype=int, length=wp.static(CHUNK))
            rim = wp.vector(dtype=int, length=wp.static(CHUNK))  # 1: sampled whole (border rule or cval)
            # order 1: tx, ty; order 3: wx[0..3], wy[0..3]; [weight·CHUNK + pixel]
            wts = wp.vector(dtype=float, length=wp.static(2 * SIDE * CHUNK))
            taps = wp.vector(dtype=T, length=wp.static(4 * SIDE * SIDE * CHUNK))  # [(tap·4 + channel)·CHUNK + pixel]
            rim_v = wp.vector(dtype=float, length=wp.static(4 * CHUNK))  # [channel·CHUNK + pixel]
            vals = wp.vector(dtype=T, length=wp.static(4 * CHUNK))
            while x < x_last:
                count = wp.min(wp.static(CHUNK), x_last - x)
                i = wp.int32(0)
                while i < count:
                    si, dzi, dzbi = map_at(blk, wp.vec2(float(x + i), fy))
                    sx[i] = si[0]
                    sy[i] = si[1]
                    if wp.static(ORDER == 0):
                        xi, yi = nearest_cell(si)
                    if wp.static(ORDER == 1):
                        xi, yi, txi, tyi = bilinear_cell(si)
                        wts[i] = txi
                        wts[wp.static(CHUNK) + i] = tyi
                    if wp.static(ORDER == 3):
                        xi, yi, wxi, wyi = cubic_cell(si)
                        for k in range(4):
                            wts[k * wp.static(CHUNK) + i] = wxi[k]
                            wts[(4 + k) * wp.static(CHUNK) + i] = wyi[k]
                    x0[i] = xi
                    y0[i] = yi
                    rim[i] = 1 - int(in_range(si) and span_inside(xi, yi, wp.static(SIDE), w, h))
                    i = i + 1
                i = wp.int32(0)
                while i < count:
                    if rim[i] == 0:
                        r = (src0 + y0[i]) & wp.static(NONNEG)  # taps inside the image: not negative
                        q = x0[i] & wp.static(NONNEG)
                        for c in range(4):
                            if c < channels:
                                for dy in range(wp.static(SIDE)):
                                    for dx in range(wp.static(SIDE)):
                                        taps[((dy * wp.static(SIDE) + dx) * 4 + c) * wp.static(CHUNK) + i] = src[
                                            r + dy, q + dx, c]
                    else:
                        si = wp.vec2(sx[i], sy[i])
                        vi = cval
                        if in_range(si):
                            vi = sample(src, src0, h, w, si, wp.static(ORDER), mode, cval, channels)
                        for c in range(4):
                            if c < channels:
                                rim_v[c * wp.static(CHUNK) + i] = vi[c]
                    i = i + 1
                i = wp.int32(0)
                while i < count:
                    for c in range(4):
                        if c < channels:
                            if wp.static(ORDER == 0):
                                vm = float(taps[c * wp.static(CHUNK) + i])
                            if wp.static(ORDER == 1):
                                vm = bilinear_mix(float(taps[c * wp.static(CHUNK) + i]),
                                                  float(taps[(4 + c) * wp.static(CHUNK) + i]),
                                                  float(taps[(8 + c) * wp.static(CHUNK) + i]),
                                                  float(taps[(12 + c) * wp.static(CHUNK) + i]),
                                                  wts[i], wts[wp.static(CHUNK) + i])
                            if wp.static(ORDER == 3):  # cubic_taps' sums, in its order
                                vm = 0.0
                                for dy in range(4):
                                    acc = 0.0
                                    for dx in range(4):
                                        acc = acc + wts[dx * wp.static(CHUNK) + i] * float(
                                            taps[((dy * 4 + dx) * 4 + c) * wp.static(CHUNK) + i])
                                    vm = vm + wts[(4 + dy) * wp.static(CHUNK) + i] * acc
                            vm = wp.where(rim[i] != 0, rim_v[c * wp.static(CHUNK) + i], vm)
                            vals[c * wp.static(CHUNK) + i] = dst.dtype(pixel_value(vm, wp.static(TOP)))
                    i = i + 1
                i = wp.int32(0)
                oyp = oy & wp.static(NONNEG)
                while i < count:
                    xi = (x + i) & wp.static(NONNEG)
                    for c in range(4):
                        if c < channels:
                            dst[oyp, xi, c] = vals[c * wp.static(CHUNK) + i]
                    i = i + 1
                x = x + count
        if wp.static(not SPLIT):
            while x < x_last:  # (a while loop: Warp's range loop carries a step sign through every iteration)
                z = wp.vec2(float(x), float(y))
                s, dz, dzb = map_at(blk, z)
                v = cval
                if in_range(s):
                    if wp.static(AA):
                        v = sample_footprint(src, src0, h, pyr, levels, n, s, dz, dzb, order, mode, cval, channels)
                    else:
                        v = sample(src, src0, h, src.shape[1], s, order, mode, cval, channels)
                store_pixel(dst, oy, x, v, channels, wp.static(TOP))
                x = x + 1

    warp_image.__name__ = warp_image.__qualname__ = label
    return wp.kernel(warp_image, enable_backward=False, module=mname)


def pyramid_kernel(dtype, rows=False, channels=None):
    """The kernel making one pyramid level from the one below it (source
    dtype ``dtype`` for level 1, "float32" above), made once per process:
    arguments (src (rows, W, C), first row, rows, columns of the level
    below; dst (rows, W', C) float32, first row, columns of the level;
    first row of the launch), launched over the level's (rows, columns),
    or its rows with ``rows`` (a thread per row, as the image kernels on
    Warp's CPU device) and for ``channels`` channels (None: the arrays').
    Texel (i, j) of the level is
    :func:`~.sample.level_texel` of texels 2i, 2i + 1 and 2j, 2j + 1
    below, an index past the last row or column clamped to it
    (:mod:`fpiwarp.sampling.pyramid`)."""
    name = np.dtype(dtype).name
    if name not in DTYPES:
        raise ValueError(f"no pyramid kernel for dtype {name}; the kernels read {sorted(DTYPES)}")
    return _cached(("pyramid", name, bool(rows), None if channels is None else int(channels)), _make_pyramid_kernel)


def _make_pyramid_kernel(key):
    T = wp.dtype_from_numpy(np.dtype(key[1]))
    ROWS, CHANNELS = key[2], key[3]

    def halve(
        src: wp.array3d(dtype=T), src0: int, h: int, w: int, dst: wp.array3d(dtype=float), dst0: int, w2: int,
        row0: int,
    ):
        if wp.static(ROWS):
            i = wp.tid() + row0
            j = wp.int32(0)
            j_last = w2
        else:
            i, j = wp.tid()
            i = i + row0
            j_last = j + 1
        r0 = src0 + 2 * i
        r1 = src0 + wp.min(2 * i + 1, h - 1)
        while j < j_last:
            c0 = 2 * j
            c1 = wp.min(2 * j + 1, w - 1)
            if wp.static(CHANNELS is None):
                for c in range(src.shape[2]):
                    dst[dst0 + i, j, c] = level_texel(src, r0, r1, c0, c1, c)
            else:
                for c in range(wp.static(CHANNELS)):  # unrolled
                    dst[dst0 + i, j, c] = level_texel(src, r0, r1, c0, c1, c)
            j = j + 1

    label = f"pyramid_{key[1]}_c{CHANNELS}{'_rows' if ROWS else ''}"
    halve.__name__ = halve.__qualname__ = label
    return wp.kernel(halve, enable_backward=False, module=_module_name(label, key))


def _make_point_kernel(spec):
    SETS = spec.sets
    Points = wp.array2d(dtype=wp.vec2d) if SETS else wp.array(dtype=wp.vec2d)

    def map_points(
        blks: wp.array2d(dtype=wp.vec4), which: wp.array(dtype=int), pts: Points, out: Points, first: int
    ):
        i = wp.tid() + first
        if wp.static(SETS):
            n = i // pts.shape[1]
            j = i - n * pts.shape[1]
            p = pts[n, j]
            w, dz, dzb = walk(blks[which[n]], wp.vec2(wp.float32(p[0]), wp.float32(p[1])), False)
            out[n, j] = wp.vec2d(wp.float64(w[0]), wp.float64(w[1]))
        else:
            p = pts[i]
            w, dz, dzb = walk(blks[which[0]], wp.vec2(wp.float32(p[0]), wp.float32(p[1])), False)
            out[i] = wp.vec2d(wp.float64(w[0]), wp.float64(w[1]))

    label = f"points{'_sets' if SETS else ''}"
    map_points.__name__ = map_points.__qualname__ = label
    return wp.kernel(map_points, enable_backward=False, module=_module_name(label, spec))
