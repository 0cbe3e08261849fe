"""Warp's CPU device (the pip-only path, ``pip install fpiwarp[warp]``)
beside ``cv2.remap``, side by side in one run.

* 3840×2160 RGB, uint8 and float32, orders 0/1/3, constant border:
  ``fpiwarp.warp_image(img, f, backend="warp")`` end to end (numpy in,
  numpy out, the map evaluated per pixel inside) and a ``Warper`` (the map
  bound once), beside ``cv2.remap`` with its maps precomputed outside the
  clock (``INTER_NEAREST``/``LINEAR``/``CUBIC``; OpenCV's cubic is Keys'
  a = -0.75, fpiwarp's a = -0.5: the same class of work);
* 256² RGB uint8 bilinear: the plain call and a ``Warper``, beside
  ``cv2.remap``;
* the first call in a fresh process once Warp's kernel cache is warm:
  ``import fpiwarp``, the first ``warp_image`` on the warp backend (Warp's
  initialization and the kernel's load from the disk cache) and the second.

Rounds are interleaved (every implementation once per round, best of the
rounds kept) so that load on a shared machine falls on both sides; the
report records the CPU model, its vector ISA, the cores this process may
use and the load average. Both sides use every core (OpenCV's default
threads, the warp backend's default ``FPIWARP_WARP_THREADS``).

Run from the repository root: ``python3 -m benchmarks.nvwarp_cpu``
(``--rounds N``, ``--quick`` for a smoke run, ``--out DIR``); writes
``nvwarp_cpu.md`` and ``nvwarp_cpu.json`` into ``benchmarks/results/``.
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks import common

RESULTS = Path(__file__).resolve().parent / "results"
ISA_FLAGS = ("avx512f", "avx512bw", "avx512vl", "avx2", "fma", "sse4_2", "neon", "asimd")


def cpu_isa():
    """The vector ISA flags of this CPU that matter to compiled kernels."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith(("flags", "features")):
                    flags = set(line.split(":", 1)[1].split())
                    return [f for f in ISA_FLAGS if f in flags]
    except OSError:
        pass
    return []


def machine():
    import cv2
    import warp

    from fpiwarp.backends import get_backend

    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count()
    backend = get_backend("warp")
    return {"cpu": common.cpu_model(), "isa": cpu_isa(), "cores": cores, "load_start": list(os.getloadavg()),
            "warp": warp.__version__, "warp_device": str(backend.device), "warp_threads": backend.threads,
            "cv2": cv2.__version__, "cv2_threads": cv2.getNumThreads()}


def sample_map(width, height):
    """A generic 4-point map of the frame (corners moved by 2-8 %, pole far outside)."""
    import fpiwarp

    w, h = width - 1, height - 1
    dx, dy = 0.03 * w, 0.035 * h
    return fpiwarp.FPI([[0, 0], [w, 0], [w, h], [0, h]],
                       [[dx, 0.6 * dy], [w - 2.5 * dx, -0.5 * dy], [w + 0.8 * dx, h - dy], [-1.2 * dx, h + 0.3 * dy]])


def cases(quick):
    """(name, image, map, order, cv2 interpolation flag) per case."""
    import cv2

    rng = np.random.default_rng(0)
    big = (1280, 720) if quick else (3840, 2160)
    frame = rng.integers(0, 256, size=(big[1], big[0], 3), dtype=np.uint8)
    small = rng.integers(0, 256, size=(256, 256, 3), dtype=np.uint8)
    label = f"{big[0]}×{big[1]} RGB"
    out = []
    for order, flag in ((1, cv2.INTER_LINEAR), (0, cv2.INTER_NEAREST), (3, cv2.INTER_CUBIC)):
        out.append((f"{label} uint8, order {order}", frame, order, flag))
    out.append((f"{label} float32, order 1", frame.astype(np.float32) / 255, 1, cv2.INTER_LINEAR))
    out.append(("256² RGB uint8, order 1", small, 1, cv2.INTER_LINEAR))
    return out


def implementations(image, order, flag):
    """{name: callable} for one case: cv2.remap (maps outside the clock), fpiwarp's plain call and Warper."""
    import cv2

    import fpiwarp
    from fpiwarp.warping import Warper

    h, w = image.shape[:2]
    transform = sample_map(w, h)
    src = fpiwarp.source_positions(transform, (h, w)).astype(np.float32)
    mx, my = np.ascontiguousarray(src[..., 0]), np.ascontiguousarray(src[..., 1])
    warper = Warper(transform, order=order, backend="warp")
    return {
        "cv2.remap": lambda: cv2.remap(image, mx, my, flag, borderMode=cv2.BORDER_CONSTANT),
        "warp_image": lambda: fpiwarp.warp_image(image, transform, order=order, backend="warp"),
        "Warper": lambda: warper(image),
    }


def interleaved(table, rounds):
    """{case: {impl: best seconds}}: each implementation once per round, in turn."""
    best = {case: dict.fromkeys(impls, float("inf")) for case, impls in table.items()}
    for fns in table.values():  # warm-up: kernels loaded, buffers made
        for fn in fns.values():
            fn()
    for _ in range(rounds):
        for case, fns in table.items():
            for name, fn in fns.items():
                start = time.perf_counter()
                fn()
                best[case][name] = min(best[case][name], time.perf_counter() - start)
    return best


FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np, fpiwarp
t1 = time.perf_counter()
img = np.zeros((256, 256, 3), np.uint8)
f = fpiwarp.FPI([[0, 0], [255, 0], [255, 255], [0, 255]], [[4, 2], [250, -3], [259, 251], [-2, 257]])
fpiwarp.warp_image(img, f, backend="warp")
t2 = time.perf_counter()
fpiwarp.warp_image(img, f, backend="warp")
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2)
"""


def first_call(runs=2):
    """Seconds of import, first call and second call in fresh processes (the
    first run may compile where the cache is cold; the later ones read it),
    and whether each printed the compile notice."""
    out = []
    root = Path(__file__).resolve().parent.parent
    env = {**os.environ, "PYTHONPATH": str(root) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    for _ in range(runs):
        proc = subprocess.run([sys.executable, "-c", FIRST_CALL], capture_output=True, text=True, env=env, cwd=root)
        numbers = proc.stdout.split()
        if proc.returncode or len(numbers) != 3:
            out.append({"error": proc.stderr.strip().splitlines()[-1:] or ["no output"]})
            continue
        out.append({"import_s": float(numbers[0]), "first_call_s": float(numbers[1]),
                    "second_call_s": float(numbers[2]), "compiled": "fpiwarp: compiling" in proc.stderr})
    return out


def report(facts, best, starts):
    lines = ["# Warp's CPU device (pip-only path) beside cv2.remap", "",
             f"CPU: {facts['cpu']}; ISA: {', '.join(facts['isa']) or 'unknown'}; {facts['cores']} cores usable; "
             f"load average {facts['load_start'][0]:.1f} at start, {facts['load_end'][0]:.1f} at end.",
             f"Warp {facts['warp']} on {facts['warp_device']} ({facts['warp_threads']} threads); OpenCV "
             f"{facts['cv2']} ({facts['cv2_threads']} threads). Best of {facts['rounds']} interleaved rounds; "
             "cv2.remap's maps are computed outside the clock, fpiwarp's plain call evaluates the map per pixel "
             "inside it.", "",
             "| case | cv2.remap ms | warp_image ms (× cv2) | Warper ms (× cv2) |", "|---|---|---|---|"]
    for case, times in best.items():
        c = times["cv2.remap"]
        lines.append(f"| {case} | {c * 1e3:.1f} | {times['warp_image'] * 1e3:.1f} ({times['warp_image'] / c:.2f}×) "
                     f"| {times['Warper'] * 1e3:.1f} ({times['Warper'] / c:.2f}×) |")
    lines += ["", "First call in a fresh process (`import fpiwarp`, first and second `warp_image` of a 256² RGB "
              "uint8 image on the warp backend):", "", "| run | import s | first call s | second call s | compiled |",
              "|---|---|---|---|---|"]
    for k, run in enumerate(starts, 1):
        if "error" in run:
            lines.append(f"| {k} | error: {run['error']} | | | |")
        else:
            lines.append(f"| {k} | {run['import_s']:.2f} | {run['first_call_s']:.2f} | {run['second_call_s']:.4f} | "
                         f"{'yes' if run['compiled'] else 'no'} |")
    lines += ["", common.CPU_PROFILE_POINTER]
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--quick", action="store_true", help="a smoke run: 1280×720 frames, two rounds")
    p.add_argument("--out", type=Path, default=RESULTS)
    args = p.parse_args(argv)
    rounds = 2 if args.quick else args.rounds
    facts = machine()
    table = {name: implementations(image, order, flag) for name, image, order, flag in cases(args.quick)}
    best = interleaved(table, rounds)
    starts = first_call()
    facts.update(load_end=list(os.getloadavg()), rounds=rounds)
    args.out.mkdir(parents=True, exist_ok=True)
    text = report(facts, best, starts)
    (args.out / "nvwarp_cpu.md").write_text(text, encoding="utf-8")
    (args.out / "nvwarp_cpu.json").write_text(json.dumps({"machine": facts, "best_s": best, "first_call": starts},
                                                         indent=1), encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
