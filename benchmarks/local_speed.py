"""The coarse pass of a local deformation's warp (fpiwarp/block/coarse.py)
against the per-pixel Newton it replaces, in one run.

``python3 -m benchmarks.local_speed [--rounds 7] [--size 1080x1920] [--out DIR]``
``python3 -m benchmarks.local_speed --batch 16 --size 512x512 [--rounds 5]``

The map is speed.py's ``LocalDeformation`` (edges 1 and 3 of a quad over the
middle of the frame); calls are interleaved round by round (best of
``rounds``): the FPI warp, the LocalDeformation with the coarse pass and
without, uint8 RGB, order 1, on the opencl backend
(``fpiwarp.backends.opencl.prepared.COARSE_PASS`` off during the 'before'
calls, ``fpiwarp.block.coarse_choice.ALWAYS`` on: the pass where it is on,
whatever the rule would pick; benchmarks/local_pick.py measures the rule)
and the gl backend, and the gl preview's exact frame (speed.py's: Renderer,
method "pixel", offscreen, waited for), the gl ones with
``fpiwarp.backends.gl.coarse.COARSE_PASS`` off during the 'before' calls.
Ratios are to the FPI on the same backend (the preview's: to the FPI's
frame). Also the float32 reference's count of spline
evaluations per pixel of the band (the pixels no region takes) with and
without the pass: the floor is one value-only evaluation per verified pixel.

Writes local_speed.md and .json into DIR (default: benchmarks/results).

``--batch N``: instead, ``warp_batch`` of N images of ``--size``, each
warped by its own LocalDeformation (uint8 RGB, order 1), on opencl and gl,
interleaved: the batch with the coarse pass (after) and without (before:
the backend's COARSE_PASS off during the call), the batch in chunks (opencl)
or draws (gl) of one image (one records buffer reused image by image, in
order), and the loop of warp_image. Ratios are to the loop on the same
backend. Its section of local_speed.md (:data:`BATCH_TITLE` and the
batch's size) is replaced (or added), the rest kept; its numbers go to
local_speed_batch_N_HxW.json.
"""

import argparse
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend
from fpiwarp.backends.gl import coarse as gl_coarse
from fpiwarp.backends.opencl import prepared
from fpiwarp.block import coarse_choice
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

#: The heading of the ``--batch`` sections of local_speed.md (then the batch's size).
BATCH_TITLE = "## Batches of local deformations"


def _bound(transform, image, coarse):
    """A warp of ``transform`` bound on opencl, each call with the coarse
    pass on (forced: coarse_choice.ALWAYS) or off (read per call)."""
    bound = get_backend("opencl").bind(transform)
    call = _patched(lambda: bound.warp_image(image, image.shape[:2], order=1, mode="constant", cval=(0, 0, 0)),
                    prepared, COARSE_PASS=coarse)
    return _patched(call, coarse_choice, ALWAYS=True)


def _gl_call(call, coarse):
    """``call`` with the gl coarse pass on (forced: coarse_choice.ALWAYS) or off (read per draw)."""
    return _patched(_patched(call, gl_coarse, COARSE_PASS=coarse), coarse_choice, ALWAYS=True)


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


def _patched(call, module, **values):
    """``call`` with ``module``'s attributes set to ``values`` during the call."""
    def run():
        was = {k: getattr(module, k) for k in values}
        try:
            for k, v in values.items():
                setattr(module, k, v)
            return call()
        finally:
            for k, v in was.items():
                setattr(module, k, v)
    return run


def run_batch(n, height, width, rounds):
    """Best seconds of the ``--batch`` calls (see the module docstring)."""
    from fpiwarp.backends.gl import batch as gl_batch
    from fpiwarp.backends.opencl import batch as cl_batch

    rng = np.random.default_rng(0)
    stack = np.stack([test_image(height, width, "uint8", rng) for _ in range(n)])
    maps = [local_deformation(height, width + 2 * k) for k in range(n)]
    calls = {}
    for name, module, one in (("opencl", prepared, (cl_batch, {"CHUNK_BYTES": 1})),
                              ("gl", gl_coarse, (gl_batch, {"SOFTWARE_CHUNK_BYTES": 1, "CHUNK_BYTES": 1}))):
        def batch(name=name):
            return fpiwarp.warp_batch(stack, maps, backend=name)

        def loop(name=name):
            return [fpiwarp.warp_image(im, m, backend=name) for im, m in zip(stack, maps)]

        def forced(call):  # the pass forced where on (the rule not asked: benchmarks/local_pick.py measures it)
            return _patched(call, coarse_choice, ALWAYS=True)

        calls[f"{name} loop of warp_image (coarse pass)"] = forced(loop)
        calls[f"{name} batch, per-pixel Newton (before)"] = _patched(batch, module, COARSE_PASS=False)
        calls[f"{name} batch, coarse pass (after)"] = forced(_patched(batch, module, COARSE_PASS=True))
        calls[f"{name} batch, coarse pass, one image per {'chunk' if name == 'opencl' else 'draw'}"] = \
            forced(_patched(_patched(batch, one[0], **one[1]), module, COARSE_PASS=True))
    times, results = interleaved(calls, rounds)
    for name in ("opencl", "gl"):  # the batch is the loop's result, bit for bit
        assert np.array_equal(np.stack(results[f"{name} loop of warp_image (coarse pass)"]),
                              results[f"{name} batch, coarse pass (after)"])
    return bests(times), _images_per_chunk(stack)


def _images_per_chunk(stack):
    """Images per chunk of the default opencl batch (zero copy or
    pipelined) and per draw of the gl batch (a Newton map's), for ``stack``."""
    from fpiwarp.backends.gl import batch as gl_batch
    from fpiwarp.backends.opencl import batch as cl_batch

    be = get_backend("opencl")
    chunks, _ = cl_batch.chunk_plan(be, stack, stack[0].nbytes, cl_batch.default_transfer(be))
    per_cl = len(range(*chunks[0]))
    per_gl = gl_batch.images_per_draw(get_backend("gl").warper, stack.shape[1:], stack.shape[1:3], 1, True)
    return {"opencl": min(per_cl, len(stack)), "gl": min(per_gl, len(stack))}


def batch_section(n, height, width, rounds, best, per_chunk, facts, load_end):
    """The ``--batch`` section of local_speed.md (``per_chunk``: :func:`_images_per_chunk`)."""
    def ratio(name, seconds):
        return fmt_ratio(seconds / best[name.split(" ")[0] + " loop of warp_image (coarse pass)"])

    table = markdown_table(["implementation", f"{n} × {width}×{height}"],
                           [[k, f"{fmt_time(v)} ({ratio(k, v)})"] for k, v in best.items()])
    return "\n".join([
        f"{BATCH_TITLE}, {n} × {width}×{height}", "", "`python3 -m benchmarks.local_speed --batch "
        f"{n} --size {height}x{width} --rounds {rounds}`: warp_batch of {n} uint8 RGB images, each by its own "
        "LocalDeformation, order 1. Best of "
        f"{rounds} interleaved rounds; ratios to the loop of warp_image on the same backend. The batch with the "
        "coarse pass equals the loop bit for bit (checked by the run). By default an opencl chunk holds "
        f"{per_chunk['opencl']} image(s) here, a gl draw {per_chunk['gl']} (the 'one image per' rows force 1).", "",
        machine_markdown(facts),
        f"Load average at the end: {load_end}.", "", table, ""])


def write_batch_section(path, section):
    """Replace the section of local_speed.md with ``section``'s title (its
    first line, up to the next section) by ``section``, or add it; the rest kept."""
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    title = section.split("\n", 1)[0] + "\n"
    if title in text:
        start = text.index(title)
        end = text.find("\n## ", start + len(title))
        text = text[:start].rstrip("\n") + ("" if end < 0 else "\n" + text[end:])
    write_text(path, text.rstrip("\n") + "\n\n" + section)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--size", default="1080x1920")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--batch", type=int, default=0, help="warp_batch of this many images instead (see above)")
    args = ap.parse_args(argv)
    height, width = (int(v) for v in args.size.split("x"))
    facts = machine_facts()
    if args.batch:
        best, per_chunk = run_batch(args.batch, height, width, args.rounds)
        load_end = machine_facts(backends=False)["load_average_1_5_15min"]
        section = batch_section(args.batch, height, width, args.rounds, best, per_chunk, facts, load_end)
        out = Path(args.out)
        write_batch_section(out / "local_speed.md", section)
        data = {"machine": facts, "load_end": load_end, "images": args.batch, "size": [height, width],
                "images_per_chunk": per_chunk, "seconds": best}
        write_json(out / f"local_speed_batch_{args.batch}_{height}x{width}.json", data)
        print(section)
        return
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
    kept = (out / "local_speed.md").read_text(encoding="utf-8") if (out / "local_speed.md").exists() else ""
    write_text(out / "local_speed.md", md)
    if BATCH_TITLE in kept:  # the --batch sections stay
        write_text(out / "local_speed.md", md.rstrip("\n") + "\n\n" + kept[kept.index(BATCH_TITLE):])
    write_json(out / "local_speed.json", {"machine": facts, "load_end": facts_end["load_average_1_5_15min"],
                                          "seconds": best, "evaluations": evals})
    print(md)


if __name__ == "__main__":
    main()
