"""Side by side: the OpenCL warp_image kernel built from two source trees.

``python -m benchmarks.opencl_kernel_ab OLD_KERNELS_DIR NEW_KERNELS_DIR
[--size 4k|1k|256] [--dtype uint8|uint16|float32] [--channels C] [--old-tile X,Y]
[--new-tile X,Y] [--repeat N]`` builds ``fpiwarp.cl`` + ``fpiwarp_map.h`` of each folder (for
instance the kernels/ of another checkout, and this one's) with this
checkout's build options for an FPI warp of a test image (bilinear,
constant border), and times launch + finish of each, interleaved with
``cv2.remap`` on precomputed maps, on the same device buffers. It prints
medians, each kernel's ratio to the first and to cv2.remap, and how many
output values differ from the first kernel's. On a shared machine only the
ratios of one run mean anything, and the position counts: on a 2-core
Zen 5 the second source of a run measured up to 1.07x slower than the
first for the same code, so compare two sources in both orders.

A tile X,Y launches X x Y work-groups (-DFW_LOCAL_X/-DFW_LOCAL_Y; the kernel
must accept them); the default is the backend's one-row width.
"""

import argparse
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.block.codegen import opencl_preamble

from .common import corner_quads, interleaved, machine_facts, machine_line, medians, remap_maps, test_image

SIZES = {"256": (256, 256), "1k": (1024, 1024), "4k": (2160, 3840)}


def build(backend, folder, options, tile):
    """(kernel, local size) of warp_image from ``folder``'s sources."""
    import pyopencl as cl

    folder = Path(folder)
    text = (folder / "fpiwarp.cl").read_text().replace('#include "fpiwarp_map.h"',
                                                        (folder / "fpiwarp_map.h").read_text())
    if tile is not None:
        options = [o for o in options if not o.startswith("-DFW_LOCAL_X=")]
        options += [f"-DFW_LOCAL_X={tile[0]}", f"-DFW_LOCAL_Y={tile[1]}"]
    program = cl.Program(backend.context, opencl_preamble() + text).build(options=list(options))
    return cl.Kernel(program, "warp_image")


def main(argv=None):
    import cv2
    import pyopencl as cl

    from fpiwarp.backends import get_backend

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old")
    parser.add_argument("new")
    parser.add_argument("--size", choices=sorted(SIZES), default="4k")
    parser.add_argument("--dtype", choices=["uint8", "uint16", "float32"], default="uint8")
    parser.add_argument("--channels", type=int, choices=[1, 2, 3, 4], default=3)
    parser.add_argument("--old-tile", type=lambda s: tuple(int(v) for v in s.split(",")))
    parser.add_argument("--new-tile", type=lambda s: tuple(int(v) for v in s.split(",")))
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args(argv)

    be = get_backend("opencl")
    h, w = SIZES[args.size]
    image = test_image(h, w, args.dtype, np.random.default_rng(0), args.channels)
    fpi = fpiwarp.FPI(*corner_quads(h, w))
    block = np.ascontiguousarray(fpi.inverse.params(), dtype=np.float32)
    _, options, local_x = be.image_program(image.dtype, args.channels, 1, "constant", w, False, be.block_kind(block))
    mf = cl.mem_flags
    blk = cl.Buffer(be.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=block)
    src = cl.Buffer(be.context, mf.READ_ONLY, image.nbytes + be.image_slack)
    cl.enqueue_copy(be.queue, src, image)
    runs = {}
    for label, folder, tile in [("old", args.old, args.old_tile), ("new", args.new, args.new_tile)]:
        kern = build(be, folder, options, tile)
        dst = cl.Buffer(be.context, mf.READ_WRITE, image.nbytes)
        kern.set_args(blk, src, np.int32(w), np.int32(h), dst, np.int32(w), np.int32(h),
                      cl.cltypes.make_float4(0, 0, 0, 0))
        local = tile or (local_x, 1)
        glob = (-(-w // local[0]) * local[0], -(-h // local[1]) * local[1])
        runs[label] = (kern, dst, glob, local)
    map_x, map_y = remap_maps(fpi, (h, w))

    def launch(label):
        kern, _, glob, local = runs[label]
        cl.enqueue_nd_range_kernel(be.queue, kern, glob, local)
        be.queue.finish()

    calls = {"old": lambda: launch("old"), "new": lambda: launch("new"),
             "cv2.remap": lambda: cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)}
    times, _ = interleaved(calls, args.repeat * (50 if h * w <= 65536 else 1))
    med = medians(times)
    outputs = {}
    for label, (_, dst, _, _) in runs.items():
        outputs[label] = np.empty_like(image)
        cl.enqueue_copy(be.queue, outputs[label], dst)
    print(machine_line(machine_facts(backends=False)))
    print(f"OpenCL device: {be.device_label}")
    for name in ("old", "new"):
        differ = int(np.count_nonzero(outputs[name] != outputs["old"]))
        print(f"{name:4s} {med[name] * 1e3:9.3f} ms  {med[name] / med['old']:5.2f}x old  "
              f"{med[name] / med['cv2.remap']:5.2f}x cv2.remap  {differ} values differ from old")
    print(f"cv2.remap {med['cv2.remap'] * 1e3:9.3f} ms")


if __name__ == "__main__":
    main()
