"""Small Warp kernels for device points of float32 (torch's and JAX's
default): widened to the ``vec2d`` the map kernel reads, and narrowed back.
Imported only when such points arrive (Warp is optional)."""

import warp as wp


@wp.kernel
def widen_points(src: wp.array2d(dtype=wp.float32), dst: wp.array(dtype=wp.vec2d)):
    """float32 (n, 2) -> vec2d (n,)."""
    i = wp.tid()
    dst[i] = wp.vec2d(wp.float64(src[i, 0]), wp.float64(src[i, 1]))


@wp.kernel
def narrow_points(src: wp.array(dtype=wp.vec2d), dst: wp.array2d(dtype=wp.float32)):
    """vec2d (n,) -> float32 (n, 2)."""
    i = wp.tid()
    dst[i, 0] = wp.float32(src[i][0])
    dst[i, 1] = wp.float32(src[i][1])
