"""What every benchmark shares: machine facts, timing, maps and images, tables, output files.

A benchmark module imports from here and from nowhere else in ``benchmarks/``
unless it reuses another benchmark's workload. The sections:

- **Machine facts** (:func:`machine_facts`, :func:`machine_markdown`): CPU
  model, ISA (``AVX-512``, ``AVX2``, ...), the PoCL device string (the OpenCL
  code PoCL generates differs between ``pthread-haswell`` (AVX2) and
  ``pthread-skylake-avx512`` machines), cores, load, library versions and each
  backend's device. Figures from two kinds of machine are never mixed: every
  results table starts with :func:`machine_markdown` (or, for a script that
  prints, :func:`machine_line`).
- **Timing** (:func:`time_call`, :func:`best_time`, :func:`interleaved`,
  :func:`frames`): every function calls each implementation once outside the
  clock first (kernel builds, first allocations); :func:`interleaved` times
  several implementations in rounds, one call of each per round, so a burst
  of load on a shared machine lands on all of them alike. Quote ratios of one
  run, never absolute times from two.
- **Maps and images** (:func:`corner_quads`, :func:`frame_fpi`,
  :func:`random_frame_maps`, :func:`test_image`, :func:`remap_maps`,
  :func:`remap_call`): the workloads' inputs and the ``cv2.remap`` baseline
  with its maps precomputed outside the clock.
- **Tables** (:func:`fmt_time`, :func:`fmt_ratio`, :func:`size_label`,
  :func:`markdown_table`).
- **Output** (:data:`RESULTS`, :func:`write_text`, :func:`write_json`): files
  written through a temporary name, so a crash leaves no half file.

Seeded case generators that tests share (random quads, constrained-FPI
configurations) are in :mod:`fpiwarp.testing`, which tests and benchmarks
both import.
"""

import importlib
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

#: Where results land by default: benchmarks/results beside this file.
RESULTS = Path(__file__).resolve().parent / "results"

# ------------------------------------------------------------------ machine facts

#: Libraries whose version every machine description lists.
LIBRARIES = ("fpiwarp", "numpy", "scipy", "cv2", "skimage", "matplotlib", "pyopencl", "moderngl", "warp")


def _cpuinfo():
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            return fh.read()
    except OSError:
        return ""


def cpu_model():
    """The CPU's model name with its family and model numbers where
    /proc/cpuinfo has them (a virtual machine may name only the vendor's
    line, "AMD EPYC", for CPUs of different generations: family 25 is Zen 3
    and 4, 26 Zen 5), else platform's guess."""
    fields = {}
    for line in _cpuinfo().splitlines():
        key, _, value = line.partition(":")
        key = key.strip().lower()
        if key in ("model name", "cpu family", "model") and key not in fields:
            fields[key] = value.strip()
        if not line.strip() and fields:  # the first processor's block only
            break
    name = fields.get("model name")
    if not name:
        return platform.processor() or platform.machine()
    if "cpu family" in fields and "model" in fields:
        return f"{name}, family {fields['cpu family']} model {fields['model']}"
    return name


def cpu_isa():
    """The widest vector extension of the CPU: "AVX-512", "AVX2", "AVX",
    "SSE4.2", or the architecture's name where /proc/cpuinfo has no flags."""
    flags = set()
    for line in _cpuinfo().splitlines():
        if line.lower().startswith(("flags", "features")):
            flags = set(line.split(":", 1)[1].split())
            break
    for flag, name in (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("sse4_2", "SSE4.2")):
        if flag in flags:
            return name
    return platform.machine() or "unknown"


def pocl_devices():
    """The names of PoCL's OpenCL devices (e.g. "pthread-skylake-avx512-AMD
    EPYC"), or one "unavailable: reason" entry."""
    try:
        import pyopencl as cl

        names = [d.name.strip() for p in cl.get_platforms() if "pocl" in (p.name + p.vendor).lower()
                 for d in p.get_devices()]
    except Exception as exc:  # noqa: BLE001 - no driver, no pyopencl: say so in the table
        first = str(exc).splitlines()[0][:80] if str(exc) else ""
        return [f"unavailable: {type(exc).__name__}" + (f": {first}" if first else "")]
    return names or ["unavailable: no PoCL platform"]


def library_versions():
    """{import name: version, or None when not installed}."""
    versions = {}
    for name in LIBRARIES:
        try:
            module = importlib.import_module(name)
        except Exception:  # noqa: BLE001 - a broken install counts as absent
            versions[name] = None
            continue
        versions[name] = str(getattr(module, "__version__", getattr(module, "VERSION", "?")))
    return versions


def backend_devices():
    """{backend: device description, or 'unavailable: reason'}."""
    import fpiwarp
    from fpiwarp.backends import get_backend

    out = {}
    for name, reason in fpiwarp.backend_status().items():
        if reason is not None:
            out[name] = f"unavailable: {reason}"
            continue
        try:
            backend = get_backend(name)
        except Exception as exc:  # noqa: BLE001
            out[name] = f"unavailable: {exc}"
            continue
        out[name] = device_of(name, backend)
    return out


def device_of(name, backend):
    """What a backend object says about its device, best effort."""
    if name == "numpy":
        return "host CPU (numpy, float64)"
    for attr in ("device_label", "renderer", "device_name", "device"):
        value = getattr(backend, attr, None)
        if value is not None and not callable(value):
            return str(value)
    ctx = getattr(backend, "ctx", None) or getattr(getattr(backend, "warper", None), "ctx", None)
    info = getattr(ctx, "info", None)
    if isinstance(info, dict) and "GL_RENDERER" in info:
        return f"{info['GL_RENDERER']} ({info.get('GL_VERSION', '?')})"
    text = repr(backend)
    return type(backend).__module__ if " object at 0x" in text else text


def machine_facts(backends=True):
    """The machine description as a JSON-ready dict. ``backends=False``
    leaves out the backends' devices (which start every backend)."""
    try:
        load = [round(v, 2) for v in os.getloadavg()]
    except OSError:
        load = None
    facts = {
        "cpu": cpu_model(),
        "isa": cpu_isa(),
        "pocl_device": "; ".join(pocl_devices()),
        "cores": os.cpu_count(),
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "load_average_1_5_15min": load,
        "libraries": library_versions(),
    }
    if backends:
        facts["backends"] = backend_devices()
    return facts


#: The line the CPU speed tables end with: the profile of their misses
#: (results/cpu_profile.md, written by hand from sampled profiles).
CPU_PROFILE_POINTER = ("Where the time goes on each kind of CPU (AVX2, AVX-512), and what was tried: "
                       "benchmarks/results/cpu_profile.md.")


def machine_line(info):
    """One line: CPU model, ISA, PoCL device, cores and load (for printed tables)."""
    load = info.get("load_average_1_5_15min")
    return (f"Machine: {info['cpu']} ({info['isa']}), PoCL device {info['pocl_device']}, {info['cores']} cores"
            + (f", load average {load[0]} at start" if load else "") + ".")


def machine_markdown(info):
    """A short Markdown block of :func:`machine_facts`' output, for the top of
    every results table."""
    libs = ", ".join(f"{k} {v}" for k, v in info["libraries"].items() if v is not None)
    lines = [machine_line(info)[:-1] + f", {info['os']}, Python {info['python']}.", "", f"Libraries: {libs}."]
    if info.get("backends"):
        lines += ["", "Backends: " + "; ".join(f"{k}: {v}" for k, v in info["backends"].items()) + "."]
    return "\n".join(lines)


# ------------------------------------------------------------------ timing


def time_call(fn, budget_s=2.0, max_repeats=7, min_repeats=2, slow_s=4.0):
    """Warm up once outside the clock, then the best of repeats within ``budget_s``.

    At least ``min_repeats`` timed calls (one if a call takes over
    ``slow_s``), then more while the budget lasts, at most ``max_repeats``.
    Returns (best seconds, all times).
    """
    t0 = time.perf_counter()
    fn()
    warm = time.perf_counter() - t0
    times, spent = [], 0.0
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


def best_time(fn, repeat=5, number=1, warm_up=True):
    """The best of ``repeat`` timings of ``number`` calls each, per call, in
    seconds (after one call outside the clock unless ``warm_up`` is False)."""
    if warm_up:
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - t0) / number)
    return min(times)


def interleaved(calls, repeats, warm_up=True):
    """Time each of ``calls`` ({name: zero-argument callable}) ``repeats``
    times in rounds, one call of each per round, after one warm-up call of
    each. Returns ({name: [seconds per call]}, {name: its last result})."""
    results = {name: fn() for name, fn in calls.items()} if warm_up else {}
    times = {name: [] for name in calls}
    for _ in range(repeats):
        for name, fn in calls.items():
            t0 = time.perf_counter()
            results[name] = fn()
            times[name].append(time.perf_counter() - t0)
    return times, results


def medians(times):
    """{name: median seconds} of :func:`interleaved`'s times."""
    return {name: statistics.median(ts) for name, ts in times.items()}


def bests(times):
    """{name: best seconds} of :func:`interleaved`'s times."""
    return {name: min(ts) for name, ts in times.items()}


def frames(n, launch, sync, each=True):
    """Seconds per frame over ``n`` calls of ``launch(k)``: each one waited
    for with ``sync()`` (``each``: a preview shows every frame), or only the
    last (throughput)."""
    sync()
    t0 = time.perf_counter()
    for k in range(n):
        launch(k)
        if each:
            sync()
    sync()
    return (time.perf_counter() - t0) / n


# ------------------------------------------------------------------ maps and images


def corner_quads(height, width):
    """Source quad (the image corners) and a generic target quad, in pixels.

    The target moves every corner by 4-12 % of the size, so the FPI is far
    from affine and its pole lies well outside the frame.
    """
    w, h = width - 1.0, height - 1.0
    src = np.array([[0, 0], [w, 0], [w, h], [0, h]])
    dst = np.array([[0.06 * w, 0.10 * h], [0.94 * w, 0.03 * h], [0.88 * w, 0.92 * h], [0.04 * w, 0.97 * h]])
    return src, dst


def frame_fpi(height, width, drag=0.0):
    """A generic FPI of a width × height frame: corners moved by a few
    percent (w/64 units); ``drag`` moves the third corner further (a
    corner dragged in a preview, one frame per value)."""
    import fpiwarp

    s = width / 64.0
    w, h = width, height
    return fpiwarp.FPI([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]],
                       [[4 * s, 3 * s], [w - 4 * s, -2 * s], [w + (3 + drag) * s, h + 2 * s], [-3 * s, h - 4 * s]])


def random_frame_maps(n, height, width, seed=0):
    """``n`` different FPIs of the frame: each corner moved by up to 4 %."""
    import fpiwarp

    rng = np.random.default_rng(seed)
    w, h = width - 1.0, height - 1.0
    src = np.array([[0, 0], [w, 0], [w, h], [0, h]])
    return [fpiwarp.FPI(src, src + rng.uniform(-0.04, 0.04, (4, 2)) * [w, h]) for _ in range(n)]


def test_image(height, width, dtype, rng, channels=3):
    """A smooth picture with some texture and noise (uint8 0..255, uint16
    0..65535 or float32 0..1), RGB by default; a fourth channel repeats the
    first."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    planes = [0.5 + 0.5 * np.sin(x / 17.0), 0.5 + 0.5 * np.cos(y / 23.0), ((x // 32 + y // 32) % 2).astype(np.float32)]
    base = np.stack((planes * 2)[:channels], axis=-1)
    base += 0.05 * rng.standard_normal(base.shape, dtype=np.float32)
    base = np.clip(base, 0, 1)
    if np.dtype(dtype) == np.uint8:
        return (base * 255 + 0.5).astype(np.uint8)
    if np.dtype(dtype) == np.uint16:
        return (base * 65535 + 0.5).astype(np.uint16)
    return base.astype(np.float32)


test_image.__test__ = False  # not a pytest test, whatever its name


def remap_maps(transform, shape):
    """cv2.remap's float32 maps (x, y) of ``transform`` for an output of
    ``shape`` (rows, cols): the numpy reference's source positions."""
    import fpiwarp

    pos = fpiwarp.source_positions(transform, shape).astype(np.float32)
    return np.ascontiguousarray(pos[..., 0]), np.ascontiguousarray(pos[..., 1])


def remap_call(image, transform, shape=None):
    """A zero-argument callable: cv2.remap of ``image`` by ``transform``
    (bilinear, constant border 0) with its maps computed here, outside any
    clock: the cost of resampling alone, the image baseline."""
    import cv2

    mx, my = remap_maps(transform, shape or image.shape[:2])
    return lambda: cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


# ------------------------------------------------------------------ tables


def fmt_time(seconds):
    """"12 µs", "3.4 ms", "1.20 s", or "–" for None."""
    if seconds is None:
        return "–"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.0f} µs"
    if seconds < 1:
        return f"{seconds * 1e3:.1f} ms"
    return f"{seconds:.2f} s"


def fmt_ratio(ratio):
    """"0.82×", "14×", or "–" for None."""
    return "–" if ratio is None else (f"{ratio:.2f}×" if ratio < 10 else f"{ratio:.0f}×")


def size_label(size):
    """"HxW" -> "W×H"; a point count -> "10K pts", "1M pts"."""
    if "x" in size:
        h, w = size.split("x")
        return f"{w}×{h}"
    n = int(size)
    return f"{n // 1_000_000}M pts" if n >= 1_000_000 else f"{n // 1000}K pts"


def markdown_table(header, rows, align=None):
    """A Markdown table: ``header`` a list of titles, ``rows`` lists of cells
    (anything ``str`` takes); ``align`` one of "l"/"r" per column (default:
    the first left, the others right)."""
    align = align or ["l"] + ["r"] * (len(header) - 1)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" if a == "l" else "---:" for a in align) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


# ------------------------------------------------------------------ output files


def write_file(path, write):
    """Call ``write(temporary path)``, then rename it to ``path`` (its
    folder made if missing)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    write(tmp)
    os.replace(tmp, path)


def write_text(path, text):
    write_file(path, lambda p: p.write_text(text, encoding="utf-8"))


def write_json(path, data):
    write_text(path, json.dumps(data, indent=1, ensure_ascii=False, allow_nan=False) + "\n")
