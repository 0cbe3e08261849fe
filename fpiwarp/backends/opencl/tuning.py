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
  versions, pyopencl's version and the kernels' source), else
  :data:`DEFAULT_TILE`.
* :func:`tune` measures :data:`CANDIDATES` on a 1024 x 1024 RGB uint8
  FPI warp (a warm-up call that builds each, then best of a few
  interleaved rounds) and stores the winner. The fast default's
  calibration calls it when it measures the opencl backend
  (:mod:`fpiwarp.backends.default`); the first time on a machine each
  candidate is one build (seconds on PoCL), later builds come from the
  caches. ``FPIWARP_OPENCL_TILE=X,Y`` fixes the tile instead.

Every tile gives the same output bit for bit (each pixel's code does not
depend on the tile; tests/backends/opencl/test_opencl_tiles.py), so the
choice changes speed only. Only CPU devices with vector lanes use tiles
(:mod:`.tiles`).
"""

import json
import os
import time

from . import build_cache

ENV_TILE = "FPIWARP_OPENCL_TILE"
#: The tile used until one is measured: (pixels per row, rows).
DEFAULT_TILE = (64, 8)
#: The tiles :func:`tune` measures (each a multiple of the 8 vector lanes wide).
CANDIDATES = ((64, 8), (32, 16), (16, 16), (32, 8))
#: The measurement: (rows, cols, channels) of uint8, and timed rounds.
TUNING_SHAPE, TUNING_ROUNDS = (1024, 1024, 3), 5


def _path(backend):
    return build_cache.path(backend, ("tile",)).with_suffix(".tile.json")


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


def tuned(backend):
    """Whether ``backend``'s tile was measured (or fixed by FPIWARP_OPENCL_TILE)."""
    return _fixed() is not None or _path(backend).exists()


def tune(backend, candidates=CANDIDATES):
    """Measure ``candidates`` on ``backend`` and keep the fastest (in memory
    and on disk); returns {"tile": (x, y), "seconds": {"XxY": s}}. Does
    nothing but report the tile on devices that do not tile."""
    import numpy as np  # noqa: PLC0415

    from ...maps.fpi import FPI  # noqa: PLC0415

    if backend.lanes == 1:
        return {"tile": None, "seconds": {}}
    h, w, c = TUNING_SHAPE
    image = np.random.default_rng(0).integers(0, 256, size=(h, w, c), dtype=np.uint8)
    f = FPI([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]],
            [[0.03 * w, 0.02 * h], [0.95 * w, -0.04 * h], [1.02 * w, 1.05 * h], [-0.05 * w, 0.93 * h]])
    block = np.ascontiguousarray(f.inverse.params(), dtype=np.float32)
    kind = backend.block_kind(block)
    saved = getattr(backend, "_tile", None)
    jobs = {}
    try:
        with backend._lock:
            for tile in (t for t in candidates if usable(backend, t)):
                backend._tile = tile
                job = type(backend._jobs)().get(backend, image, (h, w), 1, "constant", np.zeros(c), False, kind)
                job.set_block(block)
                job.run(image)  # the warm-up: builds
                jobs[tile] = job
            times = {tile: float("inf") for tile in jobs}
            for _ in range(TUNING_ROUNDS):
                for tile, job in jobs.items():
                    t0 = time.perf_counter()
                    job.run(image)
                    times[tile] = min(times[tile], time.perf_counter() - t0)
    finally:
        backend._tile = saved
    if not times:
        return {"tile": tile_for(backend), "seconds": {}}
    best = min(times, key=times.get)
    backend._tile = best
    backend._jobs.clear()  # jobs prepared with the old tile
    record = {"tile": list(best), "seconds": {f"{x}x{y}": s for (x, y), s in times.items()},
              "device": backend.device_label, "measured": time.strftime("%Y-%m-%dT%H:%M:%S")}
    try:
        path = _path(backend)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(record, indent=1), encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        pass
    return {"tile": best, "seconds": record["seconds"]}
