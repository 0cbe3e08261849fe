"""The coarse pass of a local deformation's warp (fpiwarp/block/coarse.py)
against the per-pixel Newton it replaces, in one run.

``python3 -m benchmarks.local_speed [--rounds 7] [--size 1080x1920] [--out DIR]``

The map is speed.py's ``LocalDeformation`` (edges 1 and 3 of a quad over the
middle of the frame); calls are interleaved round by round (best of
``rounds``): the FPI warp, the LocalDeformation with the coarse pass and
without, uint8 RGB, order 1, on the opencl backend
(``fpiwarp.backends.opencl.prepared.COARSE_PASS`` off when its job is made)
and the gl backend, and the gl preview's exact frame (speed.py's: Renderer,
method "pixel", offscreen, waited for), the gl ones with
``fpiwarp.backends.gl.coarse.COARSE_PASS`` off during the 'before' calls.
Ratios are to the FPI on the same backend (the preview's: to the FPI's
frame). Also the float32 reference's count of spline
evaluations per pixel of the band (the pixels no region takes) with and
without the pass: the floor is one value-only evaluation per verified pixel.

Writes local_speed.md and .json into DIR (default: benchmarks/results).
"""

import argparse
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend
from fpiwarp.backends.gl import coarse as gl_coarse
from fpiwarp.backends.opencl import prepared
from fpiwarp.block.coarse import coarse_pass, pixel_seeds
from fpiwarp.block.describe import describe, stage_rows
from fpiwarp.block.layout import PAIRED_CORES, ROW_L3, ROW_MU3, ROW_MU12
from fpiwarp.block.reference import complex_at, pre_mobius, region_winner, seed_correction, tps_core

from .common import (
    bests,
    corner_quads,
    fmt_ratio,
    fmt_time,
    interleaved,
    machine_facts,
    machine_markdown,
    markdown_table,
    test_image,
    write_json,
    write_text,
)
from .speed import local_deformation, preview_frame


def _bound(transform, image, coarse):
    """A warp of ``transform`` bound on opencl, its job made with the coarse pass on or off."""
    be = get_backend("opencl")
    was, prepared.COARSE_PASS = prepared.COARSE_PASS, coarse
    try:
        bound = be.bind(transform)
        bound.warp_image(image, image.shape[:2], order=1, mode="constant", cval=(0, 0, 0))
    finally:
        prepared.COARSE_PASS = was
    return lambda: bound.warp_image(image, image.shape[:2], order=1, mode="constant", cval=(0, 0, 0))


def _gl_call(call, coarse):
    """``call`` with the gl coarse pass on or off (read per draw)."""
    def run():
        was, gl_coarse.COARSE_PASS = gl_coarse.COARSE_PASS, coarse
        try:
            return call()
        finally:
            gl_coarse.COARSE_PASS = was
    return run


def _gl_warp(transform, image):
    """A warp of ``transform`` bound on gl."""
    bound = get_backend("gl").bind(transform)
    return lambda: bound.warp_image(image, image.shape[:2], order=1, mode="constant", cval=(0, 0, 0))


def evaluations(transform, height, width, rows_every=4):
    """Spline evaluations per band pixel of the float32 reference, without
    and with the coarse pass (every ``rows_every``-th row), and the share of
    band pixels whose coarse seed the check takes."""
    block = np.asarray(transform.inverse.params(), np.float32)
    st = describe(block).stages[0]
    rows = stage_rows(block, 0)
    paired, n, tol = st.core in PAIRED_CORES, st.n_centers, rows[ROW_L3, 2]
    py, px = np.meshgrid(np.arange(0, height, rows_every), np.arange(width), indexing="ij")
    z = (px + 1j * py).astype(np.complex64)
    won = region_winner(rows, st, z, np.float32)[0]
    t = pre_mobius(rows, z[~won])
    mu1, mu2, mu3 = complex_at(rows[ROW_MU12], 0), complex_at(rows[ROW_MU12], 2), complex_at(rows[ROW_MU3], 0)
    x = mu1 * t + mu2 * np.conj(t) + mu3 + seed_correction(t, rows, np.float32)
    count, done = np.zeros(t.shape), np.zeros(t.shape, bool)
    for _ in range(st.newton_iters):
        val, dz, dzb = tps_core(x, rows, n, np.float32, paired)
        count += ~done
        res = val - t
        done = np.abs(res) <= tol
        det = np.abs(dz) ** 2 - np.abs(dzb) ** 2
        x = np.where(done, x, x - (np.conj(dz) * res - dzb * np.conj(res)) / det)
    rec = coarse_pass(block, width, height)
    x0 = pixel_seeds(rec, px[~won], py[~won])[0]
    passed = np.abs(tps_core(x0, rows, n, np.float32, paired)[0] - t) <= tol
    seeded = 1 + np.where(passed, 0, count)
    nodes = rec.shape[0] * rec.shape[1] / (height * width)
    return {"band_share": float((~won).mean()), "plain_evals": float(count.mean()),
            "coarse_evals": float(seeded.mean()), "check_passes": float(passed.mean()), "nodes_per_pixel": nodes}


def run(height, width, rounds):
    image = test_image(height, width, "uint8", np.random.default_rng(0))
    fpi = fpiwarp.FPI(*corner_quads(height, width))
    local = local_deformation(height, width)
    calls = {
        "opencl FPI": _bound(fpi, image, True),
        "opencl LocalDeformation, per-pixel Newton (before)": _bound(local, image, False),
        "opencl LocalDeformation, coarse pass (after)": _bound(local, image, True),
        "gl FPI": _gl_warp(fpi, image),
        "gl LocalDeformation, per-pixel Newton (before)": _gl_call(_gl_warp(local, image), False),
        "gl LocalDeformation, coarse pass (after)": _gl_call(_gl_warp(local, image), True),
        "gl preview frame FPI": preview_frame(image, fpi),
        "gl preview frame LocalDeformation, per-pixel Newton (before)": _gl_call(preview_frame(image, local), False),
        "gl preview frame LocalDeformation, coarse pass (after)": _gl_call(preview_frame(image, local), True),
    }
    times, _ = interleaved(calls, rounds)
    return bests(times), evaluations(local, height, width)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--size", default="1080x1920")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args(argv)
    height, width = (int(v) for v in args.size.split("x"))
    facts = machine_facts()
    best, evals = run(height, width, args.rounds)
    facts_end = machine_facts(backends=False)
    fpi = {k: best[k] for k in ("opencl FPI", "gl FPI", "gl preview frame FPI")}

    def ratio(name, seconds):  # to the FPI of the same backend (the preview's: its FPI frame)
        base = max((k for k in fpi if name.startswith(k[:-len("FPI")])), key=len)
        return fmt_ratio(seconds / fpi[base])

    table = markdown_table(["implementation", f"{width}×{height}"],
                           [[k, f"{fmt_time(v)} ({ratio(k, v)})"] for k, v in best.items()])
    md = "\n".join([
        "# The coarse pass of a local deformation's warp", "", machine_markdown(facts),
        f"Load average at the end: {facts_end['load_average_1_5_15min']}.", "",
        f"Best of {args.rounds} interleaved rounds; ratios to the FPI on the same backend.", "", table, "",
        "Float32 reference, spline evaluations per pixel of the band (the pixels no region takes, "
        f"{evals['band_share']:.1%} of the frame): per-pixel Newton {evals['plain_evals']:.2f} "
        f"(the first with derivatives); coarse pass {evals['coarse_evals']:.3f} (one value-only check, "
        f"passed by {evals['check_passes']:.2%}), plus {evals['nodes_per_pixel']:.4f} nodes per pixel "
        "solved in full.", ""])
    out = Path(args.out)
    write_text(out / "local_speed.md", md)
    write_json(out / "local_speed.json", {"machine": facts, "load_end": facts_end["load_average_1_5_15min"],
                                          "seconds": best, "evaluations": evals})
    print(md)


if __name__ == "__main__":
    main()
