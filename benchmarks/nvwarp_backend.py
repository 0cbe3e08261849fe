"""Benchmark of the Warp backend, measured side by side in one run.

* warp_image on a 3840×2160 RGB uint8 image, bilinear, end to end (numpy
  array in, numpy array out, map computed inside), beside cv2.remap with
  maps precomputed outside the clock and beside numpy complex maps +
  cv2.remap (what users write today);
* the same for RGBA uint8, reported as warps per second and the memory
  traffic reached (image read + image written, a lower bound);
* map_points on 10M points beside the numpy reference.

Run: ``python3 -m benchmarks.nvwarp_backend [--device cpu|cuda:0] [--repeat N]``.
Warp's CPU device runs a launch on one thread; the backend splits large
calls into bands over its thread pool, so on the CPU both one thread and
the default thread count are measured. On CUDA the device is synchronized
inside the timed region (the result is copied back).
"""

import argparse
import time

import numpy as np

import fpiwarp
from fpiwarp.backends.nvwarp import backend as warp_backend

from .common import best_time, machine_facts, machine_line, remap_maps

WIDTH, HEIGHT = 3840, 2160
N_POINTS = 10_000_000


def sample_transform():
    """A generic 4-point map of the 4K frame, its pole well outside."""
    w, h = WIDTH - 1, HEIGHT - 1
    src = [[0, 0], [w, 0], [w, h], [0, h]]
    dst = [[120, 80], [w - 300, -60], [w + 90, h - 140], [-150, h + 40]]
    return fpiwarp.FPI(src, dst)


def image_rows(backends, transform, repeat):
    """Rows of (name, seconds) for the 4K RGB benchmark, and an RGBA row."""
    import cv2

    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, size=(HEIGHT, WIDTH, 3), dtype=np.uint8)
    mapx, mapy = remap_maps(transform, (HEIGHT, WIDTH))

    def remap_only():
        return cv2.remap(img, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    def numpy_then_remap():
        mx, my = remap_maps(transform, (HEIGHT, WIDTH))
        return cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    def warp_with(backend, image):
        cv = np.zeros(image.shape[2])
        return lambda: backend.warp_image(image, transform, (HEIGHT, WIDTH), order=1, mode="constant", cval=cv)

    got, want = warp_with(backends[-1], img)(), remap_only()
    agree = np.mean(np.all(np.abs(got.astype(int) - want) <= 1, axis=-1))
    rows = {
        "cv2.remap, maps precomputed": best_time(remap_only, repeat),
        "numpy maps + cv2.remap": best_time(numpy_then_remap, repeat),
    }
    for backend in backends:
        rows[f"warp {backend.device} x{backend.threads}, end to end"] = best_time(warp_with(backend, img), repeat)
    rgba = rng.integers(0, 256, size=(HEIGHT, WIDTH, 4), dtype=np.uint8)
    rgba_sec = best_time(warp_with(backends[-1], rgba), repeat)
    rows[f"warp {backends[-1].device} x{backends[-1].threads}, RGBA8"] = rgba_sec
    return rows, agree, rgba_sec


def point_rows(backends, transform, repeat):
    rng = np.random.default_rng(1)
    pts = rng.uniform([0, 0], [WIDTH, HEIGHT], size=(N_POINTS, 2))
    got, want = backends[-1].map_points(transform, pts), transform(pts)
    err = np.max(np.linalg.norm(got - want, axis=-1) / np.maximum(np.linalg.norm(want, axis=-1), 1))
    rows = {"numpy reference map_points": best_time(lambda: transform(pts), repeat)}
    for backend in backends:
        rows[f"warp {backend.device} x{backend.threads} map_points"] = best_time(
            lambda b=backend: b.map_points(transform, pts), repeat
        )
    return rows, err


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default=None, help="Warp device, e.g. cpu or cuda:0")
    parser.add_argument("--repeat", type=int, default=3, help="timed calls per row (best is kept)")
    args = parser.parse_args(argv)

    reason = warp_backend.probe()
    if reason is not None:
        raise SystemExit(f"the warp backend cannot run here: {reason}")
    t0 = time.perf_counter()
    backend = warp_backend.Backend(device=args.device)
    print(machine_line(machine_facts(backends=False)))
    print(f"Warp device {backend.device}; kernel load (compile or disk cache): {time.perf_counter() - t0:.2f} s\n")
    backends = [backend]
    if backend.device.is_cpu and backend.threads > 1:
        backends.insert(0, warp_backend.Backend(device=args.device, threads=1))
    transform = sample_transform()

    rows, agree, rgba = image_rows(backends, transform, args.repeat)
    base = rows["cv2.remap, maps precomputed"]
    pipeline = rows["numpy maps + cv2.remap"]
    print(f"{WIDTH}x{HEIGHT} uint8 bilinear, best of {args.repeat}")
    print(f"{'':44s} {'ms':>9s} {'/ remap':>8s} {'numpy+remap /':>14s}")
    for name, sec in rows.items():
        print(f"{name:44s} {sec * 1e3:9.1f} {sec / base:8.2f} {pipeline / sec:14.2f}")
    traffic = 2 * WIDTH * HEIGHT * 4 / rgba / 1e9
    print(f"RGBA8: {1 / rgba:.2f} warps/s, {traffic:.2f} GB/s of image traffic (read + write)")
    print(f"warp vs cv2.remap agreement (<= 1 level): {agree:.4%} of pixels\n")

    rows, err = point_rows(backends, transform, args.repeat)
    ref = rows["numpy reference map_points"]
    print(f"map_points, {N_POINTS:,} points, best of {args.repeat}")
    for name, sec in rows.items():
        print(f"{name:44s} {sec * 1e3:9.1f} ms  speed-up vs numpy {ref / sec:6.2f}")
    print(f"max relative error vs float64 reference: {err:.2e}")


if __name__ == "__main__":
    main()
