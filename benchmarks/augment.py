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
from fpiwarp.augment import RandomFPI, RandomLocal  # noqa: E402
from fpiwarp.maps.fpi import FPI  # noqa: E402

from .common import machine_facts  # noqa: E402

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


def fpiwarp_parts(backend):
    """The single call's parts side by side: the map drawn through the
    array path (FPI.many of one, as before the lean path), the map alone
    (lean, and through the arrays) and the warp alone (one fixed map)."""
    arrays = RandomFPI(seed=0, backend=backend)

    def array_path(img):
        f = arrays.maps_from_draws(arrays.rng.random((1, 9)), img.shape[:2])[0]
        return arrays.apply_to_image(f, img)

    lean, fixed = RandomFPI(seed=0, backend=backend), {}

    def warp_only(img):
        f = fixed.setdefault(img.shape, lean.sample(img.shape[:2]))
        return lean.apply_to_image(f, img)

    return {f"fpiwarp RandomFPI, {backend}, map through FPI.many (before)": array_path,
            "fpiwarp: drawing the map alone (lean path), maps/s": lambda img: lean.sample(img.shape[:2]),
            "fpiwarp: drawing the map alone (FPI.many of one), maps/s":
                lambda img: arrays.maps_from_draws(arrays.rng.random((1, 9)), img.shape[:2])[0],
            f"fpiwarp: the warp alone (one fixed map), {backend}": warp_only}


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


def paired(calls, image, n):
    """{name: median seconds per call}: the calls interleaved one by one
    (A, B, C, A, B, C, ...), so that a load spike hits all of them alike;
    medians ignore the spikes."""
    for fn in calls.values():
        fn(image)
    times = {name: [] for name in calls}
    for _ in range(n):
        for name, fn in calls.items():
            t = time.perf_counter()
            fn(image)
            times[name].append(time.perf_counter() - t)
    return {name: float(np.median(v)) for name, v in times.items()}


def single_call_calls(status):
    """The single-call target's contenders: albumentations Perspective,
    RandomFPI on the fastest host backend (lean map, and the map through
    FPI.many as before) and its parts."""
    out = {}
    try:
        import albumentations as A

        out["albumentations Perspective"] = _image_of(A.Perspective(scale=(0.05, 0.1), p=1.0))
    except ImportError:
        pass
    fastest = next(b for b in ("opencl", "warp", "numpy") if status.get(b) is None)
    aug = RandomFPI(seed=0, backend=fastest)
    out[f"fpiwarp RandomFPI, {fastest}"] = lambda img: aug(image=img)["image"]
    out.update(fpiwarp_parts(fastest))
    return out


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


def dot_image(shape=(256, 256)):
    h, w = shape
    img = np.zeros(shape, np.float32)
    centres = np.array([(x, y) for y in range(24, h - 24, 16) for x in range(24, w - 24, 16)], float)
    for x, y in centres.astype(int):
        img[y - 1:y + 2, x - 1:x + 2] = 1
    return img, centres


def dot_errors(image, keypoints, radius=5):
    """Distances from each keypoint to the centroid of the warped dot in a
    window around it; inf where the window holds no dot (off by > radius)."""
    h, w = image.shape[:2]
    errs = []
    for x, y in keypoints:
        if not (np.isfinite(x) and np.isfinite(y)):
            continue
        x0, y0 = int(round(x)) - radius, int(round(y)) - radius
        if x0 < 0 or y0 < 0 or x0 + 2 * radius + 1 > w or y0 + 2 * radius + 1 > h:
            continue
        win = image[y0:y0 + 2 * radius + 1, x0:x0 + 2 * radius + 1].astype(float)
        if win.sum() <= 0:
            errs.append(np.inf)
            continue
        yy, xx = np.mgrid[y0:y0 + 2 * radius + 1, x0:x0 + 2 * radius + 1]
        errs.append(np.hypot((win * xx).sum() / win.sum() - x, (win * yy).sum() / win.sum() - y))
    return errs


def peer_keypoint_calls():
    """{name: callable(image float32 (H, W), keypoints (n, 2)) -> (image, keypoints)} of the peers that move
    keypoints with the image (dot test) and {name: callable(int32 mask) -> mask} (invented labels)."""
    kp_calls, mask_calls = {}, {}
    try:
        import albumentations as A

        for name, t in (("Perspective", A.Perspective(scale=(0.05, 0.1), p=1.0)),
                        ("GridDistortion", A.GridDistortion(p=1.0)), ("ElasticTransform", A.ElasticTransform(p=1.0)),
                        ("ThinPlateSpline", A.ThinPlateSpline(p=1.0))):
            pipe = A.Compose([t], keypoint_params=A.KeypointParams(format="xy", remove_invisible=False), seed=0)
            kp_calls[f"albumentations {name}"] = (lambda q: lambda img, k: (lambda o: (o["image"], np.asarray(
                o["keypoints"], float)))(q(image=img, keypoints=k)))(pipe)
            mask_calls[f"albumentations {name}"] = (lambda q: lambda m: q(image=np.zeros(m.shape, np.uint8),
                                                                          mask=m)["mask"])(A.Compose([t], seed=0))
    except ImportError:
        pass
    try:
        import torch
        from torchvision import tv_tensors
        from torchvision.transforms import v2

        def tv(t):
            def call(img, k):
                o_img, o_k = t(tv_tensors.Image(torch.from_numpy(img)[None]),
                               tv_tensors.KeyPoints(torch.from_numpy(k), canvas_size=img.shape))
                return o_img[0].numpy(), o_k.numpy().astype(float)
            return call

        def tv_mask(t):
            blank = tv_tensors.Image(torch.zeros(1, 128, 128))
            return lambda m: t(blank, tv_tensors.Mask(torch.from_numpy(m)))[1].numpy()

        for name, t in (("RandomPerspective", v2.RandomPerspective(p=1.0)),
                        ("ElasticTransform", v2.ElasticTransform())):
            kp_calls[f"torchvision v2 {name}"], mask_calls[f"torchvision v2 {name}"] = tv(t), tv_mask(t)
    except ImportError:
        pass
    try:
        import kornia.augmentation as K
        import torch

        def kornia(t):
            def call(img, k):
                o_img, o_k = t(torch.from_numpy(img)[None, None], torch.from_numpy(k)[None].float())
                return o_img[0, 0].numpy(), o_k[0].numpy().astype(float)
            return call

        def kornia_mask(t):
            return lambda m: t(torch.zeros(1, 1, *m.shape), torch.from_numpy(m)[None, None].float())[1][0, 0].numpy()

        for name, cls in (("RandomPerspective", K.RandomPerspective),
                          ("RandomThinPlateSpline", K.RandomThinPlateSpline),
                          ("RandomElasticTransform", K.RandomElasticTransform)):
            seq = K.AugmentationSequential(cls(p=1.0), data_keys=["input", "keypoints"])
            kp_calls[f"kornia {name}"] = kornia(seq)
            mask_calls[f"kornia {name}"] = kornia_mask(K.AugmentationSequential(cls(p=1.0),
                                                                                data_keys=["input", "mask"]))
    except ImportError:
        pass
    aug = RandomFPI(seed=1, backend="numpy")
    kp_calls["fpiwarp RandomFPI"] = lambda img, k: (lambda o: (o["image"], o["keypoints"]))(aug(image=img, keypoints=k))
    local = RandomLocal(seed=1, backend="numpy")
    kp_calls["fpiwarp RandomLocal"] = lambda img, k: (lambda o: (o["image"], o["keypoints"]))(local(image=img,
                                                                                                     keypoints=k))
    labels_aug = RandomFPI(seed=3)
    mask_calls["fpiwarp RandomFPI"] = lambda m: labels_aug(mask=m)["mask"]
    return kp_calls, mask_calls


def peer_agreement(samples=4):
    """{name: {dot test median/max px, lost dots, invented labels}} (one 256² dot image, ``samples`` draws)."""
    img, centres = dot_image()
    labels = np.random.default_rng(2).integers(0, 7, (128, 128)).astype(np.int32) * 1000 - 3
    known = set(np.unique(labels).tolist()) | {0}
    kp_calls, mask_calls = peer_keypoint_calls()
    out = {}
    for name, fn in kp_calls.items():
        try:
            errs = []
            for _ in range(samples):
                o_img, o_k = fn(img, centres.copy())
                errs += dot_errors(np.asarray(o_img, float), o_k)
            errs = np.array(errs)
            ok = errs[np.isfinite(errs)]
            out[name] = {"median_px": float(np.median(errs)) if len(errs) else None,
                         "max_px": float(ok.max()) if len(ok) else None, "lost": int((~np.isfinite(errs)).sum()),
                         "measured": int(len(errs))}
        except Exception as exc:  # a peer that fails is recorded
            out[name] = {"failed": f"{type(exc).__name__}: {exc}"[:100]}
    for name, fn in mask_calls.items():
        try:
            invented = sum(len(set(np.unique(np.asarray(fn(labels)).astype(np.int64)).tolist()) - known)
                           for _ in range(samples))
        except Exception as exc:
            invented = f"failed: {type(exc).__name__}"
        out.setdefault(name, {})["invented_labels"] = invented
    return out


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
    parser.add_argument("--paired-calls", type=int, default=400, help="calls per entry in the paired single-call run")
    args = parser.parse_args(argv)
    if args.quick:
        args.rounds, args.seconds, args.paired_calls = 1, 0.05, 20
    status = fpiwarp.backend_status()
    rng = np.random.default_rng(0)
    single = {}
    for size in SIZES:
        image = rng.integers(0, 256, (size, size, 3)).astype(np.uint8)
        single[size] = {name: 1.0 / t for name, t in paired(single_call_calls(status), image,
                                                            args.paired_calls).items()}
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
    agreement = peer_agreement(1 if args.quick else 4)
    info = machine_facts()
    result = {"images_per_second": table, "paired_single_calls_per_second": single,
              "load_average_at_end": list(os.getloadavg()), "fpi_many_per_second": many,
              "fpi_one_by_one_per_second": one,
              "dot_test_px": {"median": median, "max": worst}, "agreement": agreement,
              "invented_labels": invented_labels(),
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
    single = result.get("paired_single_calls_per_second")
    if single:
        lines += ["", "Single calls paired (interleaved call by call, median of each entry's calls; per second; "
                  f"load average at the end {[round(v, 2) for v in result['load_average_at_end']]}):", "",
                  "| | 256² | 512² | 256² vs albumentations Perspective | 512² vs it |", "|---|---|---|---|---|"]
        sref = {s: single[s].get("albumentations Perspective") for s in SIZES}
        for name in single[SIZES[0]]:
            cells = [f"{single[s][name]:.0f}" for s in SIZES]
            ratios = [f"{single[s][name] / sref[s]:.2f}x" if sref[s] else "" for s in SIZES]
            lines.append(f"| {name} | {' | '.join(cells)} | {' | '.join(ratios)} |")
    lines += ["", f"- FPI construction: FPI.many {result['fpi_many_per_second']:.0f} maps/s, one FPI at a time "
              f"{result['fpi_one_by_one_per_second']:.0f} maps/s.",
              f"- Dot test (3x3 dots, order 1, fpiwarp RandomFPI keypoints vs warped-dot centroids): median "
              f"{result['dot_test_px']['median']:.3f} px, max {result['dot_test_px']['max']:.3f} px.",
              f"- Invented labels (int32 mask, 8 samples): {result['invented_labels']}.", ""]
    if result.get("agreement"):
        lines += ["Keypoints against their dots and labels, per library (3x3 dots every 16 px on 256², each "
                  "library's default interpolation; keypoint vs centroid of the warped dot in an 11x11 "
                  "window around it, 'lost' where the window holds no dot, i.e. off by more than 5 px; invented "
                  "labels: values in a warped int32 label mask that the input does not hold, over the draws):", "",
                  "| | median px | max px (found dots) | lost / measured | invented labels |", "|---|---|---|---|---|"]

        def fmt(v):
            return f"{v:.3f}" if isinstance(v, float) else ("" if v is None else str(v))

        for name, r in result["agreement"].items():
            if "failed" in r:
                lines.append(f"| {name} | {r['failed']} | | | {fmt(r.get('invented_labels'))} |")
                continue
            lost = f"{r['lost']} / {r['measured']}" if "lost" in r else ""
            lines.append(f"| {name} | {fmt(r.get('median_px'))} | {fmt(r.get('max_px'))} | {lost} | "
                         f"{fmt(r.get('invented_labels'))} |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
