"""Benchmark of the "opencl" backend beside OpenCV and the numpy reference.

Run ``python3 -m benchmarks.opencl_backend`` (``--repeat N``, ``--small`` for a
quick smoke run). Needs pyopencl with an OpenCL driver and, for the
comparison, ``opencv-python-headless``. Methods are timed round-robin in
one run, so the ratios compare like with like on a busy machine; read the
ratios, not the absolute times.

Rows
----
* 4K RGB uint8, bilinear, constant border, end to end (numpy in, numpy
  out, map computed inside):
  - ``opencl warp_image``: fpiwarp.warp_image(..., backend="opencl");
  - ``cv2.remap, maps precomputed``: the float32 maps made outside the clock;
  - ``numpy maps + cv2.remap``: what users write today: the inverse map in
    numpy complex128 on the pixel grid, then cv2.remap.
* map_points on 10M points: the opencl backend against the numpy reference.

Targets (issue 4): opencl <= 3x cv2.remap with precomputed maps, >= 3x
faster than numpy maps + cv2.remap; map_points >= 5x numpy.
"""

import argparse
import sys

import numpy as np

import fpiwarp

from .common import interleaved, machine_facts, machine_line, medians, remap_maps


def _round_robin(methods, repeat):
    """Median seconds of every method, timed in rounds after a warm-up."""
    return medians(interleaved(methods, repeat)[0])


def demo_fpi(w, h):
    """A perspective-like FPI of a w x h frame with its pole off the image."""
    return fpiwarp.FPI(
        [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]],
        [[0.02 * w, 0.02 * h], [0.95 * w, -0.015 * h], [1.01 * w, 1.03 * h], [-0.015 * w, 0.95 * h]],
    )


def warp_rows(h, w, repeat):
    import cv2

    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    f = demo_fpi(w, h)
    mx, my = remap_maps(f, (h, w))

    def opencl():
        return fpiwarp.warp_image(image, f, order=1, mode="constant", backend="opencl")

    def remap_precomputed():
        return cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    def numpy_then_remap():
        ax, ay = remap_maps(f, (h, w))
        return cv2.remap(image, ax, ay, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    got = opencl()
    ref = remap_precomputed()
    # cv2 uses 5-bit fixed-point weights: agreement to a few levels only
    agree = float(np.mean(np.abs(got.astype(int) - ref) <= 2))
    return _round_robin(
        {
            "opencl warp_image": opencl,
            "cv2.remap, maps precomputed": remap_precomputed,
            "numpy maps + cv2.remap": numpy_then_remap,
        },
        repeat,
    ), agree


def point_rows(n, repeat):
    rng = np.random.default_rng(1)
    pts = rng.uniform(0, 3840, (n, 2))
    f = demo_fpi(3840, 2160)
    return _round_robin(
        {
            "opencl map_points": lambda: fpiwarp.map_points(f, pts, backend="opencl"),
            "numpy map_points": lambda: fpiwarp.map_points(f, pts, backend="numpy"),
        },
        repeat,
    )


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed calls per method (default 5)")
    parser.add_argument("--small", action="store_true", help="a 480x270 image and 100k points, for a smoke run")
    args = parser.parse_args(argv)

    reason = fpiwarp.backend_status()["opencl"]
    if reason is not None:
        print(f"opencl backend unavailable: {reason}", file=sys.stderr)
        return 1
    from fpiwarp.backends import get_backend

    h, w = (270, 480) if args.small else (2160, 3840)
    n = 100_000 if args.small else 10_000_000
    print(machine_line(machine_facts(backends=False)))
    print(f"device: {get_backend('opencl').device_label}")

    warp, agree = warp_rows(h, w, args.repeat)
    base = warp["cv2.remap, maps precomputed"]
    print(f"\n{w}x{h} RGB uint8, bilinear, end to end (median of {args.repeat}, round-robin)")
    print(f"{'method':32s} {'ms':>9s} {'x cv2.remap':>12s}")
    for name, t in warp.items():
        print(f"{name:32s} {t * 1e3:9.1f} {t / base:12.2f}")
    speedup = warp["numpy maps + cv2.remap"] / warp["opencl warp_image"]
    print(f"opencl vs cv2.remap precomputed: {warp['opencl warp_image'] / base:.2f}x the time (target <= 3)")
    print(f"opencl vs numpy maps + cv2.remap: {speedup:.2f}x faster (target >= 3)")
    print(f"pixels within 2 levels of cv2.remap: {agree:.4f}")

    pts = point_rows(n, args.repeat)
    print(f"\nmap_points, {n:,} points (median of {args.repeat})")
    print(f"{'method':32s} {'ms':>9s}")
    for name, t in pts.items():
        print(f"{name:32s} {t * 1e3:9.1f}")
    print(f"opencl vs numpy: {pts['numpy map_points'] / pts['opencl map_points']:.2f}x faster (target >= 5)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
