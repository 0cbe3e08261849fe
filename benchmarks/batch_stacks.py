"""Stacks in one call: ``fpiwarp.warp_batch`` against the per-image loop.

- ``64 maps``: 64 images of 512² RGB uint8, each with its own FPI (64
  different maps of one kind), bilinear: the per-image loop of
  ``fpiwarp.warp_image`` and one ``fpiwarp.warp_batch`` call, per backend,
  with their ratio. Every batch is checked bit for bit against its loop.
- ``frames``: batches of 1080p and 4K RGB uint8 frames with one map each,
  in frames per second (batch and loop) on the device backends.
- ``opencl transfers``: the 64-map batch on the opencl backend through
  each way of reaching the device (``zero_copy``, ``serial`` and
  ``pipelined``, see :mod:`fpiwarp.backends.opencl.batch`).

Run alone with ``python -m benchmarks --only batch`` (writes batch.md and
batch.json). On a machine with CUDA or an OpenCL GPU the backends pick the
GPU by themselves (Warp: ``cuda:0``; OpenCL: GPUs first), so the same
command measures them there. Numbers on a shared machine are noisy:
compare ratios within one run (loop and batch are timed in turn, the
fastest of several calls each).
"""


import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend

from .common import interleaved, random_frame_maps, test_image

FULL = {"stack": (64, 512, 512), "frames": [(8, 1080, 1920), (4, 2160, 3840)], "repeats": 5}
QUICK = {"stack": (8, 64, 64), "frames": [(2, 96, 128)], "repeats": 1}
FRAME_BACKENDS = ("opencl", "warp", "gl")
#: How each backend runs a batch of N different maps.
HOW = {
    "numpy": "one call, each image sampled in turn",
    "opencl": "one launch per kind of map",
    "warp": "one launch per kind of map (the per-kind kernels, as the loop)",
    "gl": "one instanced draw per kind of map",
}


def _loop(stack, maps, backend):
    return np.stack([fpiwarp.warp_image(im, t, backend=backend) for im, t in zip(stack, maps)])


def paired(fns, repeats):
    """[(seconds of the fastest call, last result)] for each of ``fns``, called
    in rounds after a warm-up (:func:`benchmarks.common.interleaved`)."""
    times, results = interleaved(dict(enumerate(fns)), repeats)
    return [(min(times[i]), results[i]) for i in range(len(fns))]


def maps_case(sizes):
    """The ``64 maps`` case of ``sizes``: (the (N, H, W, 3) uint8 stack, its N FPIs)."""
    n, h, w = sizes["stack"]
    rng = np.random.default_rng(1)
    stack = np.stack([test_image(h, w, "uint8", rng) for _ in range(n)])
    return stack, random_frame_maps(n, h, w)


def run_maps(backends, sizes, log=print):
    """The ``64 maps`` rows: loop and batch seconds per backend, and whether equal."""
    n, h, w = sizes["stack"]
    stack, maps = maps_case(sizes)
    rows = []
    for backend in backends:
        (loop_s, expected), (batch_s, got) = paired(
            [lambda b=backend: _loop(stack, maps, b), lambda b=backend: fpiwarp.warp_batch(stack, maps, backend=b)],
            sizes["repeats"])
        rows.append({"backend": backend, "n": n, "size": [h, w], "loop_s": loop_s, "batch_s": batch_s,
                     "speedup": loop_s / batch_s, "equal": bool(np.array_equal(got, expected))})
        log(f"batch {n}x{h}x{w} {backend}: loop {loop_s * 1e3:.0f} ms, batch {batch_s * 1e3:.0f} ms")
    return rows


def run_frames(backends, sizes, log=print):
    """The ``frames`` rows: frames per second of batch and loop."""
    rows = []
    for n, h, w in sizes["frames"]:
        rng = np.random.default_rng(2)
        frame = test_image(h, w, "uint8", rng)
        stack = np.stack([np.roll(frame, 7 * i, axis=1) for i in range(n)])
        maps = random_frame_maps(n, h, w, seed=3)
        for backend in backends:
            (loop_s, _), (batch_s, _) = paired(
                [lambda b=backend, s=stack, m=maps: _loop(s, m, b),
                 lambda b=backend, s=stack, m=maps: fpiwarp.warp_batch(s, m, backend=b)], sizes["repeats"])
            rows.append({"backend": backend, "n": n, "size": [h, w], "loop_fps": n / loop_s,
                         "batch_fps": n / batch_s})
            log(f"frames {n}x{h}x{w} {backend}: loop {n / loop_s:.1f} fps, batch {n / batch_s:.1f} fps")
    return rows


def run_transfers(sizes, log=print):
    """The ``opencl transfers`` rows: seconds of the 64-map batch per transfer."""
    n, h, w = sizes["stack"]
    stack, maps = maps_case(sizes)
    backend = get_backend("opencl")
    cval = np.zeros(3)
    transfers = ("zero_copy", "serial", "pipelined")
    calls = [lambda t=t: backend.warp_batch(stack, maps, (h, w), order=1, mode="constant", cval=cval, transfer=t)
             for t in transfers]
    rows = []
    for transfer, (seconds, _) in zip(transfers, paired(calls, sizes["repeats"]), strict=True):
        rows.append({"transfer": transfer, "seconds": seconds, "bytes": 2 * stack.nbytes})
        log(f"opencl transfer {transfer}: {seconds * 1e3:.0f} ms")
    return rows


def run(quick=False, backends=None, log=print):
    """Every part; a dict for :func:`markdown` and JSON."""
    sizes = QUICK if quick else FULL
    available = fpiwarp.available_backends()
    backends = [b for b in (backends or available) if b in available]
    result = {"sizes": sizes, "maps": run_maps(backends, sizes, log)}
    devices = [b for b in backends if b in FRAME_BACKENDS]
    result["frames"] = run_frames(devices, sizes, log)
    result["transfers"] = run_transfers(sizes, log) if "opencl" in backends else []
    return result


def markdown(result, machine_md=""):
    """The tables of batch.md."""
    n, h, w = result["sizes"]["stack"]
    lines = ["# Stacks in one call: warp_batch vs the per-image loop", "", machine_md, "",
             f"## {n} images of {w}x{h} RGB uint8, {n} different maps (bilinear)", "",
             "| backend | warp_batch runs | loop of warp_image | warp_batch | batch speed-up | batch == loop |",
             "|---|---|---:|---:|---:|:---:|"]
    for r in result["maps"]:
        lines.append(f"| {r['backend']} | {HOW.get(r['backend'], '?')} | {r['loop_s'] * 1e3:.0f} ms | "
                     f"{r['batch_s'] * 1e3:.0f} ms | {r['speedup']:.2f}x | {'yes' if r['equal'] else 'NO'} |")
    if result["frames"]:
        lines += ["", "## Frames per second (one map per frame, bilinear, RGB uint8)", "",
                  "| backend | batch | loop fps | batch fps |", "|---|---|---:|---:|"]
        for r in result["frames"]:
            lines.append(f"| {r['backend']} | {r['n']} x {r['size'][1]}x{r['size'][0]} | {r['loop_fps']:.1f} | "
                         f"{r['batch_fps']:.1f} |")
    if result["transfers"]:
        lines += ["", f"## opencl: the {n}-map batch by way of transfer", "",
                  "| transfer | time | host bytes moved per second |", "|---|---:|---:|"]
        for r in result["transfers"]:
            rate = r["bytes"] / r["seconds"] / 1e9
            lines.append(f"| {r['transfer']} | {r['seconds'] * 1e3:.0f} ms | {rate:.2f} GB/s |")
    lines.append("")
    return "\n".join(lines)
