"""Arrays on devices: warp_image end to end from each kind of array, beside the kernel alone.

Per backend, an FPI warp of a uint8 RGB frame (bilinear, constant border)
at 1080p and 4K (256² with ``--quick``), three ways, each frame waited for:

- "numpy": ``warp_image(ndarray, backend=...)``, upload and readback included;
- "device": ``warp_image(device_array, out=device_out)`` with the frame
  already on the backend's device and the result left there: a
  ``pyopencl.array.Array`` made by ``fpiwarp.arrays.to_opencl`` (opencl), a Warp array (warp), a
  ``moderngl.Texture`` (gl), and a JAX CPU array (warp, through DLPack)
  where JAX is installed;
- "kernel only": the backend's prepared job (``prepare_warp``:
  ``set_map`` + ``launch`` + ``finish``) with image and output on the
  device, i.e. what the kernel costs with the same map upload per frame
  (opencl and warp; the gl backend has no such job).

Medians over the repeats, methods round-robin; frames per second and the
ratio to the kernel-only time. On this machine every "device" is the CPU
(PoCL, Warp's CPU device, llvmpipe), so "device" and "numpy" differ by
the copies the CPU paths still make; the GPU figures come from
``benchmarks/gpu_arrays.py`` on a machine with one.
"""

import numpy as np

import fpiwarp
from fpiwarp.backends import backend_status, get_backend

from .common import frame_fpi, interleaved, medians

SIZES = {"1080p": (1080, 1920), "4K": (2160, 3840)}
QUICK_SIZES = {"256²": (256, 256)}


def _methods(backend, img, f):
    """{method: (run one frame, wait)} for one backend and frame."""
    h, w, c = img.shape
    zeros = np.zeros(c)
    methods = {"numpy": (lambda: fpiwarp.warp_image(img, f, backend=backend), lambda: None)}
    be = get_backend(backend)
    if backend == "opencl":
        from pyopencl import array as cla

        from fpiwarp.arrays import opencl_queue, to_opencl

        queue = opencl_queue()
        dev, out = to_opencl(img), cla.empty(queue, img.shape, img.dtype)
        methods["device"] = (lambda: fpiwarp.warp_image(dev, f, out=out), queue.finish)
        job = be.prepare_warp(img, (h, w), order=1, mode="constant", cval=zeros)
        methods["kernel only"] = (lambda: (job.set_map(f), job.launch()), job.finish)
    elif backend == "warp":
        wp = __import__("warp")
        dev = wp.array(img, device=be.device)
        out = wp.empty(img.shape, dtype=wp.uint8, device=be.device)
        sync = lambda: wp.synchronize_device(be.device)  # noqa: E731
        methods["device"] = (lambda: fpiwarp.warp_image(dev, f, out=out), sync)
        try:
            import jax.numpy as jnp
        except ImportError:
            pass
        else:
            jimg = jnp.asarray(img)
            methods["device (JAX via DLPack)"] = (lambda: fpiwarp.warp_image(jimg, f).block_until_ready(), sync)
        job = be.prepare_warp(dev, (h, w), order=1, mode="constant", cval=zeros, out=out)
        methods["kernel only"] = (lambda: (job.set_map(f), job.launch()), job.finish)
    elif backend == "gl":
        ctx = be.ctx
        tex = ctx.texture((w, h), c, img.tobytes(), dtype="f1")
        out = ctx.texture((w, h), c, dtype="f1")
        methods["device"] = (lambda: fpiwarp.warp_image(tex, f, out=out), ctx.finish)
    return methods


def _time(methods, repeat):
    """Median seconds of each (run, wait) pair, round-robin after a warm-up."""
    times, _ = interleaved({name: (lambda r=run, s=sync: (r(), s())) for name, (run, sync) in methods.items()}, repeat)
    return medians(times)


def run(quick=False, backends=None, log=print):
    """[{backend, size, method, seconds}] for every available kernel backend."""
    sizes = QUICK_SIZES if quick else SIZES
    repeat = 3 if quick else 7
    status = backend_status()
    names = [b for b in (backends or ("opencl", "warp", "gl")) if b != "numpy" and status.get(b) is None]
    rows = []
    rng = np.random.default_rng(0)
    for label, (h, w) in sizes.items():
        img = rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8)
        f = frame_fpi(h, w)
        for backend in names:
            try:
                medians = _time(_methods(backend, img, f), repeat)
            except Exception as exc:  # a backend that fails is recorded, the run goes on
                rows.append({"backend": backend, "size": label, "method": "error", "seconds": None,
                             "error": f"{type(exc).__name__}: {exc}"})
                continue
            for method, seconds in medians.items():
                rows.append({"backend": backend, "size": label, "method": method, "seconds": seconds})
            log(f"arrays {backend} {label}: " + ", ".join(f"{m} {s * 1e3:.1f} ms" for m, s in medians.items()))
    return rows


def markdown(rows, machine_md=""):
    """The table: ms, frames per second and ratio to the kernel-only time."""
    kernel = {(r["backend"], r["size"]): r["seconds"] for r in rows if r["method"] == "kernel only"}
    lines = ["# Arrays on devices: end to end from each kind of array", "", __doc__.split("\n\n", 1)[1].strip(), "",
             "| backend | size | from | ms | frames/s | × kernel only |", "|---|---|---|---:|---:|---:|"]
    for r in rows:
        if r["seconds"] is None:
            lines.append(f"| {r['backend']} | {r['size']} | {r['method']} | {r.get('error', '')} | | |")
            continue
        k = kernel.get((r["backend"], r["size"]))
        ratio = f"{r['seconds'] / k:.2f}" if k else "n/a"
        lines.append(f"| {r['backend']} | {r['size']} | {r['method']} | {r['seconds'] * 1e3:.2f} | "
                     f"{1.0 / r['seconds']:.1f} | {ratio} |")
    return "\n".join(lines + ["", machine_md]).rstrip() + "\n"
