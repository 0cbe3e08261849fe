"""GL antialiasing cost: warp_image and the preview frame, with and without.

1920 × 1080 RGB uint8, the antialiasing benchmark's FPI shrinks (1/2, 1/8,
1/6 × 1/1.5) into outputs of the shrunk size on the "gl" backend, timed
interleaved (best of several rounds after a warm-up), wall clock and the
process's CPU time (llvmpipe's threads included); the ratio is
antialiased / plain. Also: building the pyramid's atlas on the host (the
part a new source pays once), and one preview frame (Renderer.draw of a
1920 × 1080 picture into a 1920 × 1080 framebuffer, ctx.finish) with the
view fitted to the picture and zoomed out 1/2 and 1/4.

Run: ``python3 -m benchmarks.gl_pyramid [--quick]``; writes
benchmarks/results/gl_pyramid.md and .json.
"""

import argparse
import os
import time

import numpy as np

import fpiwarp

from . import antialias, common

SHRINKS = ((2, 2), (8, 8), (6, 1.5))
ZOOMS = (1, 2, 4)


def _timer(fn):
    def timed():
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        return time.perf_counter() - w0, time.process_time() - c0
    return timed


def _interleaved(calls, rounds):
    """{name: (best wall s, best CPU s)} over ``rounds`` interleaved rounds."""
    timed = {name: _timer(fn) for name, fn in calls.items()}
    for t in timed.values():
        t()  # warm-up: compile, first pyramid
    best = {name: [np.inf, np.inf] for name in calls}
    for _ in range(rounds):
        for name, t in timed.items():
            wall, cpu = t()
            best[name] = [min(best[name][0], wall), min(best[name][1], cpu)]
    return best


def warp_costs(size, rounds, log=print):
    h, w = size
    img = common.test_image(h, w, np.uint8, np.random.default_rng(0))
    rows = []
    for sx, sy in SHRINKS:
        transform, shape = antialias.fpi_shrink(h, w, sx, sy)
        calls = {aa: (lambda aa=aa, t=transform, s=shape: fpiwarp.warp_image(img, t, s, antialias=aa, backend="gl"))
                 for aa in (False, True)}
        best = _interleaved(calls, rounds)
        label = f"1/{sx}" if sx == sy else f"1/{sx} x 1/{sy}"
        row = {"shrink": label, "plain_s": best[False][0], "antialias_s": best[True][0],
               "plain_cpu_s": best[False][1], "antialias_cpu_s": best[True][1]}
        rows.append(row)
        log(f"warp {label}: plain {row['plain_s'] * 1e3:.1f} ms, aa {row['antialias_s'] * 1e3:.1f} ms, "
            f"wall ratio {row['antialias_s'] / row['plain_s']:.2f}, cpu ratio "
            f"{row['antialias_cpu_s'] / row['plain_cpu_s']:.2f}")
    return rows


def pyramid_cost(size, rounds):
    """Best seconds of building the atlas of a 1920 × 1080 RGB uint8 picture
    (None where this tree has no atlas)."""
    try:
        from fpiwarp.backends.gl.pyramid import build_atlas
    except ImportError:
        return None
    img = common.test_image(*size, np.uint8, np.random.default_rng(1))
    return _interleaved({"build": lambda: build_atlas(img)}, rounds)["build"][0]


def preview_costs(size, rounds, log=print):
    from fpiwarp.backends import get_backend
    from fpiwarp.viewer import Renderer

    h, w = size
    img = common.test_image(h, w, np.uint8, np.random.default_rng(2))
    warper = get_backend("gl").warper
    ctx = warper.ctx
    renderers = {aa: Renderer(ctx, warper=warper, antialias=aa) for aa in (False, True)}
    tex = ctx.texture((w, h), 4, dtype="f1")
    fbo = ctx.framebuffer(color_attachments=[tex])
    transform = fpiwarp.RLinear(1, 0, 0)
    rows = []
    try:
        for r in renderers.values():
            r.set_image(img)
            r.set_transform(transform)
        fbo.use()
        for zoom in ZOOMS:
            cx, cy = (w - 1) / 2, (h - 1) / 2
            view = (cx - zoom * w / 2, cy - zoom * h / 2, cx + zoom * w / 2, cy + zoom * h / 2)

            def frame(r, view=view):
                r.view = view
                r.draw((0, 0, w, h))
                ctx.finish()
            best = _interleaved({aa: (lambda aa=aa: frame(renderers[aa])) for aa in renderers}, rounds)
            row = {"zoom": f"1/{zoom}", "plain_s": best[False][0], "antialias_s": best[True][0],
                   "plain_cpu_s": best[False][1], "antialias_cpu_s": best[True][1]}
            rows.append(row)
            log(f"preview 1/{zoom}: plain {row['plain_s'] * 1e3:.1f} ms, aa {row['antialias_s'] * 1e3:.1f} ms")
    finally:
        ctx.detect_framebuffer(0).use()
        fbo.release()
        tex.release()
        for r in renderers.values():
            r.release()
    return rows


def markdown(result, machine_md):
    lines = ["# GL antialiasing: cost over the pyramid", "", machine_md, "",
             f"Load average at the start: {result['load']}. 1920 × 1080 RGB uint8, gl backend (llvmpipe); "
             "best of interleaved rounds; ratio = antialiased / plain (wall, and the process's CPU time). "
             "See benchmarks/gl_pyramid.py.", "",
             "| shrink | plain (ms) | antialiased (ms) | ratio (wall) | ratio (CPU) |", "|---|---|---|---|---|"]
    for r in result["warp"]:
        lines.append(f"| {r['shrink']} | {r['plain_s'] * 1e3:.1f} | {r['antialias_s'] * 1e3:.1f} | "
                     f"{r['antialias_s'] / r['plain_s']:.2f} | {r['antialias_cpu_s'] / r['plain_cpu_s']:.2f} |")
    if result["pyramid_s"] is not None:
        lines += ["", f"Building the atlas of a new source on the host: {result['pyramid_s'] * 1e3:.1f} ms "
                  "(once per source; reused while its pixels stay)."]
    lines += ["", "Preview frame (Renderer.draw, identity map, view zoomed out):", "",
              "| view | plain (ms) | antialiased (ms) | ratio (wall) | ratio (CPU) |", "|---|---|---|---|---|"]
    for r in result["preview"]:
        lines.append(f"| {r['zoom']} | {r['plain_s'] * 1e3:.1f} | {r['antialias_s'] * 1e3:.1f} | "
                     f"{r['antialias_s'] / r['plain_s']:.2f} | {r['antialias_cpu_s'] / r['plain_cpu_s']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a small picture, few rounds")
    p.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "gl_pyramid"))
    args = p.parse_args(argv)
    size, rounds = ((120, 160), 2) if args.quick else ((1080, 1920), 5)
    info = common.machine_facts()
    result = {"load": " ".join(f"{v:.2f}" for v in os.getloadavg()), "warp": warp_costs(size, rounds),
              "pyramid_s": pyramid_cost(size, rounds), "preview": preview_costs(size, rounds)}
    common.write_json(args.out + ".json", {"machine": info, **result})
    common.write_text(args.out + ".md", markdown(result, common.machine_markdown(info)))


if __name__ == "__main__":
    main()
