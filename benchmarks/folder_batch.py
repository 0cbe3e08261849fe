"""Folder batch throughput: images per second on 1080p JPEGs, in one run.

Warps a folder of generated 1920×1080 JPEGs (read, warp, write with the
input's quality tables and metadata) with :func:`fpiwarp.batch.run_batch`
on the numpy backend and on every other backend that can run here, beside
the loop users write today: Pillow open, numpy maps of the inverse, then
``cv2.remap`` and a Pillow save, one image after the other. A second
baseline computes the maps once outside the loop. Each method writes every
image; one warm-up image per method is excluded (kernel compiles, caches).

Stacks already in memory (``warp_batch`` in one launch against the loop)
are measured by :mod:`benchmarks.batch_stacks` (``python -m benchmarks
--only batch``).

Run: ``python3 -m benchmarks.folder_batch [--images N] [--jobs J] [--backends numpy,gl]``.
Needs Pillow and opencv-python-headless. Numbers on a shared machine are
noisy: compare the ratios within one run.
"""

import argparse
import functools
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.batch import run_batch

from .common import machine_facts, machine_line, remap_maps

WIDTH, HEIGHT = 1920, 1080


def make_photos(folder, count, seed=0):
    """``count`` photo-like 1080p JPEGs: smooth shading, edges and grain."""
    from PIL import Image

    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float32)
    for i in range(count):
        phase = rng.uniform(0, 2 * np.pi, 3)
        base = np.stack(
            [128 + 100 * np.sin(x / (180 + 40 * k) + y / (260 + 30 * k) + phase[k]) for k in range(3)], axis=-1
        )
        checker = ((x // 120 + y // 120) % 2)[..., None] * 30
        grain = rng.normal(0, 6, size=(HEIGHT, WIDTH, 1))
        img = np.clip(base + checker + grain, 0, 255).astype(np.uint8)
        Image.fromarray(img).save(folder / f"photo{i:03d}.jpg", quality=90)


def sample_transform():
    w, h = WIDTH - 1, HEIGHT - 1
    return fpiwarp.FPI([[0, 0], [w, 0], [w, h], [0, h]], [[90, 60], [w - 200, -40], [w + 60, h - 90], [-100, h + 30]])


def baseline(files, out_dir, transform, maps_once):
    """The plain loop: Pillow open, (numpy maps), cv2.remap, Pillow save."""
    import cv2
    from PIL import Image

    maps = remap_maps(transform, (HEIGHT, WIDTH)) if maps_once else None
    for path in files:
        with Image.open(path) as im:
            img = np.asarray(im)
        mx, my = maps if maps_once else remap_maps(transform, (HEIGHT, WIDTH))
        out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        Image.fromarray(out).save(out_dir / path.name, quality=90)


def timed(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=8, help="number of 1080p JPEGs (default 8)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="threads for run_batch")
    parser.add_argument("--backends", help="comma-separated backends (default: every available one)")
    args = parser.parse_args(argv)

    backends = args.backends.split(",") if args.backends else fpiwarp.available_backends()
    transform = sample_transform()
    root = Path(tempfile.mkdtemp(prefix="fpiwarp-bench-"))
    try:
        photos = root / "in"
        warm = root / "warm"
        photos.mkdir()
        warm.mkdir()
        make_photos(photos, args.images)
        shutil.copy(photos / "photo000.jpg", warm / "photo000.jpg")
        files = sorted(photos.iterdir())

        rows = []
        for maps_once in (False, True):
            name = "loop: numpy maps + cv2.remap + Pillow save" + (" (maps once)" if maps_once else "")
            out = root / f"base{int(maps_once)}"
            out.mkdir()
            baseline(files[:1], out, transform, maps_once)  # warm-up
            shutil.rmtree(out)
            out.mkdir()
            rows.append((name, timed(lambda out=out, once=maps_once: baseline(files, out, transform, once))))
        for backend in backends:
            for jobs in sorted({1, args.jobs}):
                name = f"fpiwarp run_batch, {backend}, jobs={jobs}"
                run_batch(transform, warm, root / f"warm-{backend}-{jobs}", backend=backend, jobs=jobs)
                out = root / f"out-{backend}-{jobs}"
                run = functools.partial(run_batch, transform, photos, out, backend=backend, jobs=jobs)
                rows.append((name, timed(run)))

        reference = rows[0][1]
        print(machine_line(machine_facts(backends=False)))
        print(f"{args.images} JPEGs of {WIDTH}x{HEIGHT} RGB, bilinear, {os.cpu_count()} CPU cores")
        print(f"{'method':58} {'images/s':>9} {'vs loop':>8}")
        for name, seconds in rows:
            print(f"{name:58} {args.images / seconds:9.2f} {reference / seconds:7.2f}x")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
