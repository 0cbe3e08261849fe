"""Benchmark of the GL backend beside cv2.remap, end to end.

Warps an RGB uint8 image (default 3840×2160 and 1920×1080) by a generic
FPI with bilinear interpolation, constant border. Every GL timing includes
the texture upload, the draw and the readback into a numpy array; the
cv2.remap row uses maps precomputed outside the timed region (its best
case). The methods run round-robin, ``--repeat`` rounds after a warm-up,
so load from other processes hits all of them alike; ratios are medians
from this one run.

Usage::

    python benchmarks/bench_gl.py [--sizes 3840x2160,1920x1080] [--repeat 7]
"""

import argparse
import statistics
import time

import numpy as np

import fpiwarp


def _fpi(w, h):
    s = w / 64.0
    return fpiwarp.FPI(
        [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]],
        [[4 * s, 3 * s], [w - 4 * s, -2 * s], [w + 3 * s, h + 2 * s], [-3 * s, h - 4 * s]],
    )


def remap_reference(img, transform):
    """cv2.remap of ``img`` by ``transform`` with the float32 maps computed
    here, outside any clock (a zero-argument callable), or None without cv2."""
    try:
        import cv2
    except ImportError:
        print("(cv2 not installed: pip install opencv-python-headless for the reference row)")
        return None
    h, w = img.shape[:2]
    grid = np.stack(np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64)), -1)
    src = transform.inverse(grid).astype(np.float32)
    mx, my = np.ascontiguousarray(src[..., 0]), np.ascontiguousarray(src[..., 1])
    return lambda: cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _methods(w, h, img):
    """name -> zero-argument callable, each one complete warp of ``img``."""
    from fpiwarp.backends import get_backend

    f = _fpi(w, h)
    gl = get_backend("gl").warper
    cval = np.zeros(3)
    methods = {}
    reference = remap_reference(img, f)
    if reference is not None:
        methods["cv2.remap, precomputed maps"] = reference
    methods["gl warp_image (software bilinear)"] = lambda: gl.warp_image(
        img, f, (h, w), order=1, mode="constant", cval=cval)
    methods["gl warp_image hardware_filter"] = lambda: gl.warp_image(
        img, f, (h, w), order=1, mode="constant", cval=cval, hardware_filter=True)
    methods["gl warp_image_mesh (grid 8 px)"] = lambda: gl.warp_image_mesh(
        img, f, (h, w), order=1, mode="constant", cval=cval, grid_step=8)
    pts = np.random.default_rng(1).uniform(0, [w, h], size=(1_000_000, 2))
    methods["gl map_points, 1e6 points"] = lambda: gl.map_points(f, pts)
    return methods


def run(sizes, repeat):
    from fpiwarp.backends import backend_status
    from fpiwarp.backends.gl import shared_context

    reason = backend_status()["gl"]
    if reason is not None:
        raise SystemExit(f"gl backend unavailable: {reason}")
    ctx = shared_context()
    print(f"GL renderer: {ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})")
    rows = []
    for w, h in sizes:
        img = np.random.default_rng(0).integers(0, 256, (h, w, 3), dtype=np.uint8)
        methods = _methods(w, h, img)
        times = {name: [] for name in methods}
        for fn in methods.values():  # warm-up: compile, allocate textures
            fn()
        for _ in range(repeat):
            for name, fn in methods.items():
                t0 = time.perf_counter()
                fn()
                times[name].append(time.perf_counter() - t0)
        base = statistics.median(times[next(iter(times))]) if "cv2" in next(iter(times)) else None
        for name, ts in times.items():
            med = statistics.median(ts)
            ratio = f"{med / base:6.2f}x" if base else "   n/a"
            rows.append((f"{w}x{h}", name, med * 1e3, min(ts) * 1e3, ratio, 1.0 / med))
    print(f"{'size':>10}  {'method':<36} {'median ms':>10} {'min ms':>8} {'vs cv2':>7} {'fps':>7}")
    for size, name, med, best, ratio, fps in rows:
        print(f"{size:>10}  {name:<36} {med:10.1f} {best:8.1f} {ratio:>7} {fps:7.1f}")
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default="3840x2160,1920x1080", help="comma-separated WxH list")
    parser.add_argument("--repeat", type=int, default=7, help="timed rounds per method")
    args = parser.parse_args(argv)
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",")]
    run(sizes, args.repeat)


if __name__ == "__main__":
    main()
