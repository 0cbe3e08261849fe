"""The work-group tile of warp_image, measured once per OpenCL CPU device.

Which tile a CPU device runs fastest depends on the device: on PoCL's
pthread device for an AVX-512 EPYC (2 cores, 1 MiB L2 each), 4K RGB
uint8 FPI warps, best of 7 interleaved in one run, ratios to
``cv2.remap`` with precomputed maps: 64 x 8 tiles 1.56-1.74x, 32 x 16
0.91-1.36x, 16 x 16 1.17-1.28x, 32 x 8 1.03-1.43x (the machine was
shared, hence the spread; narrower, taller tiles keep a group's source
rows and their gathers in the L1/L2 caches). The 64 x 8 tiles were
chosen on an AVX2 machine. So the tile is a per-device choice:

* :func:`tile_for` gives the backend's tile: the one measured for its
  device (kept in memory and on disk beside the OpenCL binaries, in the
  user's cache folder, keyed by the device's name, driver and platform
  versions; not by the kernels' source, so that a new version of the
  kernels keeps the measured tile: every tile gives the same output, and
  :func:`tune` measures again), else :data:`DEFAULT_TILE`.
* :func:`tune` measures :data:`CANDIDATES` on a 1024 x 1024 RGB uint8
  FPI warp (a warm-up call that builds each, then best of a few
  interleaved rounds) and stores the winner. The fast default's
  calibration calls it when it measures the opencl backend
  (:mod:`fpiwarp.backends.default`); the first time on a machine each
  candidate is one build (seconds on PoCL), later builds come from the
  caches. ``FPIWARP_OPENCL_TILE=X,Y`` fixes the tile instead.

The vector width goes with the tile: warp_image samples 8 pixels per
work-item (AVX registers), or 16 where the device's native float vector
is 16 wide (AVX-512). On the AVX-512 EPYC above, kernel time on PoCL's
profiling clock, best of 9 interleaved (loaded machine, load 8-9), 8
lanes / 16 lanes: 4K RGB uint8 1.05-1.22x, 4K RGB float32 1.25-1.28x,
256² RGB uint8 1.12-1.13x (same outputs); whole calls were mixed (4K
float32 1.04x faster, 4K uint8 0.87x, one run at load 3), and with the measured
16 x 16 tiles (load 2) 4K float32 took the same wall time (less CPU
time), 4K uint8 1.18x -> 1.27x cv2.remap, 256² 2.27x -> 1.92x, while the
1024² uint8 tuning warp ran 1.49x faster at 16 lanes: the tuning warp
did not predict the large calls, so 16 lanes stayed opt-in. Since the
interior path reads a row's two taps in one load (FW_PAIR in
fpiwarp_map.h), whole prepared calls at 16 lanes took 0.95-1.0x the time
at 8 on a pthread-skylake-avx512 device (Zen 4, 2 cores, quiet; best of 9
interleaved rounds in one process, 32 x 8 tiles): 4K RGB uint8 27.3
against 28.3 ms, 4K float32 51.7 against 52.4 ms, 1024² 2.79 against
2.94 ms, 512² 0.714 against 0.747 ms, 256² 0.193 against 0.198 ms. So
:func:`tune` now measures the best tile at the device's native width
too where that is 16 and keeps the faster (:func:`lanes_for`);
``FPIWARP_OPENCL_LANES`` fixes the width instead.

Every tile and width gives the same output bit for bit (each pixel's code does not
depend on the tile; tests/backends/opencl/test_opencl_tiles.py), so the
choice changes speed only. Only CPU devices with vector lanes use tiles
(:mod:`.tiles`).
"""

import json
import os
import time

from . import build_cache

ENV_TILE = "FPIWARP_OPENCL_TILE"
ENV_LANES = "FPIWARP_OPENCL_LANES"
#: The tile used until one is measured: (pixels per row, rows).
DEFAULT_TILE = (64, 8)
#: The tiles :func:`tune` measures (each a multiple of the 8 vector lanes wide).
CANDIDATES = ((64, 8), (32, 16), (16, 16), (32, 8))
#: Pixels per work-item until measured, and the widths :func:`tune` may choose.
DEFAULT_LANES, WIDE_LANES = 8, 16
#: The measurement: (rows, cols, channels) of uint8, and timed rounds.
TUNING_SHAPE, TUNING_ROUNDS = (1024, 1024, 3), 5


def _path(backend):
    return build_cache.device_path(backend, "tile")


def _fixed():
    value = os.environ.get(ENV_TILE, "").strip()
    if not value:
        return None
    try:
        x, y = (int(v) for v in value.split(","))
    except ValueError:
        from ...errors import ArgumentError  # noqa: PLC0415

        raise ArgumentError(f"{ENV_TILE} must be X,Y (pixels per row, rows), got {value!r}") from None
    return x, y


def usable(backend, tile):
    """Whether ``tile`` fits the device: a multiple of its lanes wide, within its group size."""
    x, y = tile
    return x > 0 and y > 0 and x % backend.lanes == 0 and x * y <= backend.device.max_work_group_size


def tile_for(backend):
    """The tile warp_image runs in on ``backend`` (see the module docstring)."""
    tile = getattr(backend, "_tile", None)
    if tile is None:
        tile = _fixed()
        if tile is None:
            try:
                tile = tuple(json.loads(_path(backend).read_text(encoding="utf-8"))["tile"])
            except (OSError, ValueError, KeyError, TypeError):
                tile = DEFAULT_TILE
        if not usable(backend, tile):
            tile = DEFAULT_TILE
        backend._tile = tile
    return backend._tile


def lanes_for(backend):
    """The pixels per work-item warp_image samples on a CPU ``backend``:
    the measured width (see the module docstring), else :data:`DEFAULT_LANES`."""
    value = os.environ.get(ENV_LANES, "").strip()
    if value:
        if value not in {str(n) for n in candidate_lanes(backend)}:
            from ...errors import ArgumentError  # noqa: PLC0415

            raise ArgumentError(f"{ENV_LANES} must be one of {list(candidate_lanes(backend))} on this device, "
                                f"got {value!r}")
        return int(value)
    try:
        lanes = int(json.loads(_path(backend).read_text(encoding="utf-8")).get("lanes", DEFAULT_LANES))
    except (OSError, ValueError, AttributeError, TypeError):
        lanes = DEFAULT_LANES
    return lanes if lanes in candidate_lanes(backend) else DEFAULT_LANES


def candidate_lanes(backend):
    """The widths this device may run: 8, and 16 where its native float vector is 16 wide."""
    return (DEFAULT_LANES, WIDE_LANES) if backend.device.native_vector_width_float >= WIDE_LANES else (DEFAULT_LANES,)


def tuned(backend):
    """Whether ``backend``'s tile was measured (or fixed by FPIWARP_OPENCL_TILE)."""
    return _fixed() is not None or _path(backend).exists()


def tune(backend, candidates=CANDIDATES, wide=True):
    """Measure ``candidates`` on ``backend`` and keep the fastest (in memory
    and on disk); returns {"tile": (x, y), "lanes": n, "seconds": {"XxY": s}}.
    ``wide``: the best tile at 16 lanes too, where the device's vectors are
    16 wide ("XxYx16"); False measures 8 lanes only. A width fixed by
    FPIWARP_OPENCL_LANES is the one the tiles are measured at, and kept.
    Does nothing but report the tile on devices that do not tile."""
    import numpy as np  # noqa: PLC0415

    from ...maps.fpi import FPI  # noqa: PLC0415

    if backend.lanes == 1:
        return {"tile": None, "seconds": {}}
    fixed = bool(os.environ.get(ENV_LANES, "").strip())  # the width is fixed: only the tiles are measured
    base = lanes_for(backend) if fixed else DEFAULT_LANES
    h, w, c = TUNING_SHAPE
    image = np.random.default_rng(0).integers(0, 256, size=(h, w, c), dtype=np.uint8)
    f = FPI([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]],
            [[0.03 * w, 0.02 * h], [0.95 * w, -0.04 * h], [1.02 * w, 1.05 * h], [-0.05 * w, 0.93 * h]])
    block = np.ascontiguousarray(f.inverse.params(), dtype=np.float32)
    kind = backend.block_kind(block)
    saved = getattr(backend, "_tile", None), backend.lanes
    if not wide:
        backend.lanes = DEFAULT_LANES

    def measure(shapes):
        """{(tile, lanes): best seconds} of warps in each (tile, lanes), interleaved."""
        jobs = {}
        for tile, lanes in shapes:
            backend._tile, backend.lanes = tile, lanes
            if not usable(backend, tile):
                continue
            job = type(backend._jobs)().get(backend, image, (h, w), 1, "constant", np.zeros(c), False, kind, block)
            job.set_block(block)
            job.run(image)  # the warm-up: builds
            jobs[tile, lanes] = job
        times = {shape: float("inf") for shape in jobs}
        for _ in range(TUNING_ROUNDS):
            for shape, job in jobs.items():
                t0 = time.perf_counter()
                job.run(image)
                times[shape] = min(times[shape], time.perf_counter() - t0)
        return times

    try:
        with backend._lock:
            times = measure([(tile, base) for tile in candidates])
            if times and wide and not fixed and WIDE_LANES in candidate_lanes(backend):
                tile = min(times, key=times.get)[0]
                times = measure([(tile, DEFAULT_LANES), (tile, WIDE_LANES)]) | {
                    k: v for k, v in times.items() if k[0] != tile}
    finally:
        backend._tile, backend.lanes = saved
    if not times:
        return {"tile": tile_for(backend), "seconds": {}}
    best, lanes = min(times, key=times.get)
    backend._tile, backend.lanes = best, lanes
    backend._jobs.clear()  # jobs prepared with the old tile
    record = {"tile": list(best), "lanes": lanes,
              "seconds": {f"{x}x{y}" + ("" if n == DEFAULT_LANES else f"x{n}"): s for ((x, y), n), s in times.items()},
              "device": backend.device_label, "measured": time.strftime("%Y-%m-%dT%H:%M:%S")}
    try:
        path = _path(backend)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(record, indent=1), encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        pass
    return {"tile": best, "lanes": lanes, "seconds": record["seconds"]}
