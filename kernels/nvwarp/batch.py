"""NVIDIA Warp generic kernels for batches: antialiased images and point
sets, many per launch.

Each kernel runs the single call's generic per-pixel (per-point) function
of :mod:`fpiwarp.kernels.nvwarp.antialias` (:mod:`fpiwarp.kernels.nvwarp.map`)
on image (point set) n of a stack with block ``which[n]`` of stacked
parameter blocks, so a batch equals the loop bit for bit. The launch is
over (N·rows, cols), image n owning rows [n·oh, (n + 1)·oh), so that the
backend's bands of rows split a batch like one tall image. These kernels
read each stage's kind from its header at run time, so maps of every kind
share one launch. Plain (not antialiased) image batches run the kernels
specialized per kind of map instead, as single images do
(:func:`fpiwarp.kernels.nvwarp.kinds.batch_kernel`).
"""

from typing import Any

import warp as wp

from .antialias import pixel_antialias
from .map import evaluate

wp.set_module_options({"enable_backward": False})


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


for _dtype in (wp.uint8, wp.uint16, wp.float32):
    wp.overload(batch_antialias, {"img": wp.array4d(dtype=_dtype), "out": wp.array4d(dtype=_dtype)})
del _dtype
