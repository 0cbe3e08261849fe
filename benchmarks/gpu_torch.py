"""fpiwarp.torch on a CUDA device: the checks that need one, then timings. One command:

    python3 -m benchmarks.gpu_torch            # on a machine with a CUDA GPU
    python3 -m benchmarks.gpu_torch --device cpu --size 128   # a dry run of the same script

1. runs tests/torch_warps/test_torch_grad.py (its CUDA tests: bit-identical
   backward twice, agreement with the CPU), then, here, on the device:
2. parity of the forward with the CPU (float32 and float64, every order and mode);
3. bit-identical image and corner gradients over five backward passes, also
   with ``torch.use_deterministic_algorithms(True)`` (which would raise on
   an op PyTorch knows to be nondeterministic);
4. timings (synchronised) of forward + backward at 512² RGB float32, batch 8:
   fpiwarp vs grid_sample (free grid) vs kornia warp_perspective, interleaved;
   and whether grid_sample's own CUDA backward is deterministic (it is not: pytorch #68959).

Writes benchmarks/results/gpu_torch.md.
"""

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

import torch

import fpiwarp.torch as ft

from .torch_autodiff import corners

RESULTS = Path(__file__).resolve().parent / "results" / "gpu_torch.md"
MODES = ("constant", "edge", "reflect", "wrap")


def sync(device):
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def parity(device, lines):
    g = torch.Generator().manual_seed(0)
    src, dst = corners(48, 2)
    img = torch.rand(2, 3, 40, 44, generator=g, dtype=torch.float64)
    worst = 0.0
    for dtype, tol in ((torch.float64, 1e-9), (torch.float32, 1e-4)):
        for order in (0, 1, 3):
            for mode in MODES:
                cpu = ft.warp_image(img.to(dtype), src, dst, (50, 60), order=order, mode=mode, cval=0.3)
                dev = ft.warp_image(img.to(device, dtype), src.to(device), dst.to(device), (50, 60), order=order,
                                    mode=mode, cval=0.3)
                err = float((dev.cpu() - cpu).abs().max())
                worst = max(worst, err / tol)
                if err > tol:
                    lines.append(f"- FAIL parity {dtype} order {order} {mode}: {err:.3g} > {tol:g}")
    verdict = "ok" if worst <= 1 else "FAIL"
    lines.append(f"- forward parity with the CPU: worst error / tolerance = {worst:.3g} ({verdict})")
    return worst <= 1


def determinism(device, lines, deterministic_mode):
    src, dst = corners(96, 4)
    g = torch.Generator().manual_seed(1)
    img = torch.rand(4, 3, 80, 90, generator=g).to(device).requires_grad_()
    dst = dst.to(device).requires_grad_()
    ok = True
    torch.use_deterministic_algorithms(deterministic_mode)
    try:
        for order in (1, 3):
            for mode in MODES:
                grads = []
                for _ in range(5):
                    img.grad = dst.grad = None
                    out = ft.warp_image(img, src.to(device), dst, (100, 110), order=order, mode=mode)
                    out.backward(torch.linspace(-1, 1, out.numel(), device=device).reshape(out.shape))
                    grads.append((img.grad.clone(), dst.grad.clone()))
                same = all(torch.equal(a[0], b[0]) and torch.equal(a[1], b[1]) for a, b in zip(grads, grads[1:]))
                ok &= same
                if not same:
                    lines.append(f"- FAIL: gradients differ between runs (order {order}, {mode}, "
                                 f"deterministic mode {deterministic_mode})")
    finally:
        torch.use_deterministic_algorithms(False)
    lines.append(f"- bit-identical gradients over 5 backward passes, orders 1 and 3, all modes "
                 f"(use_deterministic_algorithms({deterministic_mode})): {'ok' if ok else 'FAIL'}")
    return ok


def timings(device, size, batch, rounds, lines):
    import kornia

    g = torch.Generator().manual_seed(2)
    image = torch.rand(batch, 3, size, size, generator=g).to(device).requires_grad_()
    src, dst = (t.to(device) for t in corners(size, batch))
    dst_grad = dst.clone().requires_grad_()
    h = kornia.geometry.transform.get_perspective_transform(src.float(), dst.float()).detach().requires_grad_()
    with torch.no_grad():
        ys, xs = torch.meshgrid(torch.arange(size, dtype=torch.float64, device=device),
                                torch.arange(size, dtype=torch.float64, device=device), indexing="ij")
        pix = torch.stack([xs, ys], -1).reshape(1, -1, 2)
        grid = ((2 * ft.inverse_points(pix, src, dst).reshape(batch, size, size, 2) + 1) / size - 1).float()
    fns = {
        "fpiwarp (image grad)": lambda: ft.warp_image(image, src, dst).sum().backward(),
        "grid_sample (image grad, free grid)": lambda: torch.nn.functional.grid_sample(
            image, grid, align_corners=False).sum().backward(),
        "fpiwarp (image + corner grads)": lambda: ft.warp_image(image, src, dst_grad).sum().backward(),
        "kornia warp_perspective (image + matrix grads)": lambda: kornia.geometry.transform.warp_perspective(
            image, h, (size, size), align_corners=True).sum().backward(),
    }
    times = {k: [] for k in fns}
    for fn in fns.values():
        fn()
    sync(device)
    for _ in range(rounds):
        for name, fn in fns.items():
            sync(device)
            t0 = time.perf_counter()
            fn()
            sync(device)
            times[name].append(time.perf_counter() - t0)
    lines += ["", f"{batch} × 3 × {size}² float32, median of {rounds} interleaved rounds:", "",
              "| contender | ms |", "|---|---:|"]
    ms = {k: statistics.median(v) * 1e3 for k, v in times.items()}
    lines += [f"| {k} | {v:.2f} |" for k, v in ms.items()]
    names = list(ms)
    lines += ["", f"- fpiwarp / grid_sample: {ms[names[0]] / ms[names[1]]:.2f}×",
              f"- fpiwarp / kornia: {ms[names[2]] / ms[names[3]]:.2f}×"]
    # grid_sample's own backward, for contrast
    runs = []
    for _ in range(3):
        image.grad = None
        torch.nn.functional.grid_sample(image, grid, align_corners=False).square().sum().backward()
        runs.append(image.grad.clone())
    same = all(torch.equal(runs[0], r) for r in runs[1:])
    lines.append(f"- grid_sample's image gradient bit-identical over 3 runs: {same}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    device = torch.device(args.device)
    if device.type == "cuda" and not torch.cuda.is_available():
        sys.exit("no CUDA device: run this where a GPU is lent (or pass --device cpu for a dry run)")
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else "CPU"
    lines = [f"# fpiwarp.torch on {name}", "", f"torch {torch.__version__}, device {device}.", ""]
    ok = True
    if device.type == "cuda":
        rc = subprocess.call([sys.executable, "-m", "pytest", "-q", "tests/torch_warps/test_torch_grad.py",
                              "-k", "cuda"])
        lines.append(f"- tests/torch_warps/test_torch_grad.py -k cuda: exit {rc} ({'ok' if rc == 0 else 'FAIL'})")
        ok &= rc == 0
    ok &= parity(device, lines)
    ok &= determinism(device, lines, False)
    try:
        ok &= determinism(device, lines, True)
    except RuntimeError as err:  # an op PyTorch flags as nondeterministic in that mode
        lines.append(f"- FAIL under use_deterministic_algorithms(True): {str(err).splitlines()[0]}")
        ok = False
    timings(device, args.size, args.batch, args.rounds, lines)
    text = "\n".join(lines) + "\n"
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(text)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
