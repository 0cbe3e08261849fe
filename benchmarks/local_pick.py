"""The coarse pass's choice per map (fpiwarp/block/coarse.py,
``takes_coarse_pass``) against both fixed choices, in one run.

``python3 -m benchmarks.local_pick [--rounds 5] [--backends opencl,gl] [--out DIR]``

Map families (:func:`families`): the benchmark's local deformation
(speed.py: a quad over the middle fifth of the frame, corners moved by
2-6 %) at several frame sizes; quads of a fixed size in pixels inside
frames of several sizes and quads of several sizes inside one frame
(the deformation's scale and the frame's varied independently); corners
moved further (12 % of the quad); RandomLocal's maps (the augmentation
case). Per map and size: the share of band pixels whose seed passes the
check, as the float32 reference measures it and as seed_pass_share
predicts it; and per backend, interleaved round by round (best of
``rounds``), the single warp (uint8 RGB, order 1, bound) with the pass
off (the backend's COARSE_PASS False), forced on (the rule bypassed) and
chosen by the rule, wall and process CPU time.

Writes local_pick.md and .json into DIR only when ``--out`` is given.
"""

import argparse
import os
import time
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.augment import RandomLocal
from fpiwarp.block import coarse_choice as block_coarse
from fpiwarp.block.coarse_choice import curvature_share, seed_pass_share, takes_coarse_pass

from .common import machine_facts, machine_markdown, test_image, write_json, write_text
from .local_speed import evaluations
from .speed import local_deformation


def quad_deformation(height, width, side, shift=0.04, centre=(0.5, 0.5)):
    """A LocalDeformation of a quad ``side`` px square (capped by the frame)
    centred at ``centre`` (fractions of the frame), its corners moved by
    ``shift`` of the side (the benchmark's pattern of moves), edges 1 and 3."""
    side = min(side, 0.8 * min(height, width))
    cx, cy = centre[0] * (width - 1), centre[1] * (height - 1)
    h = side / 2
    src = np.array([[cx - h, cy - h], [cx + h, cy - h], [cx + h, cy + h], [cx - h, cy + h]])
    moves = np.array([[0.5, -1.25], [0.75, 0.5], [-0.5, 1.5], [0.25, -0.75]]) * shift * side
    return fpiwarp.LocalDeformation(src, src + moves, edges=(1, 3))


def families(sizes=(128, 256, 384, 512, 768, 1080)):
    """[(family, (height, width), transform)]: the maps measured."""
    out = []
    for s in sizes:
        out.append(("bench (middle fifth)", (s, s), local_deformation(s, s)))
    for s in (128, 256, 512, 1080):
        out.append(("quad 48 px", (s, s), quad_deformation(s, s, 48)))
        out.append(("quad 0.5 frame, 12 %", (s, s), quad_deformation(s, s, 0.5 * s, shift=0.12)))
    for side in (24, 64, 160, 400):
        out.append((f"quad {side} px in 512²", (512, 512), quad_deformation(512, 512, side)))
    for s in (128, 256, 512):
        maps = RandomLocal(seed=3).sample((s, s), 3)
        for k, f in enumerate(maps):
            out.append((f"RandomLocal #{k}", (s, s), f))
    return out


def _opencl_call(transform, image, mode):
    """A bound opencl warp with the pass 'off', 'on' (forced) or 'rule'."""
    from fpiwarp.backends import get_backend  # noqa: PLC0415
    from fpiwarp.backends.opencl import prepared  # noqa: PLC0415

    bound = get_backend("opencl").bind(transform)
    return _with_mode(lambda: bound.warp_image(image, image.shape[:2], order=1, mode="constant", cval=(0, 0, 0)),
                      mode, prepared)


def _gl_warp_call(transform, image, mode):
    from fpiwarp.backends import get_backend  # noqa: PLC0415
    from fpiwarp.backends.gl import coarse as gl_coarse  # noqa: PLC0415

    bound = get_backend("gl").bind(transform)
    return _with_mode(lambda: bound.warp_image(image, image.shape[:2], order=1, mode="constant", cval=(0, 0, 0)),
                      mode, gl_coarse)


def _with_mode(call, mode, module):
    """``call`` with module.COARSE_PASS off ('off'), the rule bypassed
    ('on': every Newton map takes the pass) or as it is ('rule')."""
    def run():
        was_pass, was_always = module.COARSE_PASS, block_coarse.ALWAYS
        module.COARSE_PASS, block_coarse.ALWAYS = mode != "off", mode == "on"
        try:
            return call()
        finally:
            module.COARSE_PASS, block_coarse.ALWAYS = was_pass, was_always
    return run


CALLS = {"opencl": _opencl_call, "gl": _gl_warp_call}


def measure(cases, backends, rounds):
    """Rows of the table (see the module docstring)."""
    rows = []
    for family, (h, w), f in cases:
        block = f.inverse.params()
        ev = evaluations(f, h, w)
        block_coarse.forget()
        t0 = time.perf_counter()
        takes_coarse_pass(block, w, h, "opencl")  # uncached: the screen, and the sample where it asks
        rule_ms = (time.perf_counter() - t0) * 1e3
        row = {"family": family, "size": f"{h}x{w}", "band": ev["band_share"], "measured": ev["check_passes"],
               "predicted": seed_pass_share(block, w, h), "screen": curvature_share(block, w, h), "rule_ms": rule_ms}
        image = test_image(h, w, np.uint8, np.random.default_rng(0))
        for name in backends:
            calls = {m: CALLS[name](f, image, m) for m in ("off", "on", "rule")}
            for c in calls.values():
                c()  # build and warm
            row[name] = _best_of(calls, rounds)
            row[name]["chosen"] = "coarse" if takes_coarse_pass(block, w, h, name) else "per-pixel"
        rows.append(row)
        print(_line(row, backends), flush=True)
    return rows


def measure_batches(backends, rounds, sizes=(128, 256), n=64, shift=(0.1, 0.03)):
    """Rows of warp_batch of ``n`` images each by its own RandomLocal map
    (max_corner_shift in ``shift``), per size: per-pixel, forced coarse, chosen."""
    rows = []
    for s in sizes:
        for cs in shift:
            maps = list(RandomLocal(seed=5, max_corner_shift=cs).sample((s, s), n))
            stack = np.stack([test_image(s, s, np.uint8, np.random.default_rng(k)) for k in range(n)])
            blocks = [np.ascontiguousarray(f.inverse.params(), np.float32) for f in maps]
            ref = [evaluations(f, s, s)["check_passes"] for f in maps[:8]]
            block_coarse.forget()
            t0 = time.perf_counter()
            for b in blocks:
                takes_coarse_pass(b, s, s, "opencl")
            rule_ms = (time.perf_counter() - t0) / n * 1e3
            row = {"family": f"batch {n} RandomLocal shift {cs}", "size": f"{s}x{s}", "band": None,
                   "measured": float(np.mean(ref)), "predicted": float(np.mean([seed_pass_share(b, s, s)
                                                                                for b in blocks[:8]])),
                   "screen": float(np.mean([curvature_share(b, s, s) for b in blocks[:8]])), "rule_ms": rule_ms}
            for name in backends:
                module = _switch(name)
                calls = {m: _with_mode(lambda name=name, stack=stack, maps=maps: fpiwarp.warp_batch(
                    stack, maps, order=1, mode="constant", backend=name), m, module)
                         for m in ("off", "on", "rule")}
                for c in calls.values():
                    c()
                row[name] = _best_of(calls, rounds, block_coarse.forget)  # fresh maps each round, as augmentation's
                chosen = sum(block_coarse.takes_coarse_pass(b, s, s, name) for b in blocks)
                row[name]["chosen"] = f"coarse {chosen}/{n}"
            rows.append(row)
            print(_line(row, backends), flush=True)
    return rows


def _best_of(calls, rounds, before_round=None):
    """{name: {wall_ms, cpu_ms}}: the best of ``rounds`` interleaved rounds
    of ``calls`` ({name: callable}), wall and process CPU time;
    ``before_round`` (if any) is called before each round, off the clock."""
    best = {m: (np.inf, np.inf) for m in calls}
    for _ in range(rounds):
        if before_round is not None:
            before_round()
        for m, c in calls.items():
            w0, c0 = time.perf_counter(), time.process_time()
            c()
            dw, dc = time.perf_counter() - w0, time.process_time() - c0
            best[m] = (min(best[m][0], dw), min(best[m][1], dc))
    return {m: {"wall_ms": b[0] * 1e3, "cpu_ms": b[1] * 1e3} for m, b in best.items()}


def _switch(name):
    import importlib  # noqa: PLC0415

    return importlib.import_module({"opencl": "fpiwarp.backends.opencl.prepared",
                                    "gl": "fpiwarp.backends.gl.coarse"}[name])


def _line(row, backends):
    band = "" if row["band"] is None else f"{row['band']:.2f}"
    parts = [f"| {row['family']} | {row['size']} | {band} | {row['measured']:.2f} | {row['predicted']:.2f}"
             f" | {row['screen']:.2f} | {row['rule_ms']:.2f}"]
    for name in backends:
        r = row[name]
        best = min(r["off"]["wall_ms"], r["on"]["wall_ms"])
        parts.append(f" | {r['off']['wall_ms']:.2f} / {r['off']['cpu_ms']:.2f} | {r['on']['wall_ms']:.2f} /"
                     f" {r['on']['cpu_ms']:.2f} | {r['chosen']} {r['rule']['wall_ms']:.2f} / {r['rule']['cpu_ms']:.2f}"
                     f" | {r['rule']['wall_ms'] / best:.2f}")
    return "".join(parts) + " |"


def header(backends):
    cols = "| family | size | band | pass (ref) | pass (sampled) | pass (screen) | rule ms"
    line = "|---|---|---|---|---|---|---"
    for name in backends:
        cols += (f" | {name} per-pixel wall / CPU ms | {name} coarse wall / CPU ms | {name} chosen wall / CPU ms"
                 f" | {name} chosen / best")
        line += "|---|---|---|---"
    return cols + " |\n" + line + "|"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--backends", default="opencl,gl")
    parser.add_argument("--out", default=None)
    parser.add_argument("--batches", action="store_true", help="also batches of RandomLocal maps, measured first")
    args = parser.parse_args(argv)
    backends = [b for b in args.backends.split(",") if b]
    info = machine_facts()
    load = os.getloadavg()
    print(f"load {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}, rounds {args.rounds}")
    print(header(backends))
    rows = measure_batches(backends, args.rounds) if args.batches else []
    rows += measure(families(), backends, args.rounds)
    load_after = os.getloadavg()
    print(f"load after {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}")
    if args.out:
        body = "\n".join(_line(r, backends) for r in rows)
        out = Path(args.out)
        write_text(out / "local_pick.md", f"# The coarse pass's choice per map\n\nload {load[0]:.2f} before,"
                   f" {load_after[0]:.2f} after; best of {args.rounds} interleaved rounds\n\n{header(backends)}\n"
                   f"{body}\n\n{machine_markdown(info)}\n")
        write_json(out / "local_pick.json", {"machine": info, "load": [load, load_after], "rows": rows})


if __name__ == "__main__":
    main()
