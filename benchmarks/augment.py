"""Geometric augmentation, fpiwarp against albumentations, torchvision and
kornia: images per second at 256² and 512² uint8 RGB on one thread with a
new map per image, in alternating rounds in one process; the batch path;
the rate of building FPIs; keypoint agreement (the dot test) and labels.

    python3 -m benchmarks.augment [--rounds N] [--quick]

Writes benchmarks/results/augment.md and augment.json.
"""

import argparse
import json
import os
import platform
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("POCL_MAX_PTHREAD_COUNT", "1")  # PoCL on one thread, as every peer runs

import numpy as np  # noqa: E402

for _peer in ("torch", "torchvision.transforms.v2", "kornia.augmentation", "albumentations"):
    try:  # before fpiwarp starts its backends: torchvision crashed on import after them (its ops' native library)
        __import__(_peer)
    except ImportError:
        pass

import fpiwarp  # noqa: E402
from fpiwarp.augment import RandomFPI  # noqa: E402
from fpiwarp.maps.fpi import FPI  # noqa: E402

from .machine import describe  # noqa: E402

RESULTS = Path(__file__).parent / "results"
SIZES = (256, 512)
BATCH = 64


def _image_of(transform):
    """An albumentations transform as a call from image to image."""
    return lambda img: transform(image=img)["image"]


def peers(size):
    """{name: callable(image) -> warped} for the libraries installed here."""
    out = {}
    try:
        import albumentations as A

        out["albumentations Perspective"] = A.Perspective(scale=(0.05, 0.1), p=1.0)
        out["albumentations GridDistortion"] = A.GridDistortion(p=1.0)
        out["albumentations ElasticTransform"] = A.ElasticTransform(p=1.0)
        out["albumentations ThinPlateSpline"] = A.ThinPlateSpline(p=1.0)
        out = {k: _image_of(t) for k, t in out.items()}
    except ImportError:
        pass
    try:
        import torch
        from torchvision.transforms import v2

        torch.set_num_threads(1)
        persp, elastic = v2.RandomPerspective(p=1.0), v2.ElasticTransform()
        out["torchvision v2 RandomPerspective"] = lambda img: persp(torch.from_numpy(img).permute(2, 0, 1))
        out["torchvision v2 ElasticTransform"] = lambda img: elastic(torch.from_numpy(img).permute(2, 0, 1))
    except ImportError:
        pass
    try:
        import kornia.augmentation as K
        import torch

        kp, ktps = K.RandomPerspective(p=1.0), K.RandomThinPlateSpline(p=1.0)
        out["kornia RandomPerspective (float32)"] = lambda img: kp(torch.from_numpy(img).permute(2, 0, 1)[None].float()
                                                                   / 255)
        out["kornia RandomThinPlateSpline (float32)"] = lambda img: ktps(
            torch.from_numpy(img).permute(2, 0, 1)[None].float() / 255)
    except ImportError:
        pass
    return out


def fpiwarp_calls(status):
    out = {}
    for backend in ("opencl", "warp", "numpy"):
        if status.get(backend) is None:
            aug = RandomFPI(seed=0, backend=backend)
            out[f"fpiwarp RandomFPI, {backend}"] = (lambda a: lambda img: a(image=img)["image"])(aug)
    return out


def rate(fn, image, seconds):
    """Images per second of fn(image), calls repeated for about ``seconds``."""
    fn(image)  # warm (kernels built, caches filled)
    n, t0 = 0, time.perf_counter()
    while True:
        fn(image)
        n += 1
        t = time.perf_counter() - t0
        if t >= seconds:
            return n / t


def batch_rate(backend, stack, seconds):
    aug = RandomFPI(seed=0, backend=backend)
    aug.batch(stack)
    n, t0 = 0, time.perf_counter()
    while True:
        aug.batch(stack)
        n += len(stack)
        t = time.perf_counter() - t0
        if t >= seconds:
            return n / t


def fpi_rate(n=20000, rounds=3):
    rng = np.random.default_rng(0)
    square = np.array([[0, 0], [255, 0], [255, 255], [0, 255]], float)
    src = np.broadcast_to(square, (n, 4, 2))
    dst = src + rng.uniform(-25, 25, (n, 4, 2))
    best_many = best_one = 0.0
    for _ in range(rounds):
        t = time.perf_counter()
        FPI.many(src, dst)
        best_many = max(best_many, n / (time.perf_counter() - t))
        t = time.perf_counter()
        for i in range(500):
            FPI(src[i], dst[i])
        best_one = max(best_one, 500 / (time.perf_counter() - t))
    return best_many, best_one


def dot_test(shape=(256, 256), samples=8):
    """fpiwarp's keypoints against the centroids of their warped 3x3 dots (order 1)."""
    h, w = shape
    img = np.zeros(shape, np.float32)
    centres = np.array([(x, y) for y in range(24, h - 24, 16) for x in range(24, w - 24, 16)], float)
    for x, y in centres.astype(int):
        img[y - 1:y + 2, x - 1:x + 2] = 1
    aug = RandomFPI(seed=1, backend="numpy")
    errs = []
    for _ in range(samples):
        out = aug(image=img, keypoints=centres)
        for (x, y), ok in zip(out["keypoints"], out["keypoints_visible"]):
            if not ok:
                continue
            x0, y0 = int(round(x)) - 5, int(round(y)) - 5
            if x0 < 0 or y0 < 0 or x0 + 11 > w or y0 + 11 > h:  # a dot cut by the frame
                continue
            win = out["image"][y0:y0 + 11, x0:x0 + 11].astype(float)
            yy, xx = np.mgrid[y0:y0 + 11, x0:x0 + 11]
            errs.append(np.hypot((win * xx).sum() / win.sum() - x, (win * yy).sum() / win.sum() - y))
    return float(np.median(errs)), float(np.max(errs))


def invented_labels(samples=8):
    labels = np.random.default_rng(2).integers(0, 7, (128, 128)).astype(np.int32) * 1000 - 3
    aug = RandomFPI(seed=3)
    known = set(np.unique(labels).tolist()) | {0}
    return sum(len(set(np.unique(aug(mask=labels)["mask"]).tolist()) - known) for _ in range(samples))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=0.5)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    if args.quick:
        args.rounds, args.seconds = 1, 0.05
    status = fpiwarp.backend_status()
    rng = np.random.default_rng(0)
    table = {}
    for size in SIZES:
        image = rng.integers(0, 256, (size, size, 3)).astype(np.uint8)
        stack = rng.integers(0, 256, (BATCH, size, size, 3)).astype(np.uint8)
        calls = {**peers(size), **fpiwarp_calls(status)}
        best = {}
        for _ in range(args.rounds):  # alternating rounds: load affects every entry alike
            for name, fn in calls.items():
                try:
                    best[name] = max(best.get(name, 0.0), rate(fn, image, args.seconds))
                except Exception as exc:  # a peer that fails is recorded, the run goes on
                    best[name] = f"failed: {type(exc).__name__}: {exc}"[:120]
            for backend in ("opencl", "warp"):
                if status.get(backend) is None:
                    name = f"fpiwarp RandomFPI.batch of {BATCH}, {backend}, per image"
                    best[name] = max(best.get(name, 0.0), batch_rate(backend, stack, args.seconds))
        table[size] = best
    many, one = fpi_rate(2000 if args.quick else 20000, args.rounds)
    median, worst = dot_test(samples=2 if args.quick else 8)
    info = describe()
    result = {"images_per_second": table, "fpi_many_per_second": many, "fpi_one_by_one_per_second": one,
              "dot_test_px": {"median": median, "max": worst}, "invented_labels": invented_labels(),
              "machine": info, "python": platform.python_version()}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "augment.json").write_text(json.dumps(result, indent=1, default=str))
    (RESULTS / "augment.md").write_text(markdown(result))
    print(markdown(result))


def _versions():
    out = {}
    for name in ("numpy", "albumentations", "albucore", "torch", "torchvision", "kornia", "pyopencl", "warp"):
        try:
            out[name] = __import__(name).__version__
        except (ImportError, AttributeError):
            out[name] = "not installed"
    return out


def markdown(result):
    info = result["machine"]
    lines = ["# Augmentation: images per second (one thread, a new map per image, uint8 RGB)", "",
             f"Machine: {info.get('cpu', info.get('cpu_model', '?'))}; OpenCL device: "
             f"{info.get('backends', {}).get('opencl', '?')}; load average at start "
             f"{info.get('load_average_1_5_15min', '?')}.",
             "Versions: " + ", ".join(f"{k} {v}" for k, v in _versions().items()), "",
             "| | 256² | 512² | 256² vs albumentations Perspective | 512² vs it |", "|---|---|---|---|---|"]
    t = result["images_per_second"]
    ref = {s: t[s].get("albumentations Perspective") for s in SIZES}
    for name in t[SIZES[0]]:
        cells, ratios = [], []
        for s in SIZES:
            v = t[s].get(name)
            cells.append(f"{v:.0f}" if isinstance(v, float) else str(v))
            ratios.append(f"{v / ref[s]:.2f}x" if isinstance(v, float) and isinstance(ref[s], float) else "")
        lines.append(f"| {name} | {' | '.join(cells)} | {' | '.join(ratios)} |")
    lines += ["", f"- FPI construction: FPI.many {result['fpi_many_per_second']:.0f} maps/s, one FPI at a time "
              f"{result['fpi_one_by_one_per_second']:.0f} maps/s.",
              f"- Dot test (3x3 dots, order 1, fpiwarp RandomFPI keypoints vs warped-dot centroids): median "
              f"{result['dot_test_px']['median']:.3f} px, max {result['dot_test_px']['max']:.3f} px.",
              f"- Invented labels (int32 mask, 8 samples): {result['invented_labels']}.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
