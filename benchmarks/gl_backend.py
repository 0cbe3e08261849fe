"""Benchmark of the GL backend beside cv2.remap, end to end.

Warps an RGB uint8 image (default 3840×2160 and 1920×1080) by a generic
FPI with bilinear interpolation, constant border. Every GL timing includes
the texture upload, the draw and the readback into a numpy array; the
cv2.remap row uses maps precomputed outside the timed region (its best
case). The methods run round-robin, ``--repeat`` rounds after a warm-up,
so load from other processes hits all of them alike; ratios are medians
from this one run.

Usage::

    python3 -m benchmarks.gl_backend [--sizes 3840x2160,1920x1080] [--repeat 7]
"""

import argparse
import statistics

import numpy as np

from .common import frame_fpi, interleaved, machine_facts, machine_line, remap_call


def _methods(w, h, img):
    """name -> zero-argument callable, each one complete warp of ``img``."""
    from fpiwarp.backends import get_backend

    f = frame_fpi(h, w)
    gl = get_backend("gl").warper
    cval = np.zeros(3)
    methods = {}
    try:
        methods["cv2.remap, precomputed maps"] = remap_call(img, f)
    except ImportError:
        print("(cv2 not installed: pip install opencv-python-headless for the reference row)")
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
    print(machine_line(machine_facts(backends=False)))
    print(f"GL renderer: {ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})")
    rows = []
    for w, h in sizes:
        img = np.random.default_rng(0).integers(0, 256, (h, w, 3), dtype=np.uint8)
        methods = _methods(w, h, img)
        times, _ = interleaved(methods, repeat)  # warm-up first: compile, allocate textures
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
