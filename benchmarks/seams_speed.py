"""Speed of the constrained map on every backend: the paper's construction
(the old default: 10 equally spread points per edge, 40 plain TPS terms)
against the default (adaptive spacing, δ 0.002, 16 points per edge, 32
paired terms), measured side by side in one run (part of
``python3 -m benchmarks.seams``).

Per backend: map_points of 2^16 points and warp_image of a 256² RGB
uint8 picture (order 1), forward map and, for map_points, its Newton
inverse; best of ``repeats`` rounds of both after one warm-up call of each (compiles), and the
ratio default / old. Timings on a shared machine are noisy: read the
ratios, not the absolute numbers.
"""


import numpy as np

import fpiwarp
from fpiwarp import ConstrainedFPI

from .common import bests, interleaved

SRC = np.array([[40.0, 50.0], [210.0, 40.0], [220.0, 200.0], [30.0, 215.0]])
DST = np.array([[45.0, 60.0], [205.0, 35.0], [236.0, 210.0], [25.0, 205.0]])
OLD = dict(points_per_edge=10, delta=0.01, spacing="uniform")


def backend_speed(repeats=3, n_points=1 << 16, size=256):
    """{backend: {case: {"old_ms", "new_ms", "ratio"}}} for every available backend."""
    maps = {"old": ConstrainedFPI(SRC, DST, (0, 2), **OLD), "new": ConstrainedFPI(SRC, DST, (0, 2))}
    rng = np.random.default_rng(0)
    pts = rng.uniform(30, 220, (n_points, 2))
    img = rng.integers(0, 256, (size, size, 3), dtype=np.uint8)
    out = {}
    for backend in fpiwarp.available_backends():
        cases = {
            "map_points": lambda f, b=backend: fpiwarp.map_points(f, pts, backend=b),
            "map_points inverse": lambda f, b=backend: fpiwarp.map_points(f.inverse, pts, backend=b),
            "warp_image": lambda f, b=backend: fpiwarp.warp_image(img, f, order=1, backend=b),
        }
        out[backend] = {}
        for case, run in cases.items():
            times, _ = interleaved({m: (lambda run=run, f=f: run(f)) for m, f in maps.items()}, repeats)
            old, new = bests(times)["old"], bests(times)["new"]
            out[backend][case] = dict(old_ms=1e3 * old, new_ms=1e3 * new, ratio=new / old)
    return out


def markdown(speed):
    lines = [
        "Speed of the constrained map per backend (best of 3, ms; ratio = default / old,",
        "measured side by side; the old map: 10 uniform points, δ 0.01, 40 plain terms;",
        "the default: adaptive, δ 0.002, 16 points, 32 paired terms):",
        "",
        "| backend | case | old ms | default ms | ratio |",
        "|---|---|---|---|---|",
    ]
    for backend, cases in speed.items():
        for case, r in cases.items():
            lines.append(f"| {backend} | {case} | {r['old_ms']:.1f} | {r['new_ms']:.1f} | {r['ratio']:.2f} |")
    return "\n".join(lines) + "\n"
