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

Every implementation is called once outside the clock (warm-up: kernel
builds, buffer allocation), then timed end to end: numpy array in, numpy
array out, so a device backend's synchronization and transfers are
inside the timed region. The reported time is the best of at least two
timed calls (one for calls over 4 s), more while a 2 s budget lasts. An implementation whose predicted
time at the next size exceeds a limit is skipped with a note, as is
PiecewiseAffineTransform (O(pixels × triangles) in scikit-image) above
1 megapixel.
"""

import time
from dataclasses import asdict, dataclass, field

import numpy as np

import fpiwarp

from . import methods

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
    local_sizes: list = field(default_factory=list)  # benchmarks.speed_extra
    overhead_sizes: list = field(default_factory=list)

    @classmethod
    def quick(cls, backends=None):
        from .speed_extra import OVERHEAD_SIZES, QUICK_LOCAL_SIZES

        return cls(QUICK_POINT_SIZES, QUICK_IMAGE_SIZES, budget_s=0.0, max_repeats=1, max_call_s=2.0, backends=backends,
                   local_sizes=QUICK_LOCAL_SIZES, overhead_sizes=OVERHEAD_SIZES[:1])

    @classmethod
    def full(cls, backends=None):
        from .speed_extra import LOCAL_SIZES, OVERHEAD_SIZES

        return cls(POINT_SIZES, IMAGE_SIZES, backends=backends, local_sizes=LOCAL_SIZES, overhead_sizes=OVERHEAD_SIZES)


def time_call(fn, budget_s, max_repeats, min_repeats=2, slow_s=4.0):
    """Warm up once outside the clock, then best of repeats within ``budget_s``.

    At least ``min_repeats`` timed calls (one if a call takes over
    ``slow_s``), then more while the budget lasts, at most ``max_repeats``.
    Returns (best seconds, all times).
    """
    t0 = time.perf_counter()
    fn()
    warm = time.perf_counter() - t0
    times = []
    spent = 0.0
    while len(times) < max_repeats:
        if times:
            wanted = len(times) < min_repeats and max(warm, times[-1]) < slow_s
            if not wanted and spent + min(times) > budget_s:
                break
        t0 = time.perf_counter()
        fn()
        dt = time.perf_counter() - t0
        times.append(dt)
        spent += dt
    return min(times), times


def corner_quads(height, width):
    """Source quad (the image corners) and a generic target quad, in pixels.

    The target moves every corner by 4-12 % of the size, so the FPI is
    far from affine and its pole lies well outside the frame.
    """
    w, h = width - 1.0, height - 1.0
    src = np.array([[0, 0], [w, 0], [w, h], [0, h]])
    dst = np.array([[0.06 * w, 0.10 * h], [0.94 * w, 0.03 * h], [0.88 * w, 0.92 * h], [0.04 * w, 0.97 * h]])
    return src, dst


def test_image(height, width, dtype, rng):
    """A smooth RGB image with some texture (values 0..255 or 0..1)."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    base = np.stack(
        [0.5 + 0.5 * np.sin(x / 17.0), 0.5 + 0.5 * np.cos(y / 23.0), ((x // 32 + y // 32) % 2).astype(np.float32)],
        axis=-1,
    )
    base += 0.05 * rng.standard_normal(base.shape, dtype=np.float32)
    base = np.clip(base, 0, 1)
    if dtype == "uint8":
        return (base * 255 + 0.5).astype(np.uint8)
    return base.astype(np.float32)


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
    maps = fpiwarp.source_positions(transform, shape).astype(np.float32)
    map_x, map_y = np.ascontiguousarray(maps[..., 0]), np.ascontiguousarray(maps[..., 1])

    def remap_precomputed():
        return cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    def numpy_maps_remap():
        m = fpiwarp.source_positions(transform, shape).astype(np.float32)
        return cv2.remap(image, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    homography = cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32))
    impls[IMAGE_BASELINE] = ("peer", remap_precomputed)
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

    from . import speed_extra

    results += speed_extra.run_overhead(settings.overhead_sizes, settings, backends, rng, log)
    results += speed_extra.run_local(settings.local_sizes, settings, backends, rng, log)
    return results


def _brief(rows):
    return ", ".join(
        f"{impl.replace('fpiwarp ', '')} {row.seconds * 1e3:.1f} ms"
        for impl, row in rows.items()
        if row.seconds is not None
    )


# ---------------------------------------------------------------- reporting


def _fmt_time(s):
    if s is None:
        return "–"
    if s < 1e-3:
        return f"{s * 1e6:.0f} µs"
    if s < 1:
        return f"{s * 1e3:.1f} ms"
    return f"{s:.2f} s"


def _fmt_ratio(r):
    return "–" if r is None else (f"{r:.2f}×" if r < 10 else f"{r:.0f}×")


def table(results, workload, dtype, what="both"):
    """Markdown table: one row per implementation, one column per size.

    ``what`` is "time", "ratio" or "both" (time and ratio in each cell).
    """
    rows = [r for r in results if r.workload == workload and r.dtype == dtype]
    sizes = list(dict.fromkeys(r.size for r in rows))
    impls = list(dict.fromkeys(r.impl for r in rows))
    cell = {(r.impl, r.size): r for r in rows}
    head = "| implementation | " + " | ".join(_size_label(s) for s in sizes) + " |"
    lines = [head, "|---|" + "---:|" * len(sizes)]
    for impl in impls:
        cells = []
        for s in sizes:
            r = cell.get((impl, s))
            if r is None or r.seconds is None:
                cells.append("skipped" if r is not None and r.note.startswith("skipped") else ("error" if r else "–"))
            elif what == "time":
                cells.append(_fmt_time(r.seconds))
            elif what == "ratio":
                cells.append(_fmt_ratio(r.ratio))
            else:
                cells.append(f"{_fmt_time(r.seconds)} ({_fmt_ratio(r.ratio)})")
        lines.append(f"| {impl} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _size_label(size):
    if "x" in size:
        h, w = size.split("x")
        return f"{w}×{h}"
    n = int(size)
    return f"{n // 1_000_000}M pts" if n >= 1_000_000 else f"{n // 1000}K pts"


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
            columns.append((f"{title}, {_size_label(size)}", {r.impl: r for r in rows if r.size == size}))
    impls = list(dict.fromkeys(impl for _, cells in columns for impl in cells))
    lines = ["| implementation | " + " | ".join(t for t, _ in columns) + " |", "|---|" + "---:|" * len(columns)]
    for impl in impls:
        cells = []
        for _, col in columns:
            r = col.get(impl)
            cells.append(
                ""
                if r is None
                else ("skipped" if r.seconds is None else f"{_fmt_time(r.seconds)} ({_fmt_ratio(r.ratio)})")
            )
        lines.append(f"| {impl} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def notes(results):
    """The distinct skip and error notes, each with where it happened."""
    seen = {}
    for r in results:
        if r.note:
            seen.setdefault((r.impl, r.note), []).append(f"{r.workload} {r.dtype} {_size_label(r.size)}")
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
    from .speed_extra import markdown_parts

    parts += markdown_parts(results)
    extra = notes(results)
    if extra:
        parts += ["", "## Notes", ""] + extra
    return "\n".join(parts) + "\n"


def to_json(results):
    return [asdict(r) for r in results]
