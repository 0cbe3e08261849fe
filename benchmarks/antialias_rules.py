"""What other footprint rules would give: quality against sub-samples per pixel (issue 29).

``python3 -m benchmarks.antialias_rules [--quick] [--out DIR]``

The antialiased warp's cost over a plain warp grows with the sub-samples
it reads per pixel (each one an interpolation like the plain warp's own
sample, plus the Jacobian once per pixel). Issue 29 asks for at most
1.5x the plain warp at a 1/2 shrink and 2x at 1/8 and at 1/6 x 1/1.5, and
for a zone plate within 30 dB of the exact box at 1/3 and 1/8. This
study runs the numpy reference (:mod:`fpiwarp.sampling.antialias`, which
every backend mirrors) under other rules for the pyramid level and the
sub-sample count, on the antialiasing benchmark's pictures, FPI shrinks
and 8 x 8 supersampled box reference (:mod:`benchmarks.antialias`), and
reports for each rule and case the PSNR and the mean sub-samples per
interior pixel (:func:`fpiwarp.sampling.antialias.sample_counts` under
that rule). A rule is patched into the reference for the duration of its
runs only (:func:`rule`); the library's rule is :data:`RULES`' first.

The rules (levels as in fpiwarp/block/sampling_rules.py: the footprint's
shorter edge picks level k where it spans ``span`` to 2 ``span`` texels;
each edge gets tap_counts of its length in level-k texels, at level 0
always; at levels >= 1 a rule may read one sub-sample per edge up to
``one_tap`` texels and space them ``spacing`` texels apart beyond):
"""

import argparse
import contextlib
import time
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.sampling import antialias as aa
from fpiwarp.sampling.pyramid import Pyramid

from . import antialias as bench
from . import common

#: name -> (span, one_tap, spacing, what it is); span 2 with one_tap and
#: spacing None is the library's rule (AA_LEVEL_SPAN 2, tap_counts at every level).
RULES = {
    "fpiwarp (the library's rule)": (2.0, None, None,
                                     "level where the shorter edge spans 2-4 texels, sub-samples <= 1.25 texels apart"),
    "one sub-sample per edge up to 3 texels": (2.0, 3.0, 2.0,
                                               "the same levels; at levels >= 1 one sub-sample per edge up to "
                                               "3 texels, then 2 texels apart"),
    "fewer sub-samples at coarse levels": (2.0, 2.2, 1.6,
                                           "the same levels; at levels >= 1 one sub-sample up to 2.2 texels, "
                                           "then 1.6 apart"),
    "mipmap-like: one sub-sample at the level": (1.0, 1.5, None,
                                                 "level where the shorter edge spans 1-2 texels (as a GPU's "
                                                 "mipmap), one sub-sample up to 1.5 texels, else tap_counts"),
}
__doc__ += "".join(f"\n* {name}: {desc}." for name, (_, _, _, desc) in RULES.items())

#: The FPI shrinks of the study: (sx, sy) as benchmarks.antialias.fpi_shrink takes them.
SHRINKS = ((1.5, 1.5), (2, 2), (3, 3), (4, 4), (8, 8), (6, 1.5), (4, 1))
QUICK_SHRINKS = ((2, 2), (3, 3), (8, 8))


@contextlib.contextmanager
def rule(span, one_tap, spacing):
    """The reference's level and sub-sample rule replaced for the block's
    duration (see the module docstring); restored after, whatever happens."""
    saved = aa.AA_LEVEL_SPAN, aa.level_taps
    counts = aa.tap_counts

    def level_taps(ex, ey, k):
        scale = 2.0**k
        with np.errstate(invalid="ignore"):
            nx, ny = counts(ex / scale), counts(ey / scale)
            if one_tap is None:
                return nx, ny
            coarse = np.broadcast_to(np.asarray(k) >= 1, np.shape(nx))

            def per_edge(edge, n):
                length = np.abs(edge / scale)
                length = np.where(np.isnan(length), 0.0, length)
                step = aa.AA_SPACING if spacing is None else spacing
                many = np.clip(np.maximum(np.ceil(length / step - aa.AA_SLACK), 2), 1, aa.AA_MAX_TAPS)
                return np.where(coarse, np.where(length <= one_tap, 1, many), n).astype(np.int64)

            return per_edge(ex, nx), per_edge(ey, ny)

    aa.AA_LEVEL_SPAN, aa.level_taps = span, level_taps
    try:
        yield
    finally:
        aa.AA_LEVEL_SPAN, aa.level_taps = saved


def mean_samples(transform, shape, mask, top):
    """The reference's mean sub-samples per pixel over ``mask`` under the
    patched rule (``top``: the source pyramid's coarsest level)."""
    gy, gx = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    with np.errstate(all="ignore"):
        _, fz, fzb = transform.inverse.wirtinger(gx + 1j * gy)
    ex, ey = aa.footprint_edges(fz, fzb)
    return float(aa.sample_counts(ex, ey, top)[mask].mean())


def study(quick, log=print):
    """[{picture, shrink, plain, rules: {name: (psnr, mean sub-samples)}}]."""
    rows = []
    for name, image, formula in bench.pictures(quick)[:2]:
        h, w = image.shape[:2]
        top = Pyramid(image).top
        for sx, sy in QUICK_SHRINKS if quick else SHRINKS:
            transform, shape = bench.fpi_shrink(h, w, sx, sy)
            ref = bench.reference(image, formula, transform, shape)
            mask = bench.interior(image, transform, shape)
            plain = fpiwarp.warp_image(image, transform, shape, mode="edge", backend="numpy")
            row = {"picture": name, "shrink": f"1/{sx}" if sx == sy else f"1/{sx} x 1/{sy}",
                   "plain": round(bench.psnr(plain, ref, mask), 2), "rules": {}}
            for rule_name, (span, one_tap, spacing, _) in RULES.items():
                with rule(span, one_tap, spacing):
                    got = fpiwarp.warp_image(image, transform, shape, mode="edge", antialias=True, backend="numpy")
                    row["rules"][rule_name] = (round(bench.psnr(got, ref, mask), 2),
                                               round(mean_samples(transform, shape, mask, top), 2))
            rows.append(row)
            log(f"{name} {row['shrink']}: plain {row['plain']} dB; "
                + "; ".join(f"{k}: {v[0]} dB, {v[1]} sub-samples" for k, v in row["rules"].items()))
    return rows


#: The cost split's cases: (label, sx, sy); sx None: a translation into the 1/2 shrink's output.
COST_CASES = (("no shrink (a translation, 1/2's output shape)", None, None), ("1/2", 2, 2), ("1/8", 8, 8),
              ("1/6 x 1/1.5", 6, 1.5))


def cost_split(backend, rounds, quick=False, log=print):
    """[{case, samples, plain_s, antialias_s, plain_cpu_s, antialias_cpu_s}]:
    the library's rule on ``backend``, the antialiasing benchmark's 1920 x
    1080 RGB uint8 source (its pyramid kept), calls interleaved round by
    round, best of ``rounds`` (wall and process CPU time). The translation
    reads one sub-sample per pixel: what the Jacobian and the antialiased
    kernel's set-up cost beside the plain warp."""
    h, w = bench.QUICK_COST_SIZE if quick else bench.COST_SIZE
    image = np.random.default_rng(0).integers(0, 256, (h, w, 3), dtype=np.uint8)
    top = Pyramid(image).top
    calls, samples = {}, {}
    for label, sx, sy in COST_CASES:
        if sx is None:
            transform, shape = fpiwarp.RLinear(1, 0, complex(w / 20, h / 20)), bench.fpi_shrink(h, w, 2)[1]
        else:
            transform, shape = bench.fpi_shrink(h, w, sx, sy)
        samples[label] = mean_samples(transform, shape, np.ones(shape, bool), top)
        for aa_on in (False, True):
            calls[label, aa_on] = (lambda t=transform, sh=shape, a=aa_on:
                                   fpiwarp.warp_image(image, t, sh, backend=backend, antialias=a))
    best = {}
    for fn in calls.values():
        fn()
    for _ in range(rounds):
        for key, fn in calls.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            b = best.setdefault(key, [wall, cpu])
            b[0], b[1] = min(b[0], wall), min(b[1], cpu)
    rows = []
    for label, _, _ in COST_CASES:
        (pw, pc), (aw, ac) = best[label, False], best[label, True]
        rows.append({"case": label, "samples": round(samples[label], 2), "plain_s": pw, "antialias_s": aw,
                     "plain_cpu_s": pc, "antialias_cpu_s": ac})
        log(f"cost {backend} {label}: {samples[label]:.2f} sub-samples, plain {pw * 1e3:.2f} ms, "
            f"antialiased {aw * 1e3:.2f} ms")
    return rows


def cost_markdown(backend, rows, rounds):
    body = [[r["case"], f"{r['samples']:.2f}", f"{r['plain_s'] * 1e3:.2f}", f"{r['antialias_s'] * 1e3:.2f}",
             f"{r['antialias_s'] / r['plain_s']:.2f}", f"{r['antialias_cpu_s'] / r['plain_cpu_s']:.2f}"]
            for r in rows]
    header = ["case", "sub-samples per pixel", "plain (ms)", "antialiased (ms)", "wall ratio", "CPU ratio"]
    return f"""## What a sub-sample costs ({backend})

The library's rule on {backend}, 1920 x 1080 RGB uint8 source (its pyramid
kept), each output of its shrink's size; best of {rounds} interleaved
rounds, wall and process CPU time (all threads). The translation reads
one sub-sample per pixel, so its ratio is what the Jacobian and the
antialiased kernel's set-up add.

{common.markdown_table(header, body)}
"""


def markdown(rows, machine_md, cost_md=""):
    names = list(RULES)
    header = ["picture", "FPI shrink", "plain order 1 (dB)"] + [f"{n}: dB / sub-samples" for n in names]
    body = [[r["picture"], r["shrink"], f"{r['plain']:.2f}"]
            + [f"{r['rules'][n][0]:.2f} / {r['rules'][n][1]:.2f}" for n in names] for r in rows]
    rules = "\n".join(f"- **{n}**: {d}." for n, (_, _, _, d) in RULES.items())
    return f"""# Antialiasing rules: quality against sub-samples per pixel

`python3 -m benchmarks.antialias_rules`: the numpy reference under other
level and sub-sample rules (see the script's docstring), PSNR (dB, peak 1)
against the 8 x 8 supersampled box reference over interior pixels, and the
mean sub-samples the rule reads per pixel (the plain warp reads 1).

{rules}

{common.markdown_table(header, body)}

{cost_md}
{machine_md}
"""


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python3 -m benchmarks.antialias_rules",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small pictures, three shrinks (a smoke run)")
    parser.add_argument("--out", default=str(common.RESULTS), help="folder of antialias_rules.md and .json")
    parser.add_argument("--backend", default="opencl",
                        help="the backend of the cost split (default opencl, the fastest CPU backend; "
                             "'none' skips it)")
    parser.add_argument("--rounds", type=int, default=15, help="rounds of the cost split")
    args = parser.parse_args(argv)
    info = common.machine_facts()
    t0 = time.perf_counter()
    cost, cost_md = [], ""
    if args.backend != "none":
        cost = cost_split(args.backend, 2 if args.quick else args.rounds, args.quick)
        cost_md = cost_markdown(args.backend, cost, 2 if args.quick else args.rounds)
    rows = study(args.quick)
    info["wall_s"] = round(time.perf_counter() - t0, 1)
    out = Path(args.out)
    common.write_text(out / "antialias_rules.md", markdown(rows, common.machine_markdown(info), cost_md))
    common.write_json(out / "antialias_rules.json", {"machine": info, "rules": {
        n: {"span": s, "one_tap": o, "spacing": p, "what": d} for n, (s, o, p, d) in RULES.items()},
        "cases": rows, "cost_backend": args.backend, "cost": cost})


if __name__ == "__main__":
    main()
