"""Device arrays on a CUDA GPU: checks and timings that need one (issue 15).

Run on a machine with an NVIDIA GPU (nothing here runs in CI)::

    python3 -m benchmarks.gpu_arrays [--out DIR] [--sizes 1920x1080,3840x2160] [--repeat 20]

Checks (each PASS/FAIL/SKIP, exit status 1 on any FAIL), for Warp arrays on
"cuda:0" and, where installed, PyTorch and CuPy tensors on the GPU:

- warp_image and map_points return an array of the input's library on the
  same device, equal to the warp backend on the same numpy data;
- zero copy: ``out=`` is returned and its pointer is unchanged
  (``tensor.data_ptr()``, ``cupy.ndarray.data.ptr``, ``wp.array.ptr``),
  ``wp.from_dlpack`` views the tensor at its own pointer, and no host
  array is made (the warp backend's upload and readback fail while the
  device paths run);
- (C, H, W) tensors with ``channels="first"``;
- a CUDA tensor given to backend="opencl" or "numpy" raises
  DeviceMismatchError.

Timings, 4K and 1080p uint8 RGB, bilinear, each frame waited for: numpy in
and out (upload, kernel, readback), device-resident (Warp array, torch
tensor with ``out=``) and the kernel alone (the backend's prepared job),
frames per second and the ratio to the kernel alone (target: device
resident within 1.5x). Results go to DIR/arrays_gpu.md (default
benchmarks/results/).

Batches of device arrays (warp_batch / map_points_batch on Warp, torch and
CuPy stacks; batch vs loop and the 16 x 4K bandwidth) are checked and timed
by :mod:`benchmarks.gpu_batches` in the same run, into the same file.
"""

import argparse
import statistics
import sys
import traceback
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend
from fpiwarp.backends.nvwarp import backend as warp_backend

from . import gpu_batches
from .common import frame_fpi, interleaved, machine_facts, machine_markdown

RESULTS = []


def check(name, fn):
    """Run one check; record PASS, FAIL (with the error) or SKIP."""
    try:
        fn()
    except (_Skip, gpu_batches.Skip) as skip:
        RESULTS.append((name, "SKIP", str(skip)))
    except Exception as exc:  # noqa: BLE001 - reported, the run goes on
        RESULTS.append((name, "FAIL", f"{type(exc).__name__}: {exc}"))
        traceback.print_exc()
    else:
        RESULTS.append((name, "PASS", ""))
    print(*RESULTS[-1], flush=True)


class _Skip(Exception):
    pass


def _library(name):
    try:
        return __import__(name)
    except ImportError as exc:
        raise _Skip(f"{name} not installed ({exc})") from None


class _NoHostCopies:
    """While active, the warp backend's uploads and readbacks raise."""

    def __enter__(self):
        self.saved = warp_backend.Backend._to_device, warp_backend.DeviceWarp.read

        def fail(*args, **kwargs):
            raise AssertionError("a host copy on a device path")

        warp_backend.Backend._to_device = fail
        warp_backend.DeviceWarp.read = fail

    def __exit__(self, *exc):
        warp_backend.Backend._to_device, warp_backend.DeviceWarp.read = self.saved


def _image(h=240, w=320, c=3):
    return np.random.default_rng(1).integers(0, 256, size=(h, w, c), dtype=np.uint8)


def check_warp_cuda():
    wp = warp_backend.warp_module()
    if wp.get_cuda_device_count() == 0:
        raise _Skip("no CUDA device")
    img = _image()
    f = frame_fpi(*img.shape[:2])
    ref = fpiwarp.warp_image(img, f, backend="warp")  # numpy in, numpy out on cuda:0
    arr = wp.array(img, device="cuda:0")
    out = wp.empty(img.shape, dtype=wp.uint8, device="cuda:0")
    ptr = out.ptr
    with _NoHostCopies():
        res = fpiwarp.warp_image(arr, f, out=out)
        new = fpiwarp.warp_image(arr, f)
    assert res is out and out.ptr == ptr and str(new.device) == "cuda:0"
    np.testing.assert_array_equal(out.numpy(), ref)
    np.testing.assert_array_equal(new.numpy(), ref)
    pts = wp.array(np.random.default_rng(2).random((1000, 2)) * 300, dtype=wp.float64, device="cuda:0")
    mapped = fpiwarp.map_points(f, pts)
    np.testing.assert_allclose(mapped.numpy(), f(pts.numpy()), rtol=1e-5, atol=1e-3)


def check_torch():
    torch = _library("torch")
    if not torch.cuda.is_available():
        raise _Skip("torch without CUDA")
    wp = warp_backend.warp_module()
    img = _image()
    f = frame_fpi(*img.shape[:2])
    ref = fpiwarp.warp_image(img, f, backend="warp")
    t = torch.from_numpy(img).cuda()
    assert wp.from_dlpack(t).ptr == t.data_ptr(), "wp.from_dlpack copied the tensor"
    out = torch.empty_like(t)
    ptr = out.data_ptr()
    with _NoHostCopies():
        res = fpiwarp.warp_image(t, f, out=out)
        new = fpiwarp.warp_image(t, f)
        chw = fpiwarp.warp_image(t.permute(2, 0, 1).contiguous(), f, channels="first")
    assert res is out and out.data_ptr() == ptr
    assert isinstance(new, torch.Tensor) and new.device == t.device
    np.testing.assert_array_equal(out.cpu().numpy(), ref)
    np.testing.assert_array_equal(new.cpu().numpy(), ref)
    np.testing.assert_array_equal(chw.permute(1, 2, 0).cpu().numpy(), ref)
    pts = torch.rand(1000, 2, device="cuda") * 300
    mapped = fpiwarp.map_points(f, pts)
    assert mapped.dtype == torch.float32 and mapped.device == pts.device
    np.testing.assert_allclose(mapped.cpu().numpy(), f(pts.cpu().double().numpy()), rtol=1e-5, atol=1e-3)
    for backend in ("opencl", "numpy"):
        try:
            fpiwarp.warp_image(t, f, backend=backend)
        except fpiwarp.DeviceMismatchError:
            pass
        else:
            raise AssertionError(f"a CUDA tensor on backend={backend!r} did not raise DeviceMismatchError")


def check_cupy():
    cp = _library("cupy")
    img = _image()
    f = frame_fpi(*img.shape[:2])
    ref = fpiwarp.warp_image(img, f, backend="warp")
    a = cp.asarray(img)
    out = cp.empty_like(a)
    ptr = out.data.ptr
    with _NoHostCopies():
        res = fpiwarp.warp_image(a, f, out=out)
        new = fpiwarp.warp_image(a, f)
    assert res is out and out.data.ptr == ptr and isinstance(new, cp.ndarray)
    np.testing.assert_array_equal(cp.asnumpy(out), ref)
    np.testing.assert_array_equal(cp.asnumpy(new), ref)


def _median(run, sync, repeat):
    times, _ = interleaved({"run": lambda: (run(), sync())}, repeat)
    return statistics.median(times["run"])


def _methods(wp, be, img, f):
    """{name: (run one frame, wait)} for one frame on the warp backend's GPU."""
    h, w, _ = img.shape
    sync = lambda: wp.synchronize_device(be.device)  # noqa: E731
    arr = wp.array(img, device=be.device)
    out = wp.empty(img.shape, dtype=wp.uint8, device=be.device)
    job = be.prepare_warp(arr, (h, w), order=1, mode="constant", cval=np.zeros(3), out=out)
    methods = {
        "numpy in, numpy out": (lambda: fpiwarp.warp_image(img, f, backend="warp"), sync),
        "Warp array, out=": (lambda: fpiwarp.warp_image(arr, f, out=out), sync),
        "kernel only (new map per frame)": (lambda: (job.set_map(f), job.launch()), sync),
    }
    try:
        import torch
    except ImportError:
        return methods
    if torch.cuda.is_available():
        t = torch.from_numpy(img).cuda()
        tout = torch.empty_like(t)
        methods["torch tensor, out="] = (lambda: fpiwarp.warp_image(t, f, out=tout), torch.cuda.synchronize)
    return methods


def timings(sizes, repeat):
    """[(size, method, seconds)] on cuda:0."""
    wp = warp_backend.warp_module()
    if wp.get_cuda_device_count() == 0:
        return []
    be = get_backend("warp")
    rows = []
    for w, h in sizes:
        img = np.random.default_rng(0).integers(0, 256, size=(h, w, 3), dtype=np.uint8)
        for name, (run, waiter) in _methods(wp, be, img, frame_fpi(h, w)).items():
            rows.append((f"{w}x{h}", name, _median(run, waiter, repeat)))
            print(rows[-1], flush=True)
    return rows


def markdown(rows):
    kernel = {size: s for size, name, s in rows if name.startswith("kernel only")}
    lines = ["# Device arrays on the GPU (benchmarks/gpu_arrays.py)", "", machine_markdown(machine_facts()), "",
             "## Checks", "",
             "| check | result | detail |", "|---|---|---|"]
    lines += [f"| {n} | {r} | {d} |" for n, r, d in RESULTS]
    lines += ["", "## warp_image, uint8 RGB, bilinear, each frame waited for", "",
              "| size | from | ms | frames/s | x kernel only |", "|---|---|---:|---:|---:|"]
    for size, name, s in rows:
        lines.append(f"| {size} | {name} | {s * 1e3:.3f} | {1 / s:.0f} | {s / kernel[size]:.2f} |")
    try:
        dev = get_backend("warp").device
        lines += ["", f"Device: {dev} ({getattr(dev, 'name', '')})"]
    except Exception:  # noqa: BLE001
        pass
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    parser.add_argument("--sizes", default="1920x1080,3840x2160")
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args(argv)
    check("Warp arrays on cuda:0", check_warp_cuda)
    check("PyTorch CUDA tensors", check_torch)
    check("CuPy arrays", check_cupy)
    single = len(RESULTS)
    for name, fn in gpu_batches.CHECKS.items():  # batches of device arrays
        check(name, fn)
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",") if s]
    rows = timings(sizes, args.repeat)
    batch_rows = gpu_batches.timings(max(3, args.repeat // 4))
    batches = RESULTS[single:]
    del RESULTS[single:]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "arrays_gpu.md").write_text(markdown(rows) + gpu_batches.markdown(batches, batch_rows),
                                            encoding="utf-8")
    RESULTS.extend(batches)
    return 1 if any(r == "FAIL" for _, r, _ in RESULTS) else 0


if __name__ == "__main__":
    sys.exit(main())
