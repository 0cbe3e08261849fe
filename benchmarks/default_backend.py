"""The default call against OpenCV, side by side in one run (issue 24).

``python -m benchmarks.default_backend [--quick] [--rounds N] [--out DIR]``
times, interleaved round by round (best of the rounds, so load on a shared
machine hits every row alike; each backend's calls in rounds of their own
with cv2.remap, :func:`image_rows`):

* 4K (3840 × 2160) RGB uint8 and float32, bilinear, constant border:
  ``cv2.remap`` with the FPI's float32 maps computed outside the clock (the
  baseline), ``fpiwarp.warp_image(img, f)`` with the default backend, and
  each kernel backend named explicitly; the float64 reference once;
* 256² RGB uint8: the same with :class:`fpiwarp.Warper` (prepared map);
* ``warp_batch`` of 64 images of 512² RGB uint8 with 64 maps against the
  loop of ``warp_image`` over them, per batching kernel backend;
* the first default call in a new process (a subprocess: import, probe,
  the cached measurement and kernel binaries, the 4K warp);
* where the opencl call's time goes (:func:`kernel_split`): the kernel
  alone, timed by the device's profiling clock on a queue of its own,
  against the whole call of the table above; what is left is the host's
  work per call (copies, allocation, Python, waits).

It writes ``default_backend.md`` (and ``.json``) under ``--out``
(default ``benchmarks/results``), headed by the CPU model, its vector ISA
and the OpenCL device: figures from different machines are never mixed.
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

import fpiwarp

from . import common
from .speed import corner_quads, test_image

KERNELS = ("opencl", "gl")


def interleaved(fns, rounds):
    """{name: best seconds} of ``rounds`` interleaved rounds after one warm-up call each."""
    return common.bests(common.interleaved(fns, rounds)[0])


def image_rows(h, w, dtype, rounds, backends, warper=False):
    """Rows of one case: each backend's calls (the default's with the
    backend it is) interleaved with ``cv2.remap`` in rounds of their own,
    one backend after another: alternating two backends' thread pools
    (PoCL's, llvmpipe's) call by call on a machine of few cores slows the
    small calls of both (256² opencl Warper 2.57x cv2.remap interleaved
    with gl, 1.21x without, on a 2-core Zen 5). The ratios are to the
    best cv2.remap time of all the groups."""
    rng = np.random.default_rng(0)
    img = test_image(h, w, dtype, rng)
    f = fpiwarp.FPI(*corner_quads(h, w))
    cv2_label = "cv2.remap (precomputed maps)"
    remap = common.remap_call(img, f)
    groups = {}
    if warper:
        default = fpiwarp.Warper(f)
        groups.setdefault(default.backend, {})[f"Warper, default ({default.backend})"] = lambda: default(img)
        for b in backends:
            bound = fpiwarp.Warper(f, backend=b)
            groups.setdefault(b, {})[f"Warper, {b}"] = lambda bound=bound: bound(img)
    else:
        name = fpiwarp.default_backend()
        groups.setdefault(name, {})[f"warp_image, default ({name})"] = lambda: fpiwarp.warp_image(img, f)
        for b in backends:
            groups.setdefault(b, {})[f"warp_image, {b}"] = lambda b=b: fpiwarp.warp_image(img, f, backend=b)
    best = {cv2_label: float("inf")}
    for fns in groups.values():
        got = interleaved({cv2_label: remap, **fns}, rounds)
        best[cv2_label] = min(best[cv2_label], got.pop(cv2_label))
        best.update(got)
    base = best[cv2_label]
    return [{"case": f"{w}x{h} RGB {dtype}", "impl": k, "seconds": v, "ratio": v / base} for k, v in best.items()]


def batch_rows(n, h, w, rounds, backends):
    rng = np.random.default_rng(0)
    stack = rng.integers(0, 256, size=(n, h, w, 3), dtype=np.uint8)
    src = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    maps = [fpiwarp.FPI(src, src + rng.uniform(-0.05, 0.05, (4, 2)) * [w, h]) for _ in range(n)]
    rows = []
    for b in backends:
        best = interleaved({
            "loop": lambda b=b: [fpiwarp.warp_image(stack[i], maps[i], backend=b) for i in range(n)],
            "batch": lambda b=b: fpiwarp.warp_batch(stack, maps, backend=b),
        }, rounds)
        rows.append({"case": f"warp_batch {n} x {w}x{h} RGB uint8, {n} maps", "impl": b, "loop_s": best["loop"],
                     "batch_s": best["batch"], "speedup": best["loop"] / best["batch"]})
    return rows


def kernel_split(cases, rounds, images):
    """[{case, call_s, kernel_s}] for the opencl rows of ``images``: the
    warp_image kernel of each ``cases`` entry (h, w, dtype) alone, best of
    ``rounds`` launches on a profiling queue (a backend object of its own,
    the same program and tile as the calls)."""
    import pyopencl as cl

    from fpiwarp.backends.opencl.backend import Backend

    be = Backend()
    be.queue = cl.CommandQueue(be.context, properties=cl.command_queue_properties.PROFILING_ENABLE)
    calls = {r["case"]: r["seconds"] for r in images if r["impl"].endswith(", opencl")}
    rows = []
    for h, w, dtype in cases:
        img = test_image(h, w, dtype, np.random.default_rng(0))
        job = be.prepare_warp(img, (h, w), order=1, mode="constant", cval=np.zeros(3))
        job.set_map(fpiwarp.FPI(*corner_quads(h, w)))
        job.launch().wait()  # warm-up
        best = float("inf")
        for _ in range(rounds):
            event = job.launch()
            event.wait()
            best = min(best, (event.profile.end - event.profile.start) * 1e-9)
        case = f"{w}x{h} RGB {dtype}"
        rows.append({"case": case, "call_s": calls[case], "kernel_s": best})
    return rows


FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np, fpiwarp
t1 = time.perf_counter()
img = np.zeros((2160, 3840, 3), np.uint8)
f = fpiwarp.FPI([[0, 0], [3839, 0], [3839, 2159], [0, 2159]], [[70, 40], [3700, -30], [3900, 2200], [-50, 2100]])
fpiwarp.warp_image(img, f)
t2 = time.perf_counter()
fpiwarp.warp_image(img, f)
t3 = time.perf_counter()
print(fpiwarp.default_backend(), t1 - t0, t2 - t1, t3 - t2)
"""


def first_call():
    """(backend, import s, first 4K call s, second call s) in a new process (after the first ever run)."""
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], capture_output=True, text=True, check=True)
    name, *secs = out.stdout.split()
    return name, *(float(v) for v in secs)


def markdown(result):
    lines = ["# The default call against OpenCV", "", common.machine_line(common.machine_facts()), "",
             f"Default backend here: **{result['default']}** (ranking {result['ranking']}). "
             f"Best of {result['rounds']} interleaved rounds; ratio = time / cv2.remap with precomputed maps "
             "in the same run.", "", "| case | implementation | time | ratio |", "|---|---|---|---|"]
    for r in result["images"]:
        lines.append(f"| {r['case']} | {r['impl']} | {r['seconds'] * 1e3:.2f} ms | {r['ratio']:.2f}x |")
    lines += ["", "| batch | backend | loop | warp_batch | loop / batch |", "|---|---|---|---|---|"]
    for r in result["batches"]:
        lines.append(f"| {r['case']} | {r['impl']} | {r['loop_s'] * 1e3:.1f} ms | {r['batch_s'] * 1e3:.1f} ms | "
                     f"{r['speedup']:.2f}x |")
    if result.get("split"):
        lines += ["", "Where the opencl call's time goes (the kernel alone on a profiling queue, best of the same "
                  "rounds; the rest is the host's work per call):", "",
                  "| case | whole call | kernel alone | rest |", "|---|---|---|---|"]
        for r in result["split"]:
            lines.append(f"| {r['case']} | {r['call_s'] * 1e3:.2f} ms | {r['kernel_s'] * 1e3:.2f} ms | "
                         f"{(r['call_s'] - r['kernel_s']) * 1e3:.2f} ms |")
    name, imp, first, second = result["first_call"]
    lines += ["", f"First default call in a new process (after the first ever run): backend {name}, import "
              f"{imp:.2f} s, first 4K RGB uint8 warp {first:.2f} s (second {second * 1e3:.0f} ms).", "",
              common.CPU_PROFILE_POINTER, ""]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small sizes, one round (a smoke run)")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = p.parse_args(argv)
    backends = [b for b in KERNELS if fpiwarp.backend_status()[b] is None]
    rounds = 1 if args.quick else args.rounds
    big = (216, 384) if args.quick else (2160, 3840)
    images = image_rows(*big, "uint8", rounds, backends) + image_rows(*big, "float32", rounds, backends)
    images += image_rows(64 if args.quick else 256, 64 if args.quick else 256, "uint8", rounds * 10, backends,
                         warper=True)
    n, side = (4, 64) if args.quick else (64, 512)
    small = 64 if args.quick else 256
    split = kernel_split([(*big, "uint8"), (*big, "float32"), (small, small, "uint8")], rounds * 10,
                         images) if "opencl" in backends else []
    result = {"default": fpiwarp.default_backend(), "ranking": fpiwarp.backends.default.ranking(),
              "rounds": rounds, "images": images, "split": split,
              "batches": batch_rows(n, side, side, rounds, backends),
              "first_call": first_call(), "machine": common.machine_facts()}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "default_backend.md").write_text(markdown(result), encoding="utf-8")
    (out / "default_backend.json").write_text(json.dumps(result, indent=1, default=str), encoding="utf-8")
    print(markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
