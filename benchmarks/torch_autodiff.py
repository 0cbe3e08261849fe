"""Forward + backward of fpiwarp.torch.warp_image against grid_sample and kornia, side by side.

Run: ``python3 -m benchmarks.torch_autodiff [--rounds N] [--size S] [--batch B]``
(writes benchmarks/results/torch_autodiff.md). 512² RGB float32, batch 8,
on the CPU, rounds interleaved so machine load affects every contender alike:

* fpiwarp, image gradient only, vs ``torch.nn.functional.grid_sample`` on a
  precomputed grid (image gradient only: the grid is free for it);
* fpiwarp, image + corner gradients, vs ``kornia.geometry.transform.warp_perspective``
  (image + 3×3 matrix gradients).

Each timing is forward, a scalar loss and ``backward()``; the figure is the
median over rounds, and the ratios are of those medians.
"""

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import torch

import fpiwarp
import fpiwarp.torch as ft

from .machine import cpu_model

RESULTS = Path(__file__).resolve().parent / "results" / "torch_autodiff.md"


def isa():
    """The widest x86 vector extension the CPU reports, and the one PyTorch dispatches to."""
    flags = set()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("flags"):
                    flags = set(line.split(":", 1)[1].split())
                    break
    except OSError:
        pass
    widest = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else platform.machine()
    return f"{widest} (PyTorch CPU capability: {torch.backends.cpu.get_cpu_capability()})"


def corners(size, batch, seed=0):
    """Source square corners and perturbed targets (up to 4% of the size)."""
    g = torch.Generator().manual_seed(seed)
    s = float(size - 1)
    src = torch.tensor([[0.0, 0.0], [s, 0.0], [s, s], [0.0, s]], dtype=torch.float64).expand(batch, 4, 2)
    dst = src + (torch.rand(batch, 4, 2, generator=g, dtype=torch.float64) - 0.5) * 0.08 * size
    return src.contiguous(), dst


def contenders(size, batch):
    """{name: a function running forward + backward once}."""
    import kornia

    g = torch.Generator().manual_seed(1)
    image = torch.rand(batch, 3, size, size, generator=g).requires_grad_()
    src, dst = corners(size, batch)
    dst_grad = dst.clone().requires_grad_()
    # the same maps as homographies for kornia (pixel coordinates, kornia's convention)
    h = kornia.geometry.transform.get_perspective_transform(src.float(), dst.float())
    h = h.detach().requires_grad_()
    with torch.no_grad():  # the grid grid_sample gets for free: fpiwarp's own source positions
        pos = ft.inverse_points(_pixels(size), src, dst).reshape(batch, size, size, 2)
        grid = ((2 * pos + 1) / size - 1).float()

    def fpi_image():
        ft.warp_image(image, src, dst).sum().backward()

    def fpi_all():
        ft.warp_image(image, src, dst_grad).sum().backward()

    def grid_sample():
        torch.nn.functional.grid_sample(image, grid, align_corners=False).sum().backward()

    def kornia_warp():
        kornia.geometry.transform.warp_perspective(image, h, (size, size), align_corners=True).sum().backward()

    return {"fpiwarp (image grad)": fpi_image, "grid_sample (image grad, free grid)": grid_sample,
            "fpiwarp (image + corner grads)": fpi_all, "kornia warp_perspective (image + matrix grads)": kornia_warp}


def _pixels(size):
    ys, xs = torch.meshgrid(torch.arange(size, dtype=torch.float64), torch.arange(size, dtype=torch.float64),
                            indexing="ij")
    return torch.stack([xs, ys], -1).reshape(1, -1, 2)


def run(rounds, size, batch):
    fns = contenders(size, batch)
    times = {name: [] for name in fns}
    for fn in fns.values():  # warm-up
        fn()
    for _ in range(rounds):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t0)
    return {name: statistics.median(v) * 1e3 for name, v in times.items()}


def profile(size, batch):
    """The ten most expensive operators of one fpiwarp forward + backward (image + corner grads)."""
    image = torch.rand(batch, 3, size, size).requires_grad_()
    src, dst = corners(size, batch)
    dst = dst.requires_grad_()
    ft.warp_image(image, src, dst).sum().backward()
    with torch.profiler.profile() as prof:
        ft.warp_image(image, src, dst).sum().backward()
    return prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=10)


def report(ms, size, batch, rounds, prof):
    versions = {"torch": torch.__version__, "fpiwarp": fpiwarp.__version__}
    try:
        import kornia

        versions["kornia"] = kornia.__version__
    except ImportError:
        pass
    fi, gs = ms["fpiwarp (image grad)"], ms["grid_sample (image grad, free grid)"]
    fa, ko = ms["fpiwarp (image + corner grads)"], ms["kornia warp_perspective (image + matrix grads)"]
    lines = [
        "# fpiwarp.torch: forward + backward on the CPU",
        "",
        f"Machine: {cpu_model()}, {torch.get_num_threads()} PyTorch threads, ISA {isa()}, "
        f"{platform.system()} {platform.release()}, Python {platform.python_version()}; load average "
        f"{os.getloadavg()[0]:.1f} at the end (other work on the machine slows fpiwarp's many short passes "
        "more than one fused grid_sample kernel: compare ratios of runs at similar load).",
        "",
        "Libraries: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ".",
        "",
        f"{batch} × 3 × {size} × {size} float32, bilinear, constant mode; forward, sum, backward; median of "
        f"{rounds} interleaved rounds (`python3 -m benchmarks.torch_autodiff`).",
        "",
        "| contender | ms |",
        "|---|---:|",
        *[f"| {name} | {v:.1f} |" for name, v in ms.items()],
        "",
        f"- fpiwarp / grid_sample (image gradient): **{fi / gs:.2f}×** (target ≤ 2×)",
        f"- fpiwarp / kornia (image + map gradients): **{fa / ko:.2f}×** (target < 1×)",
        "",
        "Where fpiwarp's time goes (image + corner gradients, one run, PyTorch profiler, self CPU time):",
        "",
        "```",
        prof,
        "```",
        "",
    ]
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    ms = run(args.rounds, args.size, args.batch)
    text = report(ms, args.size, args.batch, args.rounds, profile(args.size, args.batch))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
