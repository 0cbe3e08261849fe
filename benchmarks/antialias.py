"""Antialiasing: quality against an exact supersampled reference, and cost.

Quality. Each case shrinks a picture by a map; every method's output is
compared (PSNR, peak 1) with a reference that averages 8 × 8 sub-samples
per output pixel (:data:`REF_SUB`) taken at float64 positions through the
map's exact inverse: the box integral of the pixel square's preimage.
The zone plate's reference evaluates the plate's formula itself (its
image is the formula rasterized at pixel centers); a photo's samples it
bilinearly at those positions. PSNR is taken over the output pixels
whose source position lies at least 2 px inside the picture (borders
are the border mode's business, not the filter's).

Cases: a uniform scale (where ``cv2.resize(INTER_AREA)`` and
``skimage.transform.rescale(anti_aliasing=True)`` apply), an FPI that
shrinks by about the same factor (the issue's map, scaled), and
anisotropic FPIs (one direction shrunk much more than the other).
Methods: fpiwarp order 1 without and with antialiasing (the numpy
reference: every backend agrees with it; since issue 29 the footprint
average reads a source pyramid, see fpiwarp.sampling.pyramid), ``cv2.remap`` (bilinear) at the same positions,
``skimage.transform.warp`` (order 1), where the gl backend runs its
hardware-filtered antialiasing (:data:`HW_METHOD`: ``hardware_filter``
with ``antialias``, the texture unit's trilinear filtering of the source's
mipmaps by textureGrad) and, for uniform scales, the two resizers.

Cost. 1920 × 1080 RGB uint8 pictures warped by the FPI of each shrink
factor into an output of the shrunk size, on each backend that
antialiases, with and without antialiasing, timed side by side (best of
several calls after a warm-up); the ratio is the cost of antialiasing.
Every call after the first warps the same pixels, so that every backend
reuses the source's kept pyramid (fpiwarp.sampling.pyramid.SourcePyramids),
as when a tool warps one picture many times; each call builds nothing
else again. A backend that fails a call is reported with its error, the
others still run. Beside them, for uniform shrinks, the peers'
antialiased resizers on the same picture: ``cv2.resize(INTER_AREA)`` and
``skimage.transform.rescale(anti_aliasing=True)`` (order 1), with their
time relative to the fastest plain fpiwarp warp of that shrink. The row
"gl hardware_filter" (:data:`COST_VARIANTS`) times gl's
``hardware_filter`` with and without antialiasing; its ``vs plain gl``
is its antialiased time over plain gl's (software sampling) of that run.

``python3 -m benchmarks.antialias --hardware-filter`` reruns only those
(the gl hardware-filtered column and the gl cost rows) and writes them as
a separate section of results/antialias.md (and a key of antialias.json),
marked as another run, with that run's machine line; a full run
(``python3 -m benchmarks --only antialias``) puts them in the tables.
"""

import argparse
import json
import os
import time
from dataclasses import dataclass

import numpy as np

import fpiwarp
from fpiwarp.sampling.sampler import sample

REF_SUB = 8
SHRINKS = (1.5, 2, 3, 4, 8)
QUICK_SHRINKS = (2, 3)
ANISO = ((4, 1), (6, 1.5))
#: (x, y) shrinks of the cost table: uniform ones and anisotropic ones
COST_SHRINKS = ((1.5, 1.5), (2, 2), (4, 4), (8, 8), (4, 1), (6, 1.5))
COST_SIZE = (1080, 1920)
#: FPI shrinks whose crops the figure shows: level 0 of the pyramid, and far up it
CROP_SHRINKS = ("1/3", "1/8")
QUICK_COST_SIZE = (120, 160)
#: The quality column of gl's hardware-filtered antialiasing.
HW_METHOD = "gl hardware_filter antialias"
#: Cost rows that run a backend with options: name -> (backend, backend_options).
COST_VARIANTS = {"gl hardware_filter": ("gl", {"hardware_filter": True})}
#: The title of the separate section (:func:`main`) in results/antialias.md.
HW_SECTION = "## GL hardware filter (a separate run)"


def zone_plate(n):
    """The formula of an n × n zone plate: 0.5 + 0.5 cos(π r² / n), r from
    the center, reaching the Nyquist frequency at the edges' midpoints."""
    def plate(x, y):
        return 0.5 + 0.5 * np.cos(np.pi * ((x - n / 2) ** 2 + (y - n / 2) ** 2) / n)
    return plate


def pictures(quick):
    """(name, float32 image (H, W, C) in [0, 1], formula or None)."""
    from skimage import data  # noqa: PLC0415 - benchmark peer, imported when run

    n = 256 if quick else 1024
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    plate = zone_plate(n)
    out = [("zone plate", plate(xx, yy)[..., None].astype(np.float32), plate)]
    astro = data.astronaut().astype(np.float32) / 255
    camera = data.camera().astype(np.float32)[..., None] / 255
    if quick:
        astro, camera = astro[::4, ::4], camera[::4, ::4]
    return out + [("astronaut", astro, None), ("camera", camera, None)]


def fpi_shrink(h, w, sx, sy=None):
    """The issue's FPI (corners of the frame to a skewed quad) shrinking x
    by 1/sx and y by 1/sy; with the output shape that holds it."""
    sy = sx if sy is None else sy
    unit = np.array([[0.05, 0.1], [0.9, 0.0], [1.0, 0.8], [0.0, 0.95]])
    dst = unit * [(w - 1) / sx, (h - 1) / sy]
    src = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    return fpiwarp.FPI(src, dst), (int(np.ceil(dst[:, 1].max())) + 1, int(np.ceil(dst[:, 0].max())) + 1)


def uniform_scale(h, w, s):
    """The map of cv2.resize(INTER_AREA) to round(size / s): pixel centers
    x_out = k (x + 1/2) - 1/2 per axis; and that output shape."""
    oh, ow = max(1, round(h / s)), max(1, round(w / s))
    kx, ky = ow / w, oh / h
    b = complex(0.5 * kx - 0.5, 0.5 * ky - 0.5)
    return fpiwarp.RLinear((kx + ky) / 2, (kx - ky) / 2, b), (oh, ow)


def reference(image, formula, transform, shape):
    """The 8 × 8 supersampled box average over each output pixel (float64)."""
    inv = transform.inverse
    oh, ow = shape
    gy, gx = np.mgrid[0:oh, 0:ow].astype(np.float64)
    acc = np.zeros((oh, ow, image.shape[2]))
    img64 = image.astype(np.float64)
    for j in range(REF_SUB):
        for i in range(REF_SUB):
            q = np.stack([gx + (i + 0.5) / REF_SUB - 0.5, gy + (j + 0.5) / REF_SUB - 0.5], axis=-1)
            p = inv(q)
            if formula is not None:
                acc += formula(p[..., 0], p[..., 1])[..., None]
            else:
                acc += sample(img64, p[..., 0], p[..., 1], 1, "edge", 0.0)
    return acc / REF_SUB**2


def interior(image, transform, shape, margin=2):
    pos = fpiwarp.source_positions(transform, shape)
    h, w = image.shape[:2]
    with np.errstate(invalid="ignore"):
        return ((pos[..., 0] >= margin) & (pos[..., 0] <= w - 1 - margin)
                & (pos[..., 1] >= margin) & (pos[..., 1] <= h - 1 - margin))


def psnr(got, ref, mask):
    err = np.mean((got.astype(np.float64).reshape(ref.shape)[mask] - ref[mask]) ** 2)
    return float("inf") if err == 0 else float(10 * np.log10(1.0 / err))


def methods(image, transform, shape, uniform):
    """{method: callable() -> output float image}; :data:`HW_METHOD` where
    the gl backend runs."""
    import cv2  # noqa: PLC0415 - benchmark peers
    from skimage import transform as sktf  # noqa: PLC0415

    pos = fpiwarp.source_positions(transform, shape).astype(np.float32)
    inv = transform.inverse
    chan = image.shape[2]

    def sk_warp():
        return sktf.warp(image, lambda rc: inv(rc), output_shape=shape, order=1, mode="edge")

    out = {
        "fpiwarp order 1": lambda: fpiwarp.warp_image(image, transform, shape, mode="edge", backend="numpy"),
        "fpiwarp order 1 antialias": lambda: fpiwarp.warp_image(image, transform, shape, mode="edge",
                                                                antialias=True, backend="numpy"),
        "fpiwarp order 3 antialias": lambda: fpiwarp.warp_image(image, transform, shape, order=3, mode="edge",
                                                                antialias=True, backend="numpy"),
        "cv2.remap linear": lambda: cv2.remap(image, pos[..., 0], pos[..., 1], cv2.INTER_LINEAR,
                                              borderMode=cv2.BORDER_REPLICATE).reshape(shape + (chan,)),
        "skimage warp order 1": sk_warp,
    }
    if "gl" in fpiwarp.available_backends():
        out[HW_METHOD] = lambda: fpiwarp.warp_image(image, transform, shape, mode="edge", antialias=True,
                                                    backend="gl", backend_options={"hardware_filter": True})
    if uniform:
        out["cv2.resize INTER_AREA"] = lambda: cv2.resize(image, shape[::-1], interpolation=cv2.INTER_AREA).reshape(
            shape + (chan,))
        out["skimage rescale anti_aliasing"] = lambda: sktf.resize(
            image, shape + (chan,), order=1, anti_aliasing=True, mode="edge")
    return out


@dataclass
class Case:
    picture: str
    kind: str  # "uniform", "fpi" or "aniso"
    shrink: str
    psnr: dict


def quality(quick, log=print, only=None):
    """Every case's PSNR per method (``only``: those methods only)."""
    cases, crops = [], {}
    for name, image, formula in pictures(quick):
        h, w = image.shape[:2]
        plans = [("uniform", f"1/{s}", *uniform_scale(h, w, s)) for s in (QUICK_SHRINKS if quick else SHRINKS)]
        plans += [("fpi", f"1/{s}", *fpi_shrink(h, w, s)) for s in (QUICK_SHRINKS if quick else SHRINKS)]
        plans += [("aniso", f"1/{sx} x 1/{sy}", *fpi_shrink(h, w, sx, sy)) for sx, sy in ANISO]
        plans += [("identity", "1", fpiwarp.RLinear(1, 0, 0), (h, w)), ("magnify", "x1.7", *fpi_shrink(h, w, 1 / 1.7))]
        for kind, label, transform, shape in plans:
            ref = reference(image, formula, transform, shape)
            mask = interior(image, transform, shape)
            scores = {}
            for method, run in methods(image, transform, shape, kind == "uniform").items():
                if only is not None and method not in only:
                    continue
                got = run()
                scores[method] = round(psnr(got, ref, mask), 2)
                if kind == "fpi" and label in CROP_SHRINKS:
                    crops.setdefault((name, label), {"reference": ref})[method] = got.reshape(ref.shape)
            cases.append(Case(name, kind, label, scores))
            log(f"antialias {name} {kind} {label}: " + ", ".join(f"{k} {v}" for k, v in scores.items()))
    return cases, crops


def _best_time(fn, budget=2.0, at_most=7):
    """The least wall-clock and the least CPU time (this process, all its
    threads) of several calls after a warm-up, in seconds."""
    fn()
    times, cpu, start = [], [], time.perf_counter()
    while len(times) < 2 or (len(times) < at_most and time.perf_counter() - start < budget):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(times), min(cpu)


def cost(quick, log=print, backends=None):
    """[{backend, shrink, plain_s, antialias_s, ratio, plain_cpu_s,
    antialias_cpu_s, cpu_ratio}] at COST_SIZE (a failing backend: {backend,
    shrink, error}). The CPU times (the work of the process's threads: CPU
    backends run in-process) are the steadier measure on a shared machine,
    where other processes stretch the wall clock of one call but not its
    CPU time. ``backends``: names to time (default: every available one
    that antialiases, and the :data:`COST_VARIANTS` of those). A variant's
    rows also hold ``vs_plain_base`` and ``vs_plain_base_cpu``: its
    antialiased time over its backend's plain time without options, timed
    in the same alternation."""
    h, w = QUICK_COST_SIZE if quick else COST_SIZE
    image = _cost_image(h, w)
    rows = []
    if backends is None:
        backends = [b for b in fpiwarp.available_backends() if fpiwarp.backends.backend_capabilities(b).antialias]
        backends += [v for v, (b, _) in COST_VARIANTS.items() if b in backends]
    for backend in backends:
        name, options = COST_VARIANTS.get(backend, (backend, None))
        for sx, sy in COST_SHRINKS:
            transform, shape = fpi_shrink(h, w, sx, sy)
            label = _shrink_label(sx, sy)

            def plain(b=name, t=transform, sh=shape, o=options):
                return fpiwarp.warp_image(image, t, sh, backend=b, backend_options=o)

            def smooth(b=name, t=transform, sh=shape, o=options):
                return fpiwarp.warp_image(image, t, sh, backend=b, antialias=True, backend_options=o)

            def base(b=name, t=transform, sh=shape):
                return fpiwarp.warp_image(image, t, sh, backend=b)

            calls = (plain, smooth) + ((base,) if options else ())
            try:
                # alternated, so that a change of the machine's load hits all alike
                runs = [tuple(_best_time(fn) for fn in calls) for _ in range(2)]
            except Exception as exc:  # noqa: BLE001 - one backend's failure is a result, the others still run
                rows.append({"backend": backend, "shrink": label, "error": f"{type(exc).__name__}: {exc}"[:200]})
                log(f"antialias cost {backend} {label}: failed: {rows[-1]['error']}")
                continue
            best = [np.min([r[k] for r in runs], axis=0) for k in range(len(calls))]
            (t_plain, c_plain), (t_aa, c_aa) = best[:2]
            rows.append({"backend": backend, "shrink": label, "plain_s": t_plain, "antialias_s": t_aa,
                         "ratio": round(t_aa / t_plain, 2), "plain_cpu_s": c_plain, "antialias_cpu_s": c_aa,
                         "cpu_ratio": round(c_aa / c_plain, 2)})
            if options:
                rows[-1].update(vs_plain_base=round(t_aa / best[2][0], 2),
                                vs_plain_base_cpu=round(c_aa / best[2][1], 2))
            log(f"antialias cost {backend} {label}: {t_plain * 1e3:.1f} ms -> {t_aa * 1e3:.1f} ms")
    return rows


def _cost_image(h, w):
    """The cost table's random RGB uint8 source (read-only: the benchmark never writes it)."""
    image = np.random.default_rng(0).integers(0, 256, size=(h, w, 3), dtype=np.uint8)
    image.flags.writeable = False
    return image


def _shrink_label(sx, sy):
    return f"1/{sx}" if sx == sy else f"1/{sx} x 1/{sy}"


def peer_cost(quick, fpiwarp_rows, log=print):
    """[{peer, shrink, s, cpu_s, vs_plain}]: the antialiased resizers on the
    cost table's source at its uniform shrinks; ``vs_plain`` is the time
    over the fastest plain fpiwarp warp of that shrink (wall clock)."""
    import cv2  # noqa: PLC0415 - benchmark peers
    from skimage import transform as sktf  # noqa: PLC0415

    h, w = QUICK_COST_SIZE if quick else COST_SIZE
    image = _cost_image(h, w)
    rows = []
    for sx, sy in COST_SHRINKS:
        if sx != sy:
            continue
        label = _shrink_label(sx, sy)
        size = (max(1, round(w / sx)), max(1, round(h / sy)))
        peers = {
            "cv2.resize INTER_AREA": lambda sz=size: cv2.resize(image, sz, interpolation=cv2.INTER_AREA),
            "skimage rescale anti_aliasing": lambda s=sx: sktf.rescale(image, 1 / s, order=1, anti_aliasing=True,
                                                                        channel_axis=-1),
        }
        plain = [r["plain_s"] for r in fpiwarp_rows if r["shrink"] == label and "plain_s" in r]
        for name, fn in peers.items():
            t, c = _best_time(fn)
            rows.append({"peer": name, "shrink": label, "s": t, "cpu_s": c,
                         "vs_plain": round(t / min(plain), 2) if plain else None})
            log(f"antialias cost {name} {label}: {t * 1e3:.1f} ms")
    return rows


def run(quick=False, log=print, backends=None):
    cases, crops = quality(quick, log)
    rows = cost(quick, log, backends)
    return {"cases": cases, "crops": crops, "cost": rows, "peer_cost": peer_cost(quick, rows, log), "quick": quick}


def to_json(result):
    return {
        "reference_subsamples": REF_SUB,
        "psnr_db": [{"picture": c.picture, "kind": c.kind, "shrink": c.shrink, **c.psnr} for c in result["cases"]],
        "cost": result["cost"],
        "peer_cost": result["peer_cost"],
    }


def markdown(result, machine_md):
    lines = ["# Antialiasing", "",
             f"PSNR (dB, peak 1) against a {REF_SUB}×{REF_SUB} supersampled box reference at float64 positions "
             "through the exact inverse; interior pixels only. `uniform`: a pure scale (where resizers apply); "
             "`fpi`: the issue's FPI shrinking by about that factor; `aniso`: x and y shrunk by different factors; "
             "`identity`/`magnify`: no shrinking. Border mode edge everywhere. See benchmarks/antialias.py.", ""]
    names = []
    for c in result["cases"]:
        names += [m for m in c.psnr if m not in names]
    lines += ["| picture | map | shrink | " + " | ".join(names) + " |", "|---" * (3 + len(names)) + "|"]
    for c in result["cases"]:
        cells = [f"{c.psnr[m]:.2f}" if m in c.psnr else "" for m in names]
        lines.append(f"| {c.picture} | {c.kind} | {c.shrink} | " + " | ".join(cells) + " |")
    lines += ["", "## Cost", "",
              f"{'x'.join(map(str, (QUICK_COST_SIZE if result['quick'] else COST_SIZE)[::-1]))} RGB uint8 source, "
              "FPI shrink into an output of the shrunk size, best of several calls, same run; wall clock and "
              "CPU time of the process (all threads; the steadier on a loaded machine). Every call warps the same "
              "source, so the backends reuse its pyramid after the first call (the rule: "
              "docs/guides/antialiasing.rst); `python3 -m benchmarks.pyramid_reuse` times a pyramid built per call "
              "beside a reused one:", "",
              "| backend | shrink | without AA (ms) | with AA (ms) | ratio | CPU without (ms) | CPU with (ms) "
              "| CPU ratio |", "|---|---|---|---|---|---|---|---|"]
    for r in result["cost"]:
        if "error" in r:
            lines.append(f"| {r['backend']} | {r['shrink']} | failed: {r['error']} | | | | | |")
            continue
        lines.append(f"| {r['backend']} | {r['shrink']} | {r['plain_s'] * 1e3:.1f} | {r['antialias_s'] * 1e3:.1f} "
                     f"| {r['ratio']:.2f} | {r['plain_cpu_s'] * 1e3:.1f} | {r['antialias_cpu_s'] * 1e3:.1f} "
                     f"| {r['cpu_ratio']:.2f} |")
    lines += ["", "Peers' antialiased resizers on the same source at the uniform shrinks (best of several calls, "
              "same run); `vs fastest plain fpiwarp`: their time over the fastest plain fpiwarp warp of that "
              "shrink:", "", "| peer | shrink | time (ms) | CPU (ms) | vs fastest plain fpiwarp |",
              "|---|---|---|---|---|"]
    for r in result["peer_cost"]:
        vs = "" if r["vs_plain"] is None else f"{r['vs_plain']:.2f}"
        lines.append(f"| {r['peer']} | {r['shrink']} | {r['s'] * 1e3:.1f} | {r['cpu_s'] * 1e3:.1f} | {vs} |")
    versus = [f"{r['shrink']} {r['vs_plain_base']:.2f} ({r['vs_plain_base_cpu']:.2f} CPU)"
              for r in result["cost"] if "vs_plain_base" in r]
    if versus:
        lines += ["", "The gl hardware_filter rows' antialiased time over plain gl's (software sampling, no "
                  "options) of the same shrink, timed alternately with them: " + ", ".join(versus) + "."]
    return "\n".join(lines + ["", machine_md]) + "\n"


def hardware_filter_markdown(result, machine_md):
    """The separate section of :func:`main`: the :data:`HW_METHOD` column
    beside the numpy reference's antialiased one (from the main table's
    run, read from ``result["main_psnr"]``), and the gl cost rows."""
    lines = [HW_SECTION, "",
             "From a run other than the tables above (its machine line below): the gl backend's "
             "`hardware_filter` with `antialias` (the texture unit's trilinear filtering of the source's "
             "mipmaps by textureGrad, gradients the footprint edges; Mesa's llvmpipe reports an anisotropy of "
             "16 but its anisotropic filter fails fpiwarp's check, so it runs trilinear), PSNR as above; "
             "`numpy antialias` is the main table's `fpiwarp order 1 antialias`.", "",
             f"| picture | map | shrink | {HW_METHOD} | numpy antialias | fpiwarp order 1 |",
             "|---|---|---|---|---|---|"]
    main_psnr = result.get("main_psnr", {})
    for c in result["cases"]:
        ref = main_psnr.get((c.picture, c.kind, c.shrink), {})
        cells = [f"{v:.2f}" if isinstance(v, float) else "" for v in
                 (c.psnr.get(HW_METHOD), ref.get("fpiwarp order 1 antialias"), ref.get("fpiwarp order 1"))]
        lines.append(f"| {c.picture} | {c.kind} | {c.shrink} | " + " | ".join(cells) + " |")
    lines += ["", "Cost, as above; `vs plain gl`: the antialiased time over plain gl's (software sampling, no "
              "options), timed alternately with it:", "",
              "| backend | shrink | without AA (ms) | with AA (ms) | ratio | CPU ratio | vs plain gl "
              "| CPU vs plain gl |",
              "|---|---|---|---|---|---|---|---|"]
    for r in result["cost"]:
        if "error" in r:
            lines.append(f"| {r['backend']} | {r['shrink']} | failed: {r['error']} | | | | | |")
            continue
        vs = [f"{r[k]:.2f}" if k in r else "" for k in ("vs_plain_base", "vs_plain_base_cpu")]
        lines.append(f"| {r['backend']} | {r['shrink']} | {r['plain_s'] * 1e3:.1f} | {r['antialias_s'] * 1e3:.1f} "
                     f"| {r['ratio']:.2f} | {r['cpu_ratio']:.2f} | {vs[0]} | {vs[1]} |")
    return "\n".join(lines + ["", machine_md]) + "\n"


def main(argv=None):
    """``--hardware-filter``: rerun the gl hardware-filtered parts only and
    write them as the separate section of results/antialias.md and the key
    ``gl_hardware_filter_run`` of antialias.json (see the module docstring)."""
    from . import common  # noqa: PLC0415 - when run as a script

    parser = argparse.ArgumentParser(prog="python3 -m benchmarks.antialias", description=__doc__.splitlines()[0])
    parser.add_argument("--hardware-filter", action="store_true", required=True,
                        help="rerun the gl hardware_filter column and cost rows only")
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run; nothing is written)")
    args = parser.parse_args(argv)
    info = common.machine_facts()
    t0 = time.perf_counter()
    cases, _ = quality(args.quick, only={HW_METHOD})
    rows = cost(args.quick, backends=["gl", "gl hardware_filter"])
    info["wall_s"] = round(time.perf_counter() - t0, 1)
    try:
        info["load_average_at_end"] = [round(v, 2) for v in os.getloadavg()]
    except OSError:
        pass
    md_path, json_path = common.RESULTS / "antialias.md", common.RESULTS / "antialias.json"
    data = json.loads(json_path.read_text(encoding="utf-8"))
    main_psnr = {(c["picture"], c["kind"], c["shrink"]): c for c in data.get("psnr_db", [])}
    machine_md = common.machine_markdown(info)
    if "load_average_at_end" in info:
        machine_md += f"\n\nLoad average at the end: {info['load_average_at_end'][0]}."
    section = hardware_filter_markdown({"cases": cases, "cost": rows, "main_psnr": main_psnr}, machine_md)
    print(section)
    if args.quick:
        return
    text = md_path.read_text(encoding="utf-8").split(HW_SECTION)[0].rstrip("\n")
    common.write_text(md_path, text + "\n\n" + section)
    data["gl_hardware_filter_run"] = {
        "machine": info,
        "psnr_db": [{"picture": c.picture, "kind": c.kind, "shrink": c.shrink, **c.psnr} for c in cases],
        "cost": rows,
    }
    common.write_json(json_path, data)


if __name__ == "__main__":
    main()


def figure(result, path, dpi=90):
    """Crops side by side: reference, fpiwarp with and without AA, peers;
    one row per picture and FPI shrink of CROP_SHRINKS."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    crops = result["crops"]
    cols = ["reference", "fpiwarp order 1", "fpiwarp order 1 antialias", "cv2.remap linear", "skimage warp order 1"]
    fig, axes = plt.subplots(len(crops), len(cols), figsize=(2.6 * len(cols), 2.8 * len(crops)), squeeze=False)
    for row, ((name, label), images) in enumerate(crops.items()):
        ref = images["reference"]
        h, w = ref.shape[:2]
        box = (slice(h // 4, h // 4 + max(8, h // 2)), slice(w // 4, w // 4 + max(8, w // 2)))
        for col, method in enumerate(cols):
            ax = axes[row][col]
            img = np.clip(images[method][box], 0, 1)
            ax.imshow(img[..., 0] if img.shape[2] == 1 else img, cmap="gray", vmin=0, vmax=1,
                      interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(method, fontsize=8)
            if col == 0:
                ax.set_ylabel(f"{name}, FPI {label}", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi, format="png")
    plt.close(fig)
