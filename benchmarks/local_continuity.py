"""Continuity of LocalDeformation over a 1920x1080 picture: the paper's
construction (construction="paper") against the continuous one (the
default), in one run.

``python3 -m benchmarks.local_continuity [--n 24] [--seed 3] [--spread 0.05,0.1] [--out DIR]``

Per configuration the output's inverse map q(p) (what warp_image samples
at) is evaluated over the 1920x1080 output: horizontal neighbour pairs on
every 8th row, vertical ones on every 8th column (a tear is a curve and
crosses one kind). The jump is the largest, over those neighbours p, p + s,
of |q(p + s) - q(p) - s q'| with q' the mean of the map's derivative along s at both
(a smooth map gives ~|q''|/2, a fraction of a pixel; a tear shows as its
size in source pixels). Also: maximal conformal distortion K over the
picture and over the region of interest, and fold-over (any J <= 0 over the
picture, the same grid). Configurations: the issue's (astronaut, adjacent
edges), the gallery's (opposite, parallel), and seeded random ones: a
square region of 0.25 of the picture's height, every dst corner moved by
``spread`` x N(0, 1) of the region's size, constrained edges drawn at
random, the continuous construction given the picture as its extent; a
configuration the continuous construction refuses (lines meeting inside
the picture, or no spline within the edge bound) counts as refused.

Writes local_continuity.md and .json into DIR (default: benchmarks/results).
"""

import argparse
import json
import platform
from pathlib import Path

import numpy as np

from fpiwarp import FpiwarpError, LocalDeformation

DEFAULT_OUT = Path(__file__).resolve().parent / "results"
W, H = 1920, 1080
#: Neighbour pairs on every STRIDE-th row (horizontal) and column (vertical).
STRIDE = 8


def named_cases():
    s = 1080 / 512  # the case on a 512-px picture, scaled to 1080 rows
    src = np.array([[150, 100], [350, 100], [350, 300], [150, 300]], float) * s
    dst = np.array([[150, 100], [350, 100], [350, 300], [110, 330]], float) * s
    g = np.array([[0.35 * W, 0.2 * H], [0.65 * W, 0.2 * H], [0.65 * W, 0.8 * H], [0.35 * W, 0.8 * H]])
    gd = g.copy()
    gd[1] += [0.02 * W, -0.12 * H]
    gd[2] += [0.08 * W, -0.10 * H]
    return [("issue (edges 0,1)", src, dst, (0, 1)), ("gallery (edges 3,1)", g, gd, (3, 1))]


def random_cases(n, seed, spread):
    rng = np.random.default_rng(seed)
    side = 0.25 * H
    out = []
    for i in range(n):
        c = np.array([rng.uniform(0.3 * W, 0.7 * W), rng.uniform(0.3 * H, 0.7 * H)])
        src = c + side * np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
        dst = src + spread * side * rng.standard_normal((4, 2))
        edges = [(0, 2), (1, 3), (0, 1), (1, 2), (2, 3), (3, 0)][rng.integers(6)]
        if len(set(edges)) == 2 and (edges[1] - edges[0]) % 4 != 2:  # adjacent: keep one similarity
            first = edges[0] if (edges[1] - edges[0]) % 4 == 1 else edges[1]
            free = (first + 3) % 4
            moved = dst[free].copy()
            dst = src.copy()
            dst[free] = moved
        out.append((f"random {spread:g} #{i} (edges {edges[0]},{edges[1]})", src, dst, edges))
    return out


def _pairs(inv, p, step):
    """|q(p + step) - q(p) - step-derivative| and the Wirtinger parts at p."""
    with np.errstate(all="ignore"):
        q0, qz, qzb = inv.wirtinger(p)
        q1, qz1, qzb1 = inv.wirtinger(p + step)
    d0 = qz * step + qzb * np.conj(step)
    d1 = qz1 * step + qzb1 * np.conj(step)
    return np.abs(q1 - q0 - 0.5 * (d0 + d1)), qz, qzb


def measure(f, rows=H, cols=W, stride=STRIDE):
    """Largest jump (source px), K max and fold pixels over the output:
    horizontal neighbours on every ``stride``-th row and vertical ones on
    every ``stride``-th column (a tear is a curve: it crosses one or the other)."""
    inv = f.inverse
    worst, kmax, folds = 0.0, 1.0, 0
    for ys, xs, step in ((np.arange(0, rows, stride), np.arange(cols - 1), 1.0),
                         (np.arange(rows - 1), np.arange(0, cols, stride), 1j)):
        for y0 in range(0, len(ys), 64):
            yy = ys[y0:y0 + 64].astype(np.float64)
            p = (xs[None, :].astype(np.float64) + 1j * yy[:, None]).ravel()
            jump, qz, qzb = _pairs(inv, p, step)
            worst = max(worst, float(np.nanmax(jump)))
            det = np.abs(qz) ** 2 - np.abs(qzb) ** 2
            folds += int(np.sum(det <= 0))
            with np.errstate(all="ignore"):
                k = (np.abs(qz) + np.abs(qzb)) / (np.abs(qz) - np.abs(qzb))
            kmax = max(kmax, float(np.nanmax(np.where(det > 0, k, np.inf))))
    return worst, kmax, folds


def roi_kmax(f, src, n=41):
    from fpiwarp.metrics import grid

    return float(np.max(f.distortion(grid(src, n))))


def run(n, seed, spreads, log=print):
    cases = named_cases() + [c for s in spreads for c in random_cases(n, seed, s)]
    rows = []
    for label, src, dst, edges in cases:
        row = {"case": label}
        for cons in ("paper", "continuous"):
            kw = {"extent": (W, H)} if cons == "continuous" else {}
            try:
                f = LocalDeformation(src, dst, edges, construction=cons, **kw)
            except FpiwarpError as exc:
                row[cons] = {"refused": str(exc).split(":")[0]}
                continue
            jump, kmax, folds = measure(f)
            row[cons] = {"jump_px": jump, "kmax_picture": kmax, "kmax_roi": roi_kmax(f, src), "fold_pixels": folds}
        rows.append(row)
        log(label, {k: v for k, v in row.items() if k != "case"})
    return {"rows": rows, "n": n, "seed": seed, "spreads": spreads,
            "machine": f"{platform.processor() or platform.machine()}, {platform.python_version()}"}


def _cpu():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def markdown(result):
    lines = [
        "# LocalDeformation continuity over a 1920x1080 output",
        "",
        f"CPU: {_cpu()} (host numpy float64; no kernel involved). Jump: largest |q(p+1) - q(p) - q'(p)| over",
        "neighbouring output pixels, q the inverse map (source px); K: maximal conformal distortion over",
        "the picture and over the region of interest; folds: output pixels with J <= 0.",
        "",
        "| case | paper: jump px | K picture | K ROI | folds | continuous: jump px | K picture | K ROI | folds |",
        "|---|---|---|---|---|---|---|---|---|",
    ]

    def cells(r):
        if "refused" in r:
            return ["refused: " + r["refused"][:60], "", "", ""]
        return [f"{r['jump_px']:.3g}", f"{r['kmax_picture']:.3g}", f"{r['kmax_roi']:.3g}", str(r["fold_pixels"])]

    for row in result["rows"]:
        lines.append("| " + " | ".join([row["case"], *cells(row["paper"]), *cells(row["continuous"])]) + " |")
    both = [r for r in result["rows"] if "jump_px" in r["paper"] and "jump_px" in r["continuous"]]
    if both:
        jp = np.array([r["paper"]["jump_px"] for r in both])
        jc = np.array([r["continuous"]["jump_px"] for r in both])
        kr = np.array([r["continuous"]["kmax_roi"] / r["paper"]["kmax_roi"] for r in both])
        refused = sum("refused" in r["continuous"] for r in result["rows"])
        lines += [
            "",
            f"Summary over {len(both)} configurations both accept ({refused} of {len(result['rows'])} refused by "
            "the continuous construction):",
            f"jump px median/max: paper {np.median(jp):.3g} / {jp.max():.3g}, continuous {np.median(jc):.3g} / "
            f"{jc.max():.3g}; K over the ROI, continuous / paper: median {np.median(kr):.3f}, max {kr.max():.3f}.",
        ]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12, help="random configurations per spread")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--spread", default="0.05,0.1")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    result = run(args.n, args.seed, [float(s) for s in args.spread.split(",")])
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "local_continuity.md").write_text(markdown(result))
    (args.out / "local_continuity.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
