"""NVIDIA Warp kernels for batches: many images (point sets) per launch.

Each kernel runs the single image's per-pixel function of
:mod:`fpiwarp.kernels.warp_map` (:mod:`fpiwarp.kernels.warp_antialias`)
on image n of an (N, H, W, C) stack with block ``which[n]`` of stacked
parameter blocks, so a batch equals the loop bit for bit. The launch is
over (N·rows, cols), image n owning rows [n·oh, (n + 1)·oh), so that the
backend's bands of rows split a batch like one tall image. The Warp
kernels read each stage's kind from its header at run time, so maps of
every kind share one launch.
"""

from typing import Any

import warp as wp

from .warp_antialias import pixel_antialias
from .warp_map import evaluate, pixel_cubic, pixel_linear, pixel_nearest

wp.set_module_options({"enable_backward": False})


@wp.kernel
def batch_nearest(
    blks: wp.array2d(dtype=wp.vec4),
    which: wp.array(dtype=int),
    img: wp.array4d(dtype=Any),
    out: wp.array4d(dtype=Any),
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """Order 0 on image n = row // oh."""
    r, x = wp.tid()
    r = r + row0
    n = r // out.shape[1]
    pixel_nearest(blks[which[n]], img[n], out[n], r - n * out.shape[1], x, mode, cval, top)


@wp.kernel
def batch_linear(
    blks: wp.array2d(dtype=wp.vec4),
    which: wp.array(dtype=int),
    img: wp.array4d(dtype=Any),
    out: wp.array4d(dtype=Any),
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """Order 1 on image n = row // oh."""
    r, x = wp.tid()
    r = r + row0
    n = r // out.shape[1]
    pixel_linear(blks[which[n]], img[n], out[n], r - n * out.shape[1], x, mode, cval, top)


@wp.kernel
def batch_cubic(
    blks: wp.array2d(dtype=wp.vec4),
    which: wp.array(dtype=int),
    img: wp.array4d(dtype=Any),
    out: wp.array4d(dtype=Any),
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """Order 3 on image n = row // oh."""
    r, x = wp.tid()
    r = r + row0
    n = r // out.shape[1]
    pixel_cubic(blks[which[n]], img[n], out[n], r - n * out.shape[1], x, mode, cval, top)


@wp.kernel
def batch_antialias(
    blks: wp.array2d(dtype=wp.vec4),
    which: wp.array(dtype=int),
    img: wp.array4d(dtype=Any),
    out: wp.array4d(dtype=Any),
    order: int,
    mode: int,
    cval: wp.vec4,
    top: float,
    row0: int,
):
    """Antialiased, any order, on image n = row // oh."""
    r, x = wp.tid()
    r = r + row0
    n = r // out.shape[1]
    pixel_antialias(blks[which[n]], img[n], out[n], r - n * out.shape[1], x, order, mode, cval, top)


@wp.kernel
def batch_map_points(
    blks: wp.array2d(dtype=wp.vec4),
    which: wp.array(dtype=int),
    pts: wp.array2d(dtype=wp.vec2d),
    out: wp.array2d(dtype=wp.vec2d),
    first: int,
):
    """map_points_kernel on point j of set n, thread first + i = n·P + j."""
    i = wp.tid() + first
    n = i // pts.shape[1]
    j = i - n * pts.shape[1]
    p = pts[n, j]
    w = evaluate(blks[which[n]], wp.vec2(wp.float32(p[0]), wp.float32(p[1])))
    out[n, j] = wp.vec2d(wp.float64(w[0]), wp.float64(w[1]))


#: The batch kernels by interpolation order.
BATCH_KERNELS = {0: batch_nearest, 1: batch_linear, 3: batch_cubic}

for _kernel in (*BATCH_KERNELS.values(), batch_antialias):
    for _dtype in (wp.uint8, wp.uint16, wp.float32):
        wp.overload(_kernel, {"img": wp.array4d(dtype=_dtype), "out": wp.array4d(dtype=_dtype)})
del _kernel, _dtype
