"""GPU figures: every available backend at 1080p and 4K, end to end and on the device.

For each backend, RGB and RGBA uint8 images warped by a generic FPI
(bilinear, constant border):

- "end to end": ``warp_image`` from a numpy array to a numpy array, the
  upload, the kernel and the readback included (what the library call costs);
- "on device, new map per frame": the same kernel with the image already on
  the device and the result left there, a new map solved on the host and
  its parameters uploaded every frame, each frame waited for (the preview's
  frame while a corner is dragged): Warp and OpenCL relaunch the backend's
  own kernel through its public ``prepare_warp`` job; GL draws with
  :class:`fpiwarp.viewer.Renderer` into an offscreen framebuffer;
- "on device, kernel only": one map, launches back to back (GL: each draw
  waited for), i.e. the kernel's own throughput;

Each backend runs in a Python process of its own (``--one-process`` to
share one): two GPU APIs in one process slowed each other's transfers.
- cv2.remap with maps precomputed outside the timing, on this machine's
  CPU, as the reference row.

Waiting is ``wp.synchronize_device`` (Warp), ``queue.finish`` (OpenCL),
``ctx.finish`` (GL). Methods run round-robin; medians per method.

Usage::

    python3 -m benchmarks.gpu [--sizes 1920x1080,3840x2160] [--repeat 7] [--frames 50]
"""

import argparse
import functools
import statistics

import numpy as np

import fpiwarp
from fpiwarp.backends import backend_status, get_backend

from .common import frame_fpi, frames, interleaved, machine_facts, machine_markdown, remap_call


def kernel_on_device(be, img, w, h, n, new_map):
    """Per-frame time of a backend's own kernel on an image kept on the
    device (``Backend.prepare_warp``: Warp and OpenCL), a new map uploaded
    per frame when ``new_map``."""
    job = be.prepare_warp(img, (h, w), order=1, mode="constant", cval=np.zeros(img.shape[2]))
    job.set_map(frame_fpi(h, w))

    def launch(k):
        if new_map:
            job.set_map(frame_fpi(h, w, k % 8))
        job.launch()

    return frames(n, launch, job.finish, each=new_map)


def gl_on_device(be, img, w, h, n, new_map):
    """Per-frame time of the preview Renderer drawing into an offscreen target."""
    from fpiwarp.viewer import Renderer

    warper = be.warper
    ctx = warper.ctx
    renderer = Renderer(ctx, order=1, warper=warper)
    tex = ctx.texture((w, h), 4, dtype="f1")
    fbo = ctx.framebuffer(color_attachments=[tex])
    try:
        renderer.set_image(img)
        renderer.set_transform(frame_fpi(h, w))
        fbo.use()

        def launch(k):
            if new_map:
                renderer.set_transform(frame_fpi(h, w, k % 8))
            renderer.draw((0, 0, w, h), y_down=True)

        # every frame waited for: llvmpipe skips drawing a full-screen frame
        # that the next draw of the same scene covers
        return frames(n, launch, ctx.finish)
    finally:
        renderer.release()
        fbo.release()
        tex.release()


ON_DEVICE = {"warp": kernel_on_device, "opencl": kernel_on_device, "gl": gl_on_device}


def device_of(name, be):
    if name == "warp":
        return f"warp {be.device}"
    if name == "opencl":
        return be.device_label
    return be.warper.ctx.info["GL_RENDERER"]


def run(sizes, repeat, frames, backends):
    rows = []
    for w, h in sizes:
        for channels in (3, 4):
            img = np.random.default_rng(0).integers(0, 256, (h, w, channels), dtype=np.uint8)
            f = frame_fpi(h, w)
            methods = {}
            try:
                methods["cv2.remap, precomputed maps (CPU)"] = remap_call(img, f)
            except ImportError:
                print("(cv2 not installed: pip install opencv-python-headless for the reference row)")
            for name in backends:
                be = get_backend(name)
                methods[f"{name} end to end"] = functools.partial(
                    fpiwarp.warp_image, img, f, (h, w), order=1, mode="constant", cval=0, backend=name)
                for label, new_map in (("on device, new map per frame", True), ("on device, kernel only", False)):
                    methods[f"{name} {label}"] = functools.partial(ON_DEVICE[name], be, img, w, h, frames, new_map)
            # the on-device methods return their own per-frame time; the others are timed as a whole
            times, outs = {k: [] for k in methods}, {}
            for _ in range(repeat):
                walls, outs = interleaved(methods, 1, warm_up=not outs)
                for k, dt in walls.items():
                    times[k].append(outs[k] if isinstance(outs[k], float) else dt[0])
            for k, ts in times.items():
                rows.append((f"{w}x{h}", channels, k, statistics.median(ts), min(ts)))
    return rows


def markdown(rows, devices):
    lines = ["| size | channels | method | median ms | min ms | frames/s | GB/s (in + out) | speed-up vs cv2.remap |",
             "|---|---:|---|---:|---:|---:|---:|---:|"]
    base = {(r[0], r[1]): r[3] for r in rows if r[2].startswith("cv2")}
    for size, c, name, med, best in rows:
        w, h = (int(v) for v in size.split("x"))
        gbs = 2 * w * h * c / med / 1e9
        ref = base.get((size, c))
        ratio = f"{ref / med:.2f}x" if ref else "n/a"
        cells = [size, c, name, f"{med * 1e3:.2f}", f"{best * 1e3:.2f}", f"{1 / med:.0f}", f"{gbs:.1f}", ratio]
        lines.append("| " + " | ".join(str(v) for v in cells) + " |")
    dev = "\n".join(f"- {k}: {v}" for k, v in devices.items())
    return machine_markdown(machine_facts(backends=False)) + "\n\nDevices:\n" + dev + "\n\n" + "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default="1920x1080,3840x2160", help="comma-separated WxH list")
    parser.add_argument("--repeat", type=int, default=7, help="timed rounds per method")
    parser.add_argument("--frames", type=int, default=50, help="launches per 'on device' timing")
    parser.add_argument("--backends", default="opencl,warp,gl", help="comma-separated backends to time")
    parser.add_argument("--out", help="also write the tables to this markdown file")
    parser.add_argument(
        "--one-process",
        action="store_true",
        help="time all backends in this process (by default each runs in its own: two GPU "
        "APIs in one process slow each other's transfers)",
    )
    args = parser.parse_args(argv)
    names = [b for b in args.backends.split(",") if b]
    if len(names) > 1 and not args.one_process:
        text = "\n".join(_in_own_process(name, args) for name in names)
    else:
        text = _tables(names, args)
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text)


def _tables(names, args):
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",")]
    status = backend_status()
    backends = []
    for name in names:
        if status.get(name) is None:
            backends.append(name)
        else:
            print(f"skipping {name}: {status.get(name, 'unknown backend')}")
    devices = {name: device_of(name, get_backend(name)) for name in backends}
    return markdown(run(sizes, args.repeat, args.frames, backends), devices)


def _in_own_process(name, args):
    """The tables of one backend, timed by a fresh Python process."""
    import subprocess
    import sys

    cmd = [
        sys.executable,
        "-m",
        __spec__.name,
        "--backends",
        name,
        "--sizes",
        args.sizes,
        "--repeat",
        str(args.repeat),
        "--frames",
        str(args.frames),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)  # a failure is reported, not raised
    if done.returncode != 0:
        return (
            f"## {name}\n\nfailed: {done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode}\n"
        )
    return f"## {name}\n\n{done.stdout.strip()}\n"


if __name__ == "__main__":
    main()
