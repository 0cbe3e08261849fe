"""Speed: fpiwarp's backends against the tools users would pick instead.

Two workloads, each over a range of sizes, every implementation measured
side by side in one run (so ratios are meaningful on a noisy machine):

- ``map_points``: an FPI applied to N random points (float64), per
  available backend, beside cv2.perspectiveTransform and scikit-image's
  ProjectiveTransform and ThinPlateSplineTransform on the same points.
  Ratios are against cv2.perspectiveTransform.
- ``map_points constrained``: a ConstrainedFPI (the defaults: a 64-center
  thin-plate spline between two Möbius maps) per backend, beside
  scikit-image's TPS through the same 64 constraint points (ratio baseline).
- ``warp_image``: an FPI warp (bilinear, constant border) of a uint8 RGB
  and a float32 RGB image, per available backend, beside cv2.remap with
  the FPI's maps precomputed outside the clock (the ratio baseline: the
  cost of sampling alone), numpy-computed maps + cv2.remap (the same
  maps computed inside the clock), cv2.warpPerspective and
  skimage.transform.warp with ProjectiveTransform (the projective warp
  through the same corners), PiecewiseAffineTransform (an 8 × 8 mesh of
  the FPI) and ThinPlateSplineTransform (through the same corners).
- ``warp_image local``: a ``LocalDeformation`` (edges 1 and 3 of a quad in
  the middle of the frame: a Newton inverse of a paired thin-plate
  spline inside, similarities beyond the two edges) and a ``ConstrainedFPI``
  of the image corners (edges 0 and 2, Newton inverse everywhere) warped
  per backend, uint8 RGB, beside the FPI warp of the same image on the same
  backend. The ratio of a map's row is to **that backend's FPI warp**
  (the target: a local deformation at most 2× the FPI); the FPI rows carry
  their ratio to ``cv2.remap`` with precomputed maps. ``preview frame`` rows
  (with the gl backend): one frame of the preview's exact picture
  (:class:`fpiwarp.viewer.Renderer`, ``method="pixel"``) drawn into an
  offscreen framebuffer and waited for, the map already uploaded: the FPI's
  and the ``LocalDeformation``'s (target for the latter: at most 60 ms at
  1080p on llvmpipe).
- ``warp_image overhead``: small FPI warps (64² and 256² uint8 RGB), where
  fixed costs per call dominate: each backend's plain ``warp_image``, and
  the prepared form ``fpiwarp.warping.Warper`` called on the image, beside
  ``cv2.remap`` with precomputed maps (the ratio baseline).

Every implementation is called once outside the clock (warm-up: kernel
builds, buffer allocation), then timed end to end: numpy array in, numpy
array out, so a device backend's synchronization and transfers are
inside the timed region. The reported time is the best of at least two
timed calls (one for calls over 4 s), more while a 2 s budget lasts. An implementation whose predicted
time at the next size exceeds a limit is skipped with a note, as is
PiecewiseAffineTransform (O(pixels × triangles) in scikit-image) above
1 megapixel.
"""

import dataclasses
from dataclasses import asdict, dataclass, field

import numpy as np

import fpiwarp
from fpiwarp.warping import Warper

from . import methods
from .common import corner_quads, fmt_ratio, fmt_time, remap_call, size_label, test_image, time_call

POINT_SIZES = [1_000, 10_000, 100_000, 1_000_000, 10_000_000]
IMAGE_SIZES = [(256, 256), (512, 512), (1024, 1024), (1080, 1920), (2160, 3840)]
QUICK_POINT_SIZES = [1_000, 20_000]
QUICK_IMAGE_SIZES = [(64, 64), (128, 160)]
DTYPES = ("uint8", "float32")

POINTS_BASELINE = "cv2.perspectiveTransform"
TPS_BASELINE = "skimage ThinPlateSplineTransform (same centers)"
IMAGE_BASELINE = "cv2.remap (precomputed maps)"
#: scikit-image's PiecewiseAffineTransform tests every pixel against every triangle.
PIECEWISE_MAX_PIXELS = 1_100_000
LOCAL_SIZES = [(1080, 1920), (2160, 3840)]
QUICK_LOCAL_SIZES = [(96, 128)]
OVERHEAD_SIZES = [(64, 64), (256, 256)]
#: Repeats of one overhead measurement (within the settings' time budget):
#: calls of 0.05-2 ms need hundreds for a best time that is not a first
#: call's (cold caches, a driver's worker threads waking up); the image
#: tables' 7 repeats read the 256² Warper 2-3x slower than it runs.
OVERHEAD_REPEATS = 300
LOCAL_MAPS = ("LocalDeformation", "ConstrainedFPI")


@dataclass
class Result:
    """One measurement: an implementation at one size."""

    workload: str  # "map_points" or "warp_image"
    impl: str
    kind: str  # "backend" or "peer"
    size: str  # "1000" points or "HxW"
    n: int  # points or output pixels
    dtype: str
    seconds: float | None = None
    ratio: float | None = None  # seconds / baseline seconds at the same size and dtype
    repeats: int = 0
    times: list = field(default_factory=list)
    note: str = ""


@dataclass
class Settings:
    point_sizes: list
    image_sizes: list
    dtypes: tuple = DTYPES
    budget_s: float = 2.0  # time spent on repeats of one measurement
    max_repeats: int = 7
    max_call_s: float = 12.0  # skip an implementation predicted slower than this per call
    backends: list | None = None  # None: every available backend
    local_sizes: list = field(default_factory=list)
    overhead_sizes: list = field(default_factory=list)

    @classmethod
    def quick(cls, backends=None):
        return cls(QUICK_POINT_SIZES, QUICK_IMAGE_SIZES, budget_s=0.0, max_repeats=1, max_call_s=2.0, backends=backends,
                   local_sizes=QUICK_LOCAL_SIZES, overhead_sizes=OVERHEAD_SIZES[:1])

    @classmethod
    def full(cls, backends=None):
        return cls(POINT_SIZES, IMAGE_SIZES, backends=backends, local_sizes=LOCAL_SIZES, overhead_sizes=OVERHEAD_SIZES)


def _skimage_warp(image, inverse_map, shape):
    from skimage.transform import warp

    return warp(image, inverse_map, output_shape=shape, order=1, mode="constant", cval=0, preserve_range=True)


def _piecewise_affine(inverse, height, width, n=8):
    """skimage PiecewiseAffineTransform from output to source through an
    n × n mesh of the FPI: what skimage offers for a smooth 4-point warp."""
    from skimage.transform import PiecewiseAffineTransform

    xs, ys = np.meshgrid(np.linspace(0, width - 1, n), np.linspace(0, height - 1, n))
    out_pts = np.c_[xs.ravel(), ys.ravel()]
    return methods.from_estimate(PiecewiseAffineTransform, out_pts, inverse(out_pts))


def image_implementations(image, transform, src, dst, backends):
    """{name: (kind, zero-argument callable)} for one image and FPI."""
    import cv2

    height, width = image.shape[:2]
    shape = (height, width)
    impls = {}
    for name in backends:
        impls[f"fpiwarp {name}"] = (
            "backend",
            lambda name=name: fpiwarp.warp_image(image, transform, shape, order=1, mode="constant", backend=name),
        )
    inverse = transform.inverse

    def numpy_maps_remap():
        m = fpiwarp.source_positions(transform, shape).astype(np.float32)
        return cv2.remap(image, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    homography = cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32))
    impls[IMAGE_BASELINE] = ("peer", remap_call(image, transform))
    impls["numpy maps + cv2.remap"] = ("peer", numpy_maps_remap)
    impls["cv2.warpPerspective (PROJ)"] = (
        "peer",
        lambda: cv2.warpPerspective(image, homography, (width, height), flags=cv2.INTER_LINEAR, borderValue=0),
    )
    try:
        proj_inv = methods.projective(dst, src)
        tps_inv, _ = methods.thin_plate_spline(dst, src)
    except ImportError:
        return impls
    impls["skimage warp PROJ"] = ("peer", lambda: _skimage_warp(image, proj_inv, shape))
    if height * width <= PIECEWISE_MAX_PIXELS:
        pwa = _piecewise_affine(inverse, height, width)
        impls["skimage warp PiecewiseAffine"] = ("peer", lambda: _skimage_warp(image, pwa, shape))
    else:
        impls["skimage warp PiecewiseAffine"] = ("peer", None)
    impls["skimage warp TPS"] = ("peer", lambda: _skimage_warp(image, tps_inv, shape))
    return impls


def point_implementations(points, transform, src, dst, backends):
    """{name: (kind, zero-argument callable)} for one point set and FPI."""
    import cv2

    impls = {}
    for name in backends:
        impls[f"fpiwarp {name}"] = ("backend", lambda name=name: fpiwarp.map_points(transform, points, backend=name))
    homography = cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32)).astype(np.float64)
    pts3 = points.reshape(-1, 1, 2)
    impls[POINTS_BASELINE] = ("peer", lambda: cv2.perspectiveTransform(pts3, homography))
    try:
        proj = methods.projective(src, dst)
        tps, _ = methods.thin_plate_spline(src, dst)
    except ImportError:
        return impls
    impls["skimage ProjectiveTransform"] = ("peer", lambda: proj(points))
    impls["skimage ThinPlateSplineTransform"] = ("peer", lambda: tps(points))
    return impls


def constrained_implementations(points, transform, backends):
    """{name: (kind, callable)}: a constrained FPI (TPS core) on the backends,
    beside scikit-image's TPS through the same constraint points."""
    impls = {}
    for name in backends:
        impls[f"fpiwarp {name}"] = ("backend", lambda name=name: fpiwarp.map_points(transform, points, backend=name))
    try:
        tps, _ = methods.thin_plate_spline(*transform.constraints)
    except ImportError:
        return impls
    impls[TPS_BASELINE] = ("peer", lambda: tps(points))
    return impls


def _measure(workload, size_label, n, dtype, impls, settings, last):
    """Time every implementation at one size.

    ``last`` maps impl -> (n, seconds, note) of its previous size. A call
    that took at least 0.2 s (so fixed overheads no longer dominate)
    predicts the next size's time linearly in n.
    """
    rows = {}
    for impl, (kind, fn) in impls.items():
        row = Result(workload, impl, kind, size_label, n, dtype)
        prev = last.get(impl)
        if fn is None:
            row.note = "skipped: O(pixels × triangles) in scikit-image, too slow at this size"
        elif prev is not None and prev[1] is None:
            row.note = "skipped: " + prev[2]
        elif prev is not None and prev[1] >= 0.2 and prev[1] * n / prev[0] > settings.max_call_s:
            row.note = f"skipped: predicted {prev[1] * n / prev[0]:.0f} s per call"
        else:
            try:
                row.seconds, row.times = time_call(fn, settings.budget_s, settings.max_repeats)
                row.repeats = len(row.times)
            except Exception as exc:  # noqa: BLE001 - one broken implementation must not stop the run
                row.note = f"error: {type(exc).__name__}: {str(exc).splitlines()[0][:120]}"
        if row.seconds is not None:
            last[impl] = (n, row.seconds, "")
        elif row.note.startswith(("skipped: predicted", "error")):
            last[impl] = (n, None, "previous size " + row.note)
        rows[impl] = row
    return rows


def _add_ratios(rows, baseline):
    base = rows.get(baseline)
    for row in rows.values():
        if base is not None and base.seconds and row.seconds is not None:
            row.ratio = row.seconds / base.seconds


def run(settings, log=print):
    """Run both workloads; return a list of :class:`Result`."""
    backends = settings.backends if settings.backends is not None else fpiwarp.available_backends()
    rng = np.random.default_rng(0)
    results = []

    last = {}
    for n in settings.point_sizes:
        side = 1000.0
        src, dst = corner_quads(side + 1, side + 1)
        transform = fpiwarp.FPI(src, dst)
        points = rng.uniform(0, side, size=(n, 2))
        impls = point_implementations(points, transform, src, dst, backends)
        rows = _measure("map_points", str(n), n, "float64", impls, settings, last)
        _add_ratios(rows, POINTS_BASELINE)
        results.extend(rows.values())
        log(f"map_points {n:>10,d}: " + _brief(rows))

    constrained = getattr(fpiwarp, "ConstrainedFPI", None)
    if constrained is not None:
        last = {}
        for n in settings.point_sizes:
            src, dst = corner_quads(1001, 1001)
            transform = constrained(src, dst, edges=(0, 2))
            points = rng.uniform(0, 1000.0, size=(n, 2))
            impls = constrained_implementations(points, transform, backends)
            rows = _measure("map_points constrained", str(n), n, "float64", impls, settings, last)
            _add_ratios(rows, TPS_BASELINE)
            results.extend(rows.values())
            log(f"map_points constrained {n:>10,d}: " + _brief(rows))

    for dtype in settings.dtypes:
        last = {}
        for height, width in settings.image_sizes:
            image = test_image(height, width, dtype, rng)
            src, dst = corner_quads(height, width)
            transform = fpiwarp.FPI(src, dst)
            impls = image_implementations(image, transform, src, dst, backends)
            label = f"{height}x{width}"
            rows = _measure("warp_image", label, height * width, dtype, impls, settings, last)
            _add_ratios(rows, IMAGE_BASELINE)
            results.extend(rows.values())
            log(f"warp_image {dtype:7s} {label:>9s}: " + _brief(rows))
            del image, impls

    results += run_overhead(settings.overhead_sizes, settings, backends, rng, log)
    results += run_local(settings.local_sizes, settings, backends, rng, log)
    return results


def _brief(rows):
    return ", ".join(
        f"{impl.replace('fpiwarp ', '')} {row.seconds * 1e3:.1f} ms"
        for impl, row in rows.items()
        if row.seconds is not None
    )


# ---------------------------------------------------------------- reporting


def table(results, workload, dtype, what="both"):
    """Markdown table: one row per implementation, one column per size.

    ``what`` is "time", "ratio" or "both" (time and ratio in each cell).
    """
    rows = [r for r in results if r.workload == workload and r.dtype == dtype]
    sizes = list(dict.fromkeys(r.size for r in rows))
    impls = list(dict.fromkeys(r.impl for r in rows))
    cell = {(r.impl, r.size): r for r in rows}
    head = "| implementation | " + " | ".join(size_label(s) for s in sizes) + " |"
    lines = [head, "|---|" + "---:|" * len(sizes)]
    for impl in impls:
        cells = []
        for s in sizes:
            r = cell.get((impl, s))
            if r is None or r.seconds is None:
                cells.append("skipped" if r is not None and r.note.startswith("skipped") else ("error" if r else "–"))
            elif what == "time":
                cells.append(fmt_time(r.seconds))
            elif what == "ratio":
                cells.append(fmt_ratio(r.ratio))
            else:
                cells.append(f"{fmt_time(r.seconds)} ({fmt_ratio(r.ratio)})")
        lines.append(f"| {impl} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def headline(results):
    """A compact table for a README: the largest sizes measured, one column
    each for points, uint8 images and float32 images (time and ratio)."""
    columns = []
    for workload, dtype, title in (
        ("map_points", "float64", "map_points"),
        ("warp_image", "uint8", "warp_image uint8 RGB"),
        ("warp_image", "float32", "warp_image float32 RGB"),
    ):
        rows = [r for r in results if r.workload == workload and r.dtype == dtype]
        if rows:
            size = max(rows, key=lambda r: r.n).size
            columns.append((f"{title}, {size_label(size)}", {r.impl: r for r in rows if r.size == size}))
    impls = list(dict.fromkeys(impl for _, cells in columns for impl in cells))
    lines = ["| implementation | " + " | ".join(t for t, _ in columns) + " |", "|---|" + "---:|" * len(columns)]
    for impl in impls:
        cells = []
        for _, col in columns:
            r = col.get(impl)
            cells.append(
                ""
                if r is None
                else ("skipped" if r.seconds is None else f"{fmt_time(r.seconds)} ({fmt_ratio(r.ratio)})")
            )
        lines.append(f"| {impl} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def notes(results):
    """The distinct skip and error notes, each with where it happened."""
    seen = {}
    for r in results:
        if r.note:
            seen.setdefault((r.impl, r.note), []).append(f"{r.workload} {r.dtype} {size_label(r.size)}")
    return [f"- {impl} ({', '.join(where)}): {note}" for (impl, note), where in seen.items()]


def markdown(results, settings, machine_md):
    parts = [
        "# fpiwarp speed benchmark",
        "",
        "Best wall time per call (numpy array in, numpy array out; warm-up outside the clock) and, in",
        f"parentheses, the ratio to the baseline at the same size: `{POINTS_BASELINE}` for points,",
        f"`{IMAGE_BASELINE}` for images (ratio < 1: faster than the baseline). The transform is an FPI",
        "through moved image corners; PROJ rows are the projective warp through the same corners,",
        "PiecewiseAffine an 8 × 8 mesh of the FPI, TPS the thin-plate spline through the corners.",
        "Images: bilinear, constant border, RGB.",
        "",
        machine_md,
        "",
        "## Headline: the largest sizes",
        "",
        headline(results),
        "",
        "## map_points (float64 points)",
        "",
        table(results, "map_points", "float64"),
    ]
    if any(r.workload == "map_points constrained" for r in results):
        parts += [
            "",
            "## map_points, constrained FPI (TPS core)",
            "",
            "A `ConstrainedFPI` (edges 0 and 2, the defaults: 16 points per edge, a 64-center thin-plate",
            f"spline packed as 32 pairs, between two Möbius maps) on the backends; ratios to `{TPS_BASELINE}`,",
            "scikit-image's TPS through the same 64 constraint points (a different map, about the same work).",
            "",
            table(results, "map_points constrained", "float64"),
        ]
    for dtype in settings.dtypes:
        parts += ["", f"## warp_image, {dtype} RGB", "", table(results, "warp_image", dtype)]
    parts += local_markdown_parts(results)
    extra = notes(results)
    if extra:
        parts += ["", "## Notes", ""] + extra
    return "\n".join(parts) + "\n"


# ---------------------------------------------------------------- local deformations, per-call overhead


def local_deformation(height, width):
    """Edges 1 and 3 of a quad over the middle fifth of the frame held to
    similarities; its corners moved by 2-6 % of the size."""
    w, h = width - 1.0, height - 1.0
    src = np.array([[0.4 * w, 0.3 * h], [0.6 * w, 0.3 * h], [0.6 * w, 0.7 * h], [0.4 * w, 0.7 * h]])
    dst = src + np.array([[0.02 * w, -0.05 * h], [0.03 * w, 0.02 * h], [-0.02 * w, 0.06 * h], [0.01 * w, -0.03 * h]])
    return fpiwarp.LocalDeformation(src, dst, edges=(1, 3))


def constrained_fpi(height, width):
    src, dst = corner_quads(height, width)
    return fpiwarp.ConstrainedFPI(src, dst, edges=(0, 2))


def _warp(image, transform, name):
    return lambda: fpiwarp.warp_image(image, transform, order=1, mode="constant", backend=name)


def preview_frame(image, transform):
    """One exact preview frame (Renderer, method "pixel") of ``transform``
    into an offscreen framebuffer, waited for; the objects live as long as
    the returned callable."""
    from fpiwarp.backends import get_backend
    from fpiwarp.viewer import Renderer

    ctx = get_backend("gl").warper.ctx
    height, width = image.shape[:2]
    renderer = Renderer(ctx, order=1, warper=get_backend("gl").warper, method="pixel")
    tex = ctx.texture((width, height), 4, dtype="f1")
    fbo = ctx.framebuffer(color_attachments=[tex])
    renderer.set_image(image)
    renderer.set_transform(transform)

    def frame():
        fbo.use()
        renderer.draw((0, 0, width, height), y_down=True)
        ctx.finish()

    frame.keep = (renderer, tex, fbo)
    return frame


def run_local(sizes, settings, backends, rng, log=print):
    """``warp_image local`` rows: each map per backend, ratio to its FPI."""
    results, last = [], {}
    for height, width in sizes:
        image = test_image(height, width, "uint8", rng)
        fpi = fpiwarp.FPI(*corner_quads(height, width))
        maps = {"LocalDeformation": local_deformation(height, width), "ConstrainedFPI": constrained_fpi(height, width)}
        impls = {IMAGE_BASELINE: ("peer", remap_call(image, fpi))}
        for name in backends:
            impls[f"fpiwarp {name} FPI"] = ("backend", _warp(image, fpi, name))
            for label, transform in maps.items():
                impls[f"fpiwarp {name} {label}"] = ("backend", _warp(image, transform, name))
        if "gl" in backends:
            impls["fpiwarp gl preview frame FPI"] = ("backend", preview_frame(image, fpi))
            impls["fpiwarp gl preview frame LocalDeformation"] = (
                "backend", preview_frame(image, maps["LocalDeformation"]))
        label = f"{height}x{width}"
        rows = _measure("warp_image local", label, height * width, "uint8", impls, settings, last)
        _add_ratios(rows, IMAGE_BASELINE)
        for name in backends:
            fpi_row = rows[f"fpiwarp {name} FPI"]
            for m in LOCAL_MAPS:
                row = rows[f"fpiwarp {name} {m}"]
                row.ratio = row.seconds / fpi_row.seconds if row.seconds and fpi_row.seconds else None
        if "gl" in backends:
            fpi_row, row = rows["fpiwarp gl preview frame FPI"], rows["fpiwarp gl preview frame LocalDeformation"]
            row.ratio = row.seconds / fpi_row.seconds if row.seconds and fpi_row.seconds else None
        results.extend(rows.values())
        log(f"warp_image local {label:>9s}: " + _brief(rows))
    return results


def run_overhead(sizes, settings, backends, rng, log=print):
    """``warp_image overhead`` rows: plain call and Warper per backend."""
    if settings.max_repeats > 1:  # not the quick smoke run
        settings = dataclasses.replace(settings, max_repeats=max(settings.max_repeats, OVERHEAD_REPEATS))
    results, last = [], {}
    for height, width in sizes:
        image = test_image(height, width, "uint8", rng)
        fpi = fpiwarp.FPI(*corner_quads(height, width))
        impls = {IMAGE_BASELINE: ("peer", remap_call(image, fpi))}
        for name in backends:
            impls[f"fpiwarp {name}"] = ("backend", _warp(image, fpi, name))
            warper = Warper(fpi, order=1, mode="constant", backend=name)
            impls[f"fpiwarp {name} Warper"] = ("backend", lambda warper=warper, image=image: warper(image))
        label = f"{height}x{width}"
        rows = _measure("warp_image overhead", label, height * width, "uint8", impls, settings, last)
        _add_ratios(rows, IMAGE_BASELINE)
        results.extend(rows.values())
        log(f"warp_image overhead {label:>9s}: " + _brief(rows))
    return results


def local_markdown_parts(results):
    """The sections of speed.md for these workloads (empty when not run)."""
    parts = []
    if any(r.workload == "warp_image local" for r in results):
        parts += [
            "",
            "## warp_image, local deformations (uint8 RGB)",
            "",
            "A `LocalDeformation` (edges 1 and 3 of a quad over the middle of the frame) and a `ConstrainedFPI`",
            "(edges 0 and 2 of the image corners): Newton inverses of a thin-plate spline of 31 center pairs",
            "per pixel, seeded from the block's table of exact inverses.",
            "Their ratio is to **the FPI warp on the same backend** (target: at most 2×); the FPI rows'",
            f"ratio is to `{IMAGE_BASELINE}`. The `gl preview frame` rows: one exact frame of the preview",
            "(`fpiwarp.viewer.Renderer`, method \"pixel\", offscreen, waited for; target for the local",
            "deformation at 1080p: at most 60 ms), the LocalDeformation's ratio to the FPI's frame.",
            "",
            table(results, "warp_image local", "uint8"),
        ]
    if any(r.workload == "warp_image overhead" for r in results):
        parts += [
            "",
            "## warp_image, per-call overhead (small FPI warps, uint8 RGB)",
            "",
            f"Plain `warp_image` and the prepared `fpiwarp.warping.Warper`; ratios to `{IMAGE_BASELINE}`.",
            "",
            table(results, "warp_image overhead", "uint8"),
        ]
    return parts


def to_json(results):
    return [asdict(r) for r in results]
