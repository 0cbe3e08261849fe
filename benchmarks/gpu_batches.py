"""Batches of device arrays on a CUDA GPU: checks and timings that need one (issue 15).

Run by ``python3 -m benchmarks.gpu_arrays`` (with its single-image checks,
into the same arrays_gpu.md); tests/backends/nvwarp/test_nvwarp_cuda.py runs the checks
under pytest (skipped without CUDA). Checks, each raising on failure or
:class:`Skip` without the hardware or library:

- a Warp stack on cuda:0, N maps of three kinds: one launch per kind, the
  result equal to the per-image loop of warp_image on the same device's
  backend, ``out=`` written in place (pointer unchanged), no readback
  (``wp.array.numpy`` and the runner's host paths fail meanwhile);
  channels-first (N, C, H, W) Warp stacks through the strided kernel;
- a numpy stack on the CUDA backend (copied in and out chunk by chunk,
  here forced to one image per chunk), serial and pipelined (pinned
  staging, two streams), equal to the loop;
- map_points_batch on float64 Warp and float32 torch point sets;
- torch (B, C, H, W) tensors with ``channels="first"`` and ``out=``
  (``data_ptr`` unchanged), CuPy stacks, and DeviceMismatchError for a
  CUDA tensor on "opencl" or "numpy".

Timings (:func:`timings`): 64 images of 512² RGB uint8 with 64 different
FPIs, loop vs one warp_batch, from numpy and from device stacks (target:
≥ 20x on a GPU), and 16 4K frames from numpy in one warp_batch against the
measured host-device copy bandwidth (target: ≥ 60 %), serial and pipelined.
"""

import os

import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend
from fpiwarp.backends.nvwarp import backend as warp_backend

from .common import interleaved

KINDS = ("fpi", "tps_inverse", "compound", "fpi")


class Skip(Exception):
    """The check needs hardware or a library this machine lacks."""


#: Set (to anything) to run the checks on Warp's CPU device: the checks'
#: own logic is tested that way where there is no GPU (tests/backends/nvwarp/test_nvwarp_cuda.py).
ON_CPU_ENV = "FPIWARP_GPU_CHECKS_ON_CPU"


def cuda_backend():
    """(wp, the registry's warp backend) when it runs on CUDA, else Skip."""
    wp = warp_backend.warp_module()
    be = get_backend("warp")
    if os.environ.get(ON_CPU_ENV) and be.device.is_cpu:
        return wp, be
    if wp.get_cuda_device_count() == 0:
        raise Skip("no CUDA device")
    if be.device.is_cpu:
        raise Skip("the warp backend runs on the CPU (FPIWARP_WARP_DEVICE?)")
    return wp, be


def library(name):
    try:
        return __import__(name)
    except ImportError as exc:
        raise Skip(f"{name} not installed ({exc})") from None


def make_maps(n, h, w):
    """n maps cycling through three kinds of block (fpi twice)."""
    src = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    out = []
    for k in range(n):
        d = 0.02 * (k % 7 + 1) * np.array([w, h])
        fpi = fpiwarp.FPI(src, src + np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * d)
        kind = KINDS[k % len(KINDS)]
        if kind == "tps_inverse":
            out.append(fpiwarp.ThinPlateSpline([w / 3 + 1j * h / 3, w / 2 + 1j * h / 2], [0.01, -0.01j * (1 + k % 3)],
                                               (1, 0.02, 1 + 0.05j)).inverse)
        elif kind == "compound":
            out.append(fpi @ fpiwarp.RLinear(1, 0, 1 + 1j))
        else:
            out.append(fpi)
    return out


def stack_of(n, h, w, c=3, seed=1):
    return np.random.default_rng(seed).integers(0, 256, size=(n, h, w, c), dtype=np.uint8)


def loop(stack, maps):
    """The reference: warp_image per image on the (CUDA) warp backend, numpy in and out."""
    return np.stack([fpiwarp.warp_image(im, t, backend="warp") for im, t in zip(stack, maps, strict=True)])


class NoReadback:
    """While active, Warp readbacks and the batch runner's host paths raise."""

    def __init__(self, wp):
        from fpiwarp.backends.nvwarp import batch as warp_batches

        self.patches = [(type(wp.empty(1, device="cpu")), "numpy"), (warp_backend.Backend, "_to_device"),
                        (warp_backend.DeviceWarp, "read"), (warp_batches.BatchRunner, "warp_batch"),
                        (warp_batches.BatchRunner, "map_points_batch")]

    def __enter__(self):
        self.saved = [getattr(owner, name) for owner, name in self.patches]

        def fail(*args, **kwargs):
            raise AssertionError("a host copy on a device path")

        for owner, name in self.patches:
            setattr(owner, name, fail)

    def __exit__(self, *exc):
        for (owner, name), value in zip(self.patches, self.saved, strict=True):
            setattr(owner, name, value)


def check_warp_stacks():
    wp, be = cuda_backend()
    stack = stack_of(6, 90, 120)
    maps = make_maps(6, 90, 120)
    ref = loop(stack, maps)
    arr = wp.array(stack, device=be.device)
    out = wp.empty(stack.shape, dtype=wp.uint8, device=be.device)
    ptr = out.ptr
    runner = be.batches()
    launches, real = [], runner.launch
    runner.launch = lambda kernel, *a: launches.append(kernel) or real(kernel, *a)
    try:
        with NoReadback(wp):
            res = fpiwarp.warp_batch(arr, maps, out=out)
            new = fpiwarp.warp_batch(arr, maps)
            first = fpiwarp.warp_batch(wp.array(np.ascontiguousarray(stack.transpose(0, 3, 1, 2)), device=be.device),
                                       maps, channels="first")
    finally:
        runner.launch = real
    assert res is out and out.ptr == ptr and str(new.device) == str(be.device)
    assert len(launches) == 9, f"{len(launches)} launches for 3 calls of 3 kinds"
    np.testing.assert_array_equal(out.numpy(), ref)
    np.testing.assert_array_equal(new.numpy(), ref)
    np.testing.assert_array_equal(first.numpy().transpose(0, 2, 3, 1), ref)


def check_numpy_stack_on_cuda():
    from fpiwarp.backends.nvwarp import batch as warp_batches

    cuda_backend()
    stack = stack_of(5, 70, 90, 4)
    maps = make_maps(5, 70, 90)
    saved = warp_batches.CHUNK_BYTES, warp_batches.PIPELINE_CHUNK_BYTES
    warp_batches.CHUNK_BYTES = warp_batches.PIPELINE_CHUNK_BYTES = 1  # one image per chunk
    try:
        got = fpiwarp.warp_batch(stack, maps, backend="warp")
        piped = get_backend("warp").warp_batch(stack, maps, stack.shape[1:3], order=1, mode="constant",
                                               cval=np.zeros(4), transfer="pipelined")
    finally:
        warp_batches.CHUNK_BYTES, warp_batches.PIPELINE_CHUNK_BYTES = saved
    expected = loop(stack, maps)
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(piped, expected)


def check_warp_points():
    wp, be = cuda_backend()
    pts = np.random.default_rng(3).uniform(-10, 130, size=(4, 500, 2))
    maps = make_maps(4, 90, 120)
    ref = np.stack([fpiwarp.map_points(t, p, backend="warp") for t, p in zip(maps, pts, strict=True)])
    arr = wp.array(pts, dtype=wp.float64, device=be.device)
    out = wp.empty_like(arr)
    with NoReadback(wp):
        res = fpiwarp.map_points_batch(maps, arr, out=out)
    assert res is out
    np.testing.assert_array_equal(out.numpy(), ref)


def check_torch_batches():
    torch = library("torch")
    wp, be = cuda_backend()
    stack = stack_of(4, 64, 80)
    maps = make_maps(4, 64, 80)
    ref = loop(stack, maps)
    t = torch.from_numpy(stack).cuda().permute(0, 3, 1, 2).contiguous()  # (B, C, H, W)
    assert wp.from_dlpack(t).ptr == t.data_ptr(), "wp.from_dlpack copied the tensor"
    out = torch.empty_like(t)
    ptr = out.data_ptr()
    with NoReadback(wp):
        res = fpiwarp.warp_batch(t, maps, channels="first", out=out)
        new = fpiwarp.warp_batch(t, maps, channels="first")
        pts = torch.rand(4, 300, 2, device="cuda") * 80
        mapped = fpiwarp.map_points_batch(maps, pts)
    assert res is out and out.data_ptr() == ptr and isinstance(new, torch.Tensor) and new.device == t.device
    np.testing.assert_array_equal(out.permute(0, 2, 3, 1).cpu().numpy(), ref)
    np.testing.assert_array_equal(new.permute(0, 2, 3, 1).cpu().numpy(), ref)
    assert mapped.dtype == torch.float32 and mapped.device == pts.device
    expected = [fpiwarp.map_points(m, p) for m, p in zip(maps, pts, strict=True)]
    np.testing.assert_array_equal(mapped.cpu().numpy(), torch.stack(expected).cpu().numpy())
    for backend in ("opencl", "numpy"):
        try:
            fpiwarp.warp_batch(t, maps, backend=backend, channels="first")
        except fpiwarp.DeviceMismatchError:
            continue
        raise AssertionError(f"a CUDA batch on backend={backend!r} did not raise DeviceMismatchError")


def check_cupy_batches():
    cp = library("cupy")
    cuda_backend()
    stack = stack_of(3, 50, 60)
    maps = make_maps(3, 50, 60)
    a = cp.asarray(stack)
    out = cp.empty_like(a)
    ptr = out.data.ptr
    res = fpiwarp.warp_batch(a, maps, out=out)
    assert res is out and out.data.ptr == ptr
    np.testing.assert_array_equal(cp.asnumpy(out), loop(stack, maps))


CHECKS = {
    "warp_batch on Warp stacks on cuda:0 (one launch per kind, out=, channels first)": check_warp_stacks,
    "warp_batch on a numpy stack on the CUDA backend (chunks; serial and pipelined transfers)":
        check_numpy_stack_on_cuda,
    "map_points_batch on Warp points on cuda:0": check_warp_points,
    "warp_batch / map_points_batch on torch (B, C, H, W) CUDA tensors": check_torch_batches,
    "warp_batch on CuPy stacks": check_cupy_batches,
}


def _best(fn, sync, repeat):
    times, _ = interleaved({"run": lambda: (fn(), sync())}, repeat)
    return min(times["run"])


def timings(repeat=5):
    """[(what, seconds, note)] on cuda:0; [] without CUDA."""
    try:
        wp, be = cuda_backend()
    except Skip:
        return []
    sync = lambda: wp.synchronize_device(be.device)  # noqa: E731
    rows = []
    stack = stack_of(64, 512, 512)
    maps = make_maps(64, 512, 512)
    dev, dev_out = wp.array(stack, device=be.device), wp.empty(stack.shape, dtype=wp.uint8, device=be.device)
    singles = [(wp.array(im, device=be.device), wp.empty(im.shape, dtype=wp.uint8, device=be.device)) for im in stack]

    def device_loop():
        for (img, out), t in zip(singles, maps, strict=True):
            fpiwarp.warp_image(img, t, out=out)

    for what, fn in [("64x512² loop, numpy", lambda: loop(stack, maps)),
                     ("64x512² warp_batch, numpy", lambda: fpiwarp.warp_batch(stack, maps, backend="warp")),
                     ("64x512² loop, Warp arrays", device_loop),
                     ("64x512² warp_batch, Warp stack", lambda: fpiwarp.warp_batch(dev, maps, out=dev_out))]:
        rows.append((what, _best(fn, sync, repeat), ""))
        print(rows[-1], flush=True)
    frames = stack_of(16, 2160, 3840)
    fmaps = make_maps(16, 2160, 3840)[:1] * 16
    copy_s = _best(lambda: wp.array(frames, device=be.device).numpy(), sync, repeat)  # the same bytes up and down
    batch_s = _best(lambda: fpiwarp.warp_batch(frames, fmaps, backend="warp"), sync, repeat)
    piped_s = _best(lambda: be.warp_batch(frames, fmaps, frames.shape[1:3], order=1, mode="constant",
                                          cval=np.zeros(3), transfer="pipelined"), sync, repeat)
    rows.append(("16x4K copy up and down (wp.array, .numpy)", copy_s, f"{2 * frames.nbytes / copy_s / 1e9:.1f} GB/s"))
    rows.append(("16x4K warp_batch, numpy (serial transfers)", batch_s, f"{copy_s / batch_s:.0%} of the copies' "
                 "bandwidth"))
    rows.append(("16x4K warp_batch, numpy (pipelined transfers)", piped_s, f"{copy_s / piped_s:.0%} of the copies' "
                 "bandwidth (target ≥ 60 %)"))
    print(rows[-3:], flush=True)
    return rows


def markdown(results, rows):
    """The batch section of arrays_gpu.md: check results, then timings with the ratios."""
    lines = ["", "## Batches (benchmarks/gpu_batches.py)", "", "| check | result | detail |", "|---|---|---|"]
    lines += [f"| {n} | {r} | {d} |" for n, r, d in results]
    if rows:
        t = {what: s for what, s, _ in rows}
        lines += ["", "| what | ms | note |", "|---|---:|---|"]
        lines += [f"| {what} | {s * 1e3:.2f} | {note} |" for what, s, note in rows]
        host = t["64x512² loop, numpy"] / t["64x512² warp_batch, numpy"]
        device = t["64x512² loop, Warp arrays"] / t["64x512² warp_batch, Warp stack"]
        lines += ["", f"Batch speed-up over the loop: numpy {host:.1f}x, device arrays {device:.1f}x "
                  "(target ≥ 20x on a GPU)."]
    return "\n".join(lines) + "\n"
