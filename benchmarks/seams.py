"""Seams of the local deformations: how closely the constrained FPI follows
each constrained edge's similarity, before and after, in one run.

``python3 -m benchmarks.seams [--n 320] [--seed 16] [--grid 41] [--out DIR] [--no-backends]``

Configurations (seeded): src is the unit square centered at 0 with every
corner moved by 0.3 N(0, 1), dst is src with every corner moved by
0.3 N(0, 1) again, constrained edges (0, 2) or (1, 3) with equal odds;
kept when both quads are valid, a LocalDeformation can be built and
the old default map (10 equally spread points per edge, δ = 0.01, the
paper's construction) has no fold-over on a grid x grid grid spanning src.

Per variant of ConstrainedFPI, over the same configurations:

- edge deviation: max over both constrained edges (401 points each) of
  |f(p) - S_k(p)| / |w_k+1 - w_k|, S_k edge k's similarity: median, p90,
  max; and the LocalDeformation jump across the edges, measured the same
  way between points 1e-9 of the size inside and outside the edge;
- corner error: max |f(z_i) - w_i| / size of dst;
- maximal conformal distortion K on the grid (Fig. 11 style: its maximum
  over all configurations, and per configuration the ratio to the old default's:
  median, p90, max, count above 1.01);
- fold-overs: configurations whose Jacobian determinant is <= 0 somewhere
  on the grid;
- fit time (median per map) and centers in the block stage;
- beyond the free edges: LocalDeformation's jump on the constrained
  edges' lines 0.05 and 0.25 edge lengths past the corners;
- the float32 parameter block (what the kernels evaluate): forward error
  and the share of points the float32 Newton inverse leaves unsolved;
- host evaluation time per point, forward and Newton inverse;
- the speed of the old and the default map on every backend
  (:mod:`benchmarks.seams_speed`).

Writes seams.md and seams.json into DIR (default: benchmarks/results).
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from fpiwarp import ConstrainedFPI, LocalDeformation
from fpiwarp.block import evaluate
from fpiwarp.maps.constrained import edge_similarity
from fpiwarp.metrics import grid, jacobian_determinant
from fpiwarp.testing import PAPER_CONSTRUCTION, UNIT_SQUARE, constrained_configurations

from .common import RESULTS as DEFAULT_OUT
from .common import machine_facts, machine_markdown, write_text
from .seams_speed import backend_speed
from .seams_speed import markdown as speed_markdown

#: (label, ConstrainedFPI keywords); the first is the baseline, the old
#: default (the paper's construction). PLAIN: the same map with its block
#: packed as plain TPS terms (no pairs), to show what float32 loses then.
PLAIN = "_plain"
VARIANTS = [
    ("before: 10 uniform, δ 0.01 (paper's, old default)", PAPER_CONSTRUCTION),
    ("16 graded, δ 0.01", dict(points_per_edge=16, spacing="graded", delta=0.01)),
    ("16 adaptive, δ 0.01 (old opt-in)", dict(points_per_edge=16, spacing="adaptive", delta=0.01)),
    ("16 adaptive, δ 0.004", dict(points_per_edge=16, spacing="adaptive", delta=0.004)),
    ("after: default (16 adaptive, δ 0.002, paired block)", dict()),
    ("default, block as plain terms", {PLAIN: True}),
]


def _c(a):
    a = np.asarray(a, dtype=np.float64)
    return a[..., 0] + 1j * a[..., 1]


def configurations(n, seed, grid_n):
    """The seeded configurations (:func:`fpiwarp.testing.constrained_configurations`,
    which tests/maps/test_local_seams.py checks too)."""
    return constrained_configurations(n, seed, grid_n, construction=VARIANTS[0][1])


def edge_deviation(f, src, dst, edges, n=401):
    z, w = _c(src), _c(dst)
    t = np.linspace(0.0, 1.0, n)
    worst = 0.0
    for k in edges:
        a, b = edge_similarity(z, w, k)
        p = z[k] + t * (z[(k + 1) % 4] - z[k])
        dev = np.abs(f.map_complex(p) - (a * p + b)) / abs(w[(k + 1) % 4] - w[k])
        worst = max(worst, float(dev.max()))
    return worst


def local_jump(src, dst, edges, kw, n=401):
    """Largest |L(p + eps n) - L(p - eps n)| / edge length across the edges."""
    loc = LocalDeformation(src, dst, edges, construction="paper", **{k: v for k, v in kw.items() if k != PLAIN})
    z, w = _c(src), _c(dst)
    eps = 1e-9 * float(np.max(np.abs(z - z.mean())))
    t = np.linspace(0.0, 1.0, n)[1:-1]
    worst = 0.0
    for reg, k in zip(loc.regions, loc.edges):
        p = z[k] + t * (z[(k + 1) % 4] - z[k])
        jump = np.abs(loc.map_complex(p + eps * reg.normal) - loc.map_complex(p - eps * reg.normal))
        worst = max(worst, float(jump.max()) / abs(w[(k + 1) % 4] - w[k]))
    return worst


def beyond_corners(f, src, dst, edges, s):
    """|f(p) - S_k(p)| / |w_k+1 - w_k| on edge k's line at s edge lengths
    beyond either end (past the free edges): what LocalDeformation jumps
    by there, between the strip (f) and the outer similarity S_k."""
    z, w = _c(src), _c(dst)
    worst = 0.0
    for k in edges:
        e = z[(k + 1) % 4] - z[k]
        a, b = edge_similarity(z, w, k)
        p = np.array([z[k] - s * e, z[(k + 1) % 4] + s * e])
        worst = max(worst, float(np.max(np.abs(f.map_complex(p) - (a * p + b)))) / abs(w[(k + 1) % 4] - w[k]))
    return worst


def float32_block(f, src, dst, n=25):
    """Largest |block in float32 - host| / size of dst over an n x n grid
    (forward map), the fraction of those images the float32 Newton
    inverse leaves unsolved (NaN), and the largest error of the packed
    (float32) parameters evaluated in float64: what rounding the centers
    and weights alone costs."""
    g = grid(src, n).reshape(-1, 2)
    size = float(np.max(np.abs(_c(dst) - _c(dst).mean())))
    host = f(g)
    block = f.params()
    fwd = evaluate(block, g, dtype=np.float32).astype(np.float64)
    packed = evaluate(block, g, dtype=np.float64)
    inv = evaluate(f.inverse.params(), host, dtype=np.float32)
    return (
        float(np.max(np.abs(_c(fwd) - _c(host)))) / size,
        float(np.mean(~np.isfinite(inv).all(axis=1))),
        float(np.max(np.abs(_c(packed) - _c(host)))) / size,
    )


def measure(configs, kw, grid_n):
    dev, jump, corner, kmax, folds, times = [], [], [], [], 0, []
    near, far, f32, unsolved, packed = [], [], [], [], []
    plain = kw.get(PLAIN, False)
    kw = {k: v for k, v in kw.items() if k != PLAIN}
    for src, dst, edges in configs:
        t0 = time.perf_counter()
        f = ConstrainedFPI(src, dst, edges, **kw)
        times.append(time.perf_counter() - t0)
        if plain:
            f.tps.partner = None  # the block as plain terms (host map unchanged)
        dev.append(edge_deviation(f, src, dst, edges))
        jump.append(local_jump(src, dst, edges, kw))
        size = float(np.max(np.abs(_c(dst) - _c(dst).mean())))
        corner.append(float(np.max(np.abs(f.map_complex(_c(src)) - _c(dst)))) / size)
        g = grid(src, grid_n)
        kmax.append(float(np.max(f.distortion(g))))
        folds += int(not np.min(jacobian_determinant(f, g)) > 0)
        near.append(beyond_corners(f, src, dst, edges, 0.05))
        far.append(beyond_corners(f, src, dst, edges, 0.25))
        e32, nan, e64 = float32_block(f, src, dst)
        f32.append(e32)
        unsolved.append(nan)
        packed.append(e64)
    return dict(
        beyond_05=np.array(near), beyond_25=np.array(far), f32=max(f32), unsolved=max(unsolved), packed=max(packed),
        dev=np.array(dev), jump=np.array(jump), corner=max(corner), kmax=np.array(kmax),
        folds=folds, fit_ms=1e3 * float(np.median(times)), centers=len(f.tps.centers),
    )


def eval_speed(kw, n_points=1 << 15, repeats=3):
    """Host evaluation time of the forward map and its Newton inverse."""
    src, dst = UNIT_SQUARE, UNIT_SQUARE + [[0.05, 0.02], [-0.03, 0.04], [0.1, -0.05], [0.0, 0.03]]
    f = ConstrainedFPI(src, dst, (0, 2), **{k: v for k, v in kw.items() if k != PLAIN})
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.45, 0.45, (n_points, 2))
    out = {}
    for name, m in (("forward", f), ("inverse", f.inverse)):
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            m(pts)
            best = min(best, time.perf_counter() - t0)
        out[name] = best * 1e9 / n_points
    return out


def run(n=320, seed=16, grid_n=41, log=print):
    configs = configurations(n, seed, grid_n)
    rows = []
    base = None
    for label, kw in VARIANTS:
        m = measure(configs, kw, grid_n)
        if base is None:
            base = m
        ratio = m["kmax"] / base["kmax"]
        d, j = m["dev"], m["jump"]
        row = dict(
            variant=label, keywords=kw, centers=m["centers"],
            dev_median=float(np.median(d)), dev_p90=float(np.percentile(d, 90)), dev_max=float(d.max()),
            dev_over_1e3=int(np.sum(d > 1e-3)), jump_max=float(j.max()), corner_err=m["corner"],
            kmax=float(m["kmax"].max()), kratio_median=float(np.median(ratio)),
            kratio_p90=float(np.percentile(ratio, 90)), kratio_max=float(ratio.max()),
            kratio_over_101=int(np.sum(ratio > 1.01)), folds=m["folds"], fit_ms=m["fit_ms"],
            beyond_05_median=float(np.median(m["beyond_05"])), beyond_05_max=float(m["beyond_05"].max()),
            beyond_25_median=float(np.median(m["beyond_25"])), beyond_25_max=float(m["beyond_25"].max()),
            float32_err_max=m["f32"], newton32_unsolved_max=m["unsolved"], packed_err_max=m["packed"],
        )
        big = base["kmax"] >= 16
        row["kratio_max_before_below_16"] = float(ratio[~big].max())
        row.update({f"ns_per_point_{k}": v for k, v in eval_speed(kw).items()})
        rows.append(row)
        log(f"{label}: dev {row['dev_median']:.1e}/{row['dev_p90']:.1e}/{row['dev_max']:.1e}, "
            f"K max {row['kmax']:.1f}, ratio {row['kratio_median']:.3f}/{row['kratio_p90']:.3f}/"
            f"{row['kratio_max']:.2f}, folds {row['folds']}, fit {row['fit_ms']:.1f} ms")
    return dict(n=len(configs), seed=seed, grid=grid_n, rows=rows)


def markdown(result):
    lines = [
        "# Constrained edges: deviation from their similarities",
        "",
        f"{result['n']} random fold-free configurations (seed {result['seed']}), distortion on a "
        f"{result['grid']}² grid over src; K ratio: per configuration, to the old default's "
        "(the paper's construction).",
        "",
        machine_markdown(result["machine"]) if "machine" in result else "",
        "",
        "| variant | centers | dev median | dev p90 | dev max | > 1e-3 | jump max | corner err "
        "| K max | K ratio median | p90 | max | > 1.01 | fold-overs | fit ms | ns/pt fwd | ns/pt inv |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        lines.append(
            f"| {r['variant']} | {r['centers']} | {r['dev_median']:.2e} | {r['dev_p90']:.2e} | "
            f"{r['dev_max']:.2e} | {r['dev_over_1e3']} | {r['jump_max']:.2e} | {r['corner_err']:.0e} | "
            f"{r['kmax']:.1f} | {r['kratio_median']:.3f} | {r['kratio_p90']:.3f} | {r['kratio_max']:.2f} | "
            f"{r['kratio_over_101']} | {r['folds']} | {r['fit_ms']:.1f} | "
            f"{r['ns_per_point_forward']:.0f} | {r['ns_per_point_inverse']:.0f} |"
        )
    lines += [
        "",
        "K ratio max where the old default's K < 16 (the rest are near-degenerate), the jump of",
        "LocalDeformation on the constrained edges' lines beyond the free edges (0.05 and",
        "0.25 edge lengths past a corner, median / max, relative to the edge length), and the",
        "float32 block (what the kernels evaluate): largest error of its packed parameters evaluated",
        "in float64 and of its float32 evaluation, relative to the size of dst, and the largest",
        "fraction of points the float32 Newton inverse leaves unsolved.",
        "",
        "| variant | K ratio max (old K < 16) | beyond 0.05 | beyond 0.25 | packed params err | float32 fwd err "
        "| f32 Newton unsolved |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        lines.append(
            f"| {r['variant']} | {r['kratio_max_before_below_16']:.3f} | "
            f"{r['beyond_05_median']:.1e} / {r['beyond_05_max']:.1e} | "
            f"{r['beyond_25_median']:.1e} / {r['beyond_25_max']:.1e} | {r['packed_err_max']:.1e} | "
            f"{r['float32_err_max']:.1e} | "
            f"{r['newton32_unsolved_max']:.3f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=320)
    ap.add_argument("--seed", type=int, default=16)
    ap.add_argument("--grid", type=int, default=41)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--no-backends", action="store_true", help="skip the per-backend speed table")
    args = ap.parse_args(argv)
    result = run(args.n, args.seed, args.grid)
    result["machine"] = machine_facts()
    if not args.no_backends:
        result["backend_speed"] = backend_speed()
    args.out.mkdir(parents=True, exist_ok=True)
    text = markdown(result)
    if "backend_speed" in result:
        text += "\n" + speed_markdown(result["backend_speed"])
    write_text(args.out / "seams.md", text)
    write_text(args.out / "seams.json", json.dumps(result, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
