"""Frames per second while dragging a handle at 1080p: the browser page in
headless Chromium beside the desktop preview on this machine's GL.

Browser: the --web page (fpiwarp.widget) at a fixed 1920×1080 canvas; one
frame of a drag is a move message to the Python session (over the local
server), the map rebuilt there, the new block uploaded and the frame drawn
and finished (a one-pixel read). "draw only" redraws without a round trip.
Desktop: fpiwarp.viewer's Editor and Renderer into a 1920×1080 framebuffer
of the gl backend's headless context; one frame is the rebuilt map, its
upload and the draw, finished (ctx.finish); "while dragging" uses the
viewer's drag method ("auto": the mesh path for maps of non-constant
distortion), "per pixel" the exact path. Rounds alternate browser and
desktop so that load from other processes hits both alike; figures are
medians of the rounds.

Parity, in the same browser: the share of pixels of the page's frame
within 2 levels of warp_image(..., backend="numpy"), for the maps, orders
and pictures of tests/widget/test_page_parity.py (the test's own
measurement, ``shares``), in a 640×480 window.

Usage::

    python benchmarks/browser_preview.py [--rounds 3] [--out benchmarks/results/browser.md]
"""

import argparse
import math
import statistics
import time
from pathlib import Path

import numpy as np

import fpiwarp

W, H = 1920, 1080
SRC = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]
DST = [[0.05 * W, 0.04 * H], [0.92 * W, -0.04 * H], [1.03 * W, 1.02 * H], [-0.03 * W, 0.93 * H]]
MAPS = {"FPI": lambda: fpiwarp.FPI(SRC, DST),
        "LocalDeformation (edges 0, 2)": lambda: fpiwarp.LocalDeformation(SRC, DST, edges=(0, 2))}


def picture():
    y, x = np.mgrid[0:H, 0:W]
    rng = np.random.default_rng(0)
    img = np.stack([x * 255 // W, y * 255 // H, ((x // 40 + y // 40) % 2) * 200], -1)
    return (img + rng.integers(0, 40, img.shape)).clip(0, 255).astype(np.uint8)


def path(k):
    """The dragged handle's k-th position: a small circle around its start."""
    a = 2 * math.pi * k / 16
    return [DST[2][0] + 30 * math.cos(a), DST[2][1] + 30 * math.sin(a)]


DRAG_JS = """
const [n, pts, done] = [arguments[0], arguments[1], arguments[arguments.length - 1]];
const ed = window.fpiwarpEditor;
(async () => {
  await ed.whenIdle(); ed.finish();
  const t0 = performance.now();
  for (let k = 0; k < n; k++) {
    ed.post({type: "move", index: 2, xy: pts[k]});
    await ed.whenIdle();
    ed.finish();
  }
  const drag = performance.now() - t0;
  ed.post({type: "release"}); await ed.whenIdle();
  const t1 = performance.now();
  for (let k = 0; k < n; k++) { ed.draw(); ed.finish(); }
  done({drag: drag / 1000, draw: (performance.now() - t1) / 1000});
})();
"""


def browser_round(driver, n):
    pts = [path(k) for k in range(n)]
    t = driver.execute_async_script(DRAG_JS, n, pts)
    return n / t["drag"], n / t["draw"]


def desktop_round(editor, renderer, ctx, fbo, n, method):
    fbo.use()
    renderer.method = method
    t0 = time.perf_counter()
    for k in range(n):
        editor.dst[2] = path(k)
        editor.rebuild()
        renderer.draw((0, 0, W, H))
        ctx.finish()
    return n / (time.perf_counter() - t0)



def parity_rows(driver):
    """[(map, order, dtype, {what: share})] of tests/widget/test_page_parity.py."""
    from fpiwarp.widget import browser
    from fpiwarp.widget.server import PageServer
    from fpiwarp.widget.session import Session
    from tests.widget.test_page_parity import MAPS, picture, shares

    rows = []
    driver.set_window_size(640, 480)
    with PageServer(Session(picture(np.uint8), MAPS["fpi"]())) as server:
        browser.open_page(driver, server.url, timeout=300)
        for dtype in (np.uint8, np.uint16):
            for name in MAPS:
                for order in (0, 1, 3):
                    got = shares(driver, lambda s: browser.show(driver, server, s), name, order, dtype)
                    rows.append((name, order, np.dtype(dtype).name, got))
                    print(rows[-1], flush=True)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", default=str(Path(__file__).parent / "results" / "browser.md"))
    args = parser.parse_args(argv)

    from benchmarks.common import cpu_isa, cpu_model, machine_facts, machine_markdown
    from fpiwarp.backends import get_backend
    from fpiwarp.viewer import Editor, Renderer
    from fpiwarp.widget import browser
    from fpiwarp.widget.server import PageServer
    from fpiwarp.widget.session import Session

    img = picture()
    ctx = get_backend("gl").warper.ctx
    fbo = ctx.simple_framebuffer((W, H))
    driver = browser.launch(size=(1280, 800))
    rows, strings = [], {}
    try:
        for name, make in MAPS.items():
            n = 12 if name == "FPI" else 2
            session = Session(img, make(), background=(0.18, 0.18, 0.2, 1.0))
            renderer = Renderer(ctx, background=(0.18, 0.18, 0.2, 1.0), warper=get_backend("gl").warper)
            renderer.handles = renderer.outline = True
            editor = Editor(renderer, img, make())
            with PageServer(session) as server:
                browser.open_page(driver, server.url, timeout=300)
                driver.execute_script("const ed = window.fpiwarpEditor; ed.setFixedSize(arguments[0], "
                                      "ed.state.export_area);", [W, H])
                strings = {"browser": driver.capabilities.get("browserVersion"),
                           **driver.execute_script("return window.fpiwarpEditor.info();")}
                b_drag, b_draw, d_drag, d_pixel = [], [], [], []
                browser_round(driver, 2)  # warm-up: programs compiled
                desktop_round(editor, renderer, ctx, fbo, 2, "auto")
                desktop_round(editor, renderer, ctx, fbo, 2, "pixel")
                for _ in range(args.rounds):
                    drag, draw = browser_round(driver, n)
                    b_drag.append(drag)
                    b_draw.append(draw)
                    d_drag.append(desktop_round(editor, renderer, ctx, fbo, n, "auto"))
                    d_pixel.append(desktop_round(editor, renderer, ctx, fbo, n, "pixel"))
            renderer.release()
            med = statistics.median
            rows.append((name, med(b_drag), med(b_draw), med(d_drag), med(d_pixel)))
            print(rows[-1], flush=True)
        parity = parity_rows(driver)
    finally:
        driver.quit()
        fbo.release()
    info = machine_facts()
    lines = [
        "# Dragging at 1080p: the browser page beside the desktop preview",
        "",
        "Written by `python benchmarks/browser_preview.py`. Frames per second while a handle is dragged, a "
        "1920×1080 RGB uint8 frame; medians of "
        f"{args.rounds} interleaved rounds (browser, desktop, desktop, ...), each frame finished on the GPU.",
        "",
        f"CPU: {cpu_model()}, ISA {cpu_isa()}, {info['cores']} cores (shared with other work; load at start "
        f"{info['load_average_1_5_15min'][0] if info['load_average_1_5_15min'] else '?'}).",
        "",
        f"Browser: Chromium {strings.get('browser')} headless, {strings.get('version')}, "
        f"renderer {strings.get('unmasked') or strings.get('renderer')}.",
        "",
        f"Desktop: {ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']}), headless EGL.",
        "",
        "| map | browser: drag (round trip + draw) | browser: draw only | desktop: drag (viewer's method) "
        "| desktop: drag, per pixel | browser drag / desktop drag |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, bd, bw, dd, dp in rows:
        lines.append(f"| {name} | {bd:.3g} | {bw:.3g} | {dd:.3g} | {dp:.3g} | {bd / dd:.2g} |")
    lines += [
        "",
        "The desktop viewer drags maps of non-constant distortion (the LocalDeformation) by the mesh path; "
        "the page always draws per pixel (WebGL2 has no clip distances for the mesh path's pole culling), "
        "so compare its drag with the desktop's per-pixel column for those.",
        "",
        "Parity, same run: share of the page's pixels within 2 levels of `warp_image(..., backend=\"numpy\")` "
        "(tests/widget/test_page_parity.py's pictures, 72×54; the test asks for 0.99 everywhere). uint16: "
        "*levels* are the 16-bit values (the program into a float target), *shown* the 8-bit canvas.",
        "",
        "| map | order | uint8 | uint16 levels | uint16 shown |",
        "|---|---:|---:|---:|---:|",
    ]
    by = {(m, o, d): got for m, o, d, got in parity}
    for m, o in dict.fromkeys((m, o) for m, o, _, _ in parity):
        u8, u16 = by[(m, o, "uint8")], by[(m, o, "uint16")]
        lines.append(f"| {m} | {o} | {u8['shown']:.4f} | {u16['levels']:.4f} | {u16['shown']:.4f} |")
    lines += [
        "",
        machine_markdown(info),
        "",
    ]
    Path(args.out).write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
