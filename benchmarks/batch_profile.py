"""Where the time of a batch goes: the 64-map stack of :mod:`benchmarks.batch_stacks`
(64 images of 512² RGB uint8, 64 different FPIs, bilinear) on each device
backend, timed in turn in one run (the fastest of a few calls each):

- ``loop``: the per-image loop of ``fpiwarp.warp_image`` on numpy images;
- ``loop, device arrays``: the same loop on images already on the device
  (pyopencl / Warp arrays, ``out=`` kept): no host copies, all the per-call
  Python and validation;
- ``kernels only``: one image prepared on the device once
  (``prepare_warp``), then ``set_map`` + ``launch`` for each of the 64 maps
  and one wait: the kernels and the block uploads, nothing else;
- ``batch``: one ``fpiwarp.warp_batch`` call on the numpy stack;
- ``batch, device arrays``: one ``warp_batch`` on the stack already on the
  device, into a kept ``out=``.

``loop / kernels only`` bounds what any batching can gain over the loop on
that device; ``batch - batch, device arrays`` is what the host stack costs
(copies in and out). Run: ``python -m benchmarks.batch_profile [--quick]``.
"""

import argparse

import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend

from .batch_stacks import FULL, QUICK, maps_case
from .common import bests, interleaved, machine_facts, machine_markdown

PARTS = ("loop", "loop, device arrays", "kernels only", "batch", "batch, device arrays")


def _device(backend, stack):
    """(the stack on the device, a kept output stack there, [(image, out)]
    on the device one by one, a function that waits for the device)."""
    if backend == "opencl":
        from pyopencl import array as cla

        from fpiwarp.arrays import opencl_queue, to_opencl

        singles = [(to_opencl(im), cla.empty(opencl_queue(), im.shape, im.dtype)) for im in stack]
        return to_opencl(stack), cla.empty(opencl_queue(), stack.shape, stack.dtype), singles, opencl_queue().finish
    from fpiwarp.backends.nvwarp import backend as warp_backend

    wp = warp_backend.warp_module()
    device = get_backend("warp").device
    singles = [(wp.array(im, device=device), wp.empty(im.shape, dtype=wp.uint8, device=device)) for im in stack]
    return (wp.array(stack, device=device), wp.empty(stack.shape, dtype=wp.uint8, device=device), singles,
            lambda: wp.synchronize_device(device))


def parts(backend, stack, maps):
    """{part: a function running it once} for one backend."""
    be = get_backend(backend)
    dev, dev_out, singles, wait = _device(backend, stack)
    job = be.prepare_warp(stack[0], stack.shape[1:3], order=1, mode="constant", cval=np.zeros(3))

    def kernels():
        for t in maps:
            job.set_map(t)
            job.launch()
        job.finish()

    def device_loop():
        for (img, out), t in zip(singles, maps, strict=True):
            fpiwarp.warp_image(img, t, out=out)
        wait()

    def device_batch():
        fpiwarp.warp_batch(dev, maps, out=dev_out)
        wait()

    return {
        "loop": lambda: [fpiwarp.warp_image(im, t, backend=backend) for im, t in zip(stack, maps, strict=True)],
        "loop, device arrays": device_loop,
        "kernels only": kernels,
        "batch": lambda: fpiwarp.warp_batch(stack, maps, backend=backend),
        "batch, device arrays": device_batch,
    }


def run(quick=False, backends=("opencl", "warp"), log=print):
    """[{backend, part: seconds}] timed in turn, the fastest of the repeats."""
    sizes = QUICK if quick else FULL
    n, h, w = sizes["stack"]
    stack, maps = maps_case(sizes)
    rows = []
    for backend in [b for b in backends if b in fpiwarp.available_backends()]:
        times, _ = interleaved(parts(backend, stack, maps), sizes["repeats"])  # warm-up: kernels compiled, buffers kept
        best = bests(times)
        rows.append({"backend": backend, **best})
        log(f"{backend} {n}x{h}x{w}: " + ", ".join(f"{k} {v * 1e3:.0f} ms" for k, v in best.items()))
    return rows


def markdown(rows):
    """A table of the parts and the two ratios that say what is left."""
    lines = [machine_markdown(machine_facts()), "",
             "| backend | " + " | ".join(PARTS) + " | loop / kernels only | loop / batch |",
             "|---|" + "---:|" * (len(PARTS) + 2)]
    for r in rows:
        cells = " | ".join(f"{r[p] * 1e3:.0f} ms" for p in PARTS)
        lines.append(f"| {r['backend']} | {cells} | {r['loop'] / r['kernels only']:.2f}x | "
                     f"{r['loop'] / r['batch']:.2f}x |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--backends", default="opencl,warp")
    args = parser.parse_args()
    print(markdown(run(args.quick, tuple(args.backends.split(",")))))
