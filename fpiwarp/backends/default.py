"""The fast default: which backend ``backend=None`` runs on host arrays.

:func:`fpiwarp.warp_image` and :func:`fpiwarp.warp_batch` on numpy
arrays with ``backend=None`` (and the command line without
``--backend``) run the fastest backend that works on this machine. The
rule, in order:

1. ``FPIWARP_DEFAULT_BACKEND`` (or :func:`set_default_backend`) names a
   backend: that one, always (``numpy`` gives the float64 reference, the
   behaviour of fpiwarp before the fast default). ``auto`` (or unset):
   go on.
2. The candidates are the registry's entries with ``auto`` whose probe
   passes (:func:`fpiwarp.backend_status`), that accept the call
   (dtype, order, mode, antialiasing, options, sizes: their declared
   capabilities) and that can run in the calling thread (the gl backend's
   context belongs to one thread), and the numpy reference, always last
   resort.
3. They are ranked by a measurement made once per machine: a short warp
   of a 512 × 512 RGB uint8 image by an FPI on each candidate, after a
   warm-up call that builds its kernels, best of a few calls (about a
   second in all after the kernels are built; never on import, only at
   the first call that needs it). A candidate with per-device choices of
   its own measures them first (``Backend.tune()``: the opencl backend's
   work-group tile, :mod:`fpiwarp.backends.opencl.tuning`). The ranking is cached on disk in the
   user's cache directory (``FPIWARP_CACHE_DIR``, else
   ``$XDG_CACHE_HOME/fpiwarp``, else ``~/.cache/fpiwarp``), in a file
   named by a hash of what it depends on: CPU model, machine, OS, Python,
   the versions of fpiwarp, numpy and the backends' libraries, the
   device-selecting environment variables and the OpenCL drivers
   installed. The device each measured backend ran on is stored too and
   checked when the backend is first used: a different device measures
   again. ``FPIWARP_CALIBRATE=0`` skips the measurement and ranks by the
   registry's order (opencl, gl, then warp, numpy last); :func:`reset`
   forgets the ranking (in memory and on disk).
4. A candidate whose kernels are slow to build the first time (Warp on a
   CPU, 10-20 s, then cached by Warp) is measured only where no other
   kernel backend works, and a message on the ``fpiwarp`` logger says
   what is happening.
5. A backend that fails when it runs (an OpenCL driver that cannot build
   the kernels for this CPU, say) is marked failed with its reason
   (:func:`fpiwarp.backends.mark_failed`, shown by
   :func:`fpiwarp.backend_status`) and the call runs on the next
   candidate.

Results of the kernels are float32 evaluations of the same parameter
block as the float64 reference, within the parity the tests state
(docs/guides/choosing_a_backend.rst), not bit-identical across machines
or backends. ``backend="numpy"`` gives the reference.
"""

import hashlib
import importlib
import json
import logging
import os
import platform
import sys
import threading
import time
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path

from . import REGISTRY, backend_capabilities, backend_reason, get_backend

ENV_DEFAULT = "FPIWARP_DEFAULT_BACKEND"
ENV_CALIBRATE = "FPIWARP_CALIBRATE"
ENV_CACHE_DIR = "FPIWARP_CACHE_DIR"
#: The reference: the last resort, and what ``FPIWARP_DEFAULT_BACKEND=numpy`` asks for.
REFERENCE = "numpy"
#: The calibration workload: (rows, cols, channels) uint8, bilinear, constant border.
CALIBRATION_SHAPE = (512, 512, 3)
#: Timed calls per candidate after its warm-up (the best is kept).
CALIBRATION_REPEATS = 3
#: Candidates whose first kernel build on a CPU takes many seconds.
SLOW_FIRST_BUILD_ON_CPU = ("warp",)
#: Version of the cache file's layout (a change measures again).
CACHE_VERSION = 1
#: Libraries whose versions key the cache.
KEY_LIBRARIES = ("fpiwarp", "numpy", "pyopencl", "warp-lang", "moderngl", "pocl-binary-distribution")
#: Environment variables that choose devices (they key the cache).
DEVICE_VARIABLES = ("FPIWARP_OPENCL_DEVICE", "FPIWARP_WARP_DEVICE", "OCL_ICD_VENDORS", "OCL_ICD_FILENAMES",
                    "POCL_DEVICES", "CUDA_VISIBLE_DEVICES")

log = logging.getLogger("fpiwarp")
_lock = threading.RLock()
_state = {}  # "ranking": [names], "devices": {name: device}, "override": name or None
_checked_devices = set()  # backends whose device was compared with the measured one


def cache_dir() -> Path:
    """Where fpiwarp keeps what it measured (``FPIWARP_CACHE_DIR``, else the
    user's cache directory)."""
    given = os.environ.get(ENV_CACHE_DIR)
    if given:
        return Path(given)
    base = os.environ.get("XDG_CACHE_HOME")
    if base:
        return Path(base) / "fpiwarp"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "fpiwarp"
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        return Path(os.environ["LOCALAPPDATA"]) / "fpiwarp" / "Cache"
    return Path.home() / ".cache" / "fpiwarp"


def _cpu_model():
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _version(dist):
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def _opencl_drivers():
    """The installed OpenCL ICDs (names and sizes): a new driver measures again."""
    folder = Path(os.environ.get("OCL_ICD_VENDORS", "/etc/OpenCL/vendors"))
    try:
        return sorted((p.name, p.read_text(errors="replace").strip()) for p in folder.glob("*.icd"))
    except OSError:
        return []


def machine_key() -> dict:
    """What the measured ranking depends on, cheap to compute (no backend is imported)."""
    version = getattr(sys.modules.get("fpiwarp"), "__version__", None)  # the package's (set after its imports)
    return {
        "cache_version": CACHE_VERSION,
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "machine": platform.machine(),
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "fpiwarp": version,
        "libraries": {name: _version(name) for name in KEY_LIBRARIES},
        "environment": {name: os.environ.get(name) for name in DEVICE_VARIABLES},
        "opencl_drivers": _opencl_drivers(),
        "calibration": [*CALIBRATION_SHAPE, CALIBRATION_REPEATS],
    }


def cache_path(key=None) -> Path:
    """The file of this machine's measured ranking."""
    text = json.dumps(machine_key() if key is None else key, sort_keys=True)
    return cache_dir() / f"default-backend-{hashlib.sha256(text.encode()).hexdigest()[:20]}.json"


def device_of(name, backend=None) -> str:
    """A one-line description of the device backend ``name`` runs on."""
    backend = get_backend(name) if backend is None else backend
    for attr in ("device_label", "device"):
        value = getattr(backend, attr, None)
        if value is not None and not callable(value):
            return str(value)
    return repr(backend) if " object at 0x" not in repr(backend) else type(backend).__module__


def _on_cpu(backend):
    device = getattr(backend, "device", None)
    return getattr(device, "is_cpu", True) is not False


def _usable_here(name):
    """None where backend ``name`` may run in the calling thread, else why not
    (its module's optional ``usable_here()``)."""
    try:
        module = importlib.import_module(REGISTRY[name].module)
    except ImportError:
        return None  # its probe says why
    check = getattr(module, "usable_here", None)
    return check() if check is not None else None


def candidates() -> list[str]:
    """The registry's fast-default candidates that may run in this thread and
    pass their probe, in the registry's order."""
    return [name for name, entry in REGISTRY.items()
            if entry.auto and _usable_here(name) is None and backend_reason(name) is None]


def _calibration_case():
    import numpy as np  # noqa: PLC0415

    from ..maps.fpi import FPI  # noqa: PLC0415

    h, w, c = CALIBRATION_SHAPE
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, size=(h, w, c), dtype=np.uint8)
    f = FPI([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]],
            [[0.03 * w, 0.02 * h], [0.95 * w, -0.04 * h], [1.02 * w, 1.05 * h], [-0.05 * w, 0.93 * h]])
    return image, f


def _time_backend(name, image, transform):
    """Best seconds of one warp on backend ``name`` (after a warm-up), or the reason it failed."""
    import numpy as np  # noqa: PLC0415

    backend = get_backend(name)
    shape = image.shape[:2]
    cval = np.zeros(image.shape[2])
    try:
        backend.warp_image(image, transform, shape, order=1, mode="constant", cval=cval)
        best = float("inf")
        for _ in range(CALIBRATION_REPEATS):
            t0 = time.perf_counter()
            backend.warp_image(image, transform, shape, order=1, mode="constant", cval=cval)
            best = min(best, time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - any failure of a device disqualifies it, with the reason kept
        return None, f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
    return best, None


def calibrate() -> dict:
    """Measure the candidates now and store the ranking on disk; returns the
    record ({"ranking": [...], "seconds": {...}, "devices": {...},
    "skipped": {...}}). Called by the first call that needs the ranking."""
    from . import mark_failed  # noqa: PLC0415

    image, transform = _calibration_case()
    found = candidates()
    seconds, devices, skipped = {}, {}, {}
    slow = []
    for name in found:
        try:
            backend = get_backend(name)
        except Exception as exc:  # noqa: BLE001 - failed to start: not a candidate
            skipped[name] = str(exc)
            continue
        if name in SLOW_FIRST_BUILD_ON_CPU and _on_cpu(backend):
            slow.append(name)
            continue
        tune = getattr(backend, "tune", None)  # a backend's own per-device choices, measured once
        if tune is not None:
            try:
                tune()
            except Exception as exc:  # noqa: BLE001 - a device failing here is skipped below
                log.info("fpiwarp: tuning %s failed: %s", name, exc)
        secs, why = _time_backend(name, image, transform)
        if secs is None:
            mark_failed(name, why)
            skipped[name] = why
            continue
        seconds[name], devices[name] = secs, device_of(name, backend)
    for name in slow:
        if seconds:
            skipped[name] = "not measured: its first kernel build on a CPU takes many seconds and " + \
                            ", ".join(seconds) + " works here"
            continue
        log.warning("fpiwarp: building the %s backend's kernels for this CPU to choose the default backend "
                    "(the first time only, 10-20 s; FPIWARP_DEFAULT_BACKEND=numpy skips this)", name)
        secs, why = _time_backend(name, image, transform)
        if secs is None:
            mark_failed(name, why)
            skipped[name] = why
            continue
        seconds[name], devices[name] = secs, device_of(name)
    if seconds:  # the reference is never faster than a working kernel backend at 512² (measured once to say so)
        secs, _ = _time_backend(REFERENCE, image, transform)
        seconds[REFERENCE] = secs
    ranking = sorted(seconds, key=seconds.get)
    if REFERENCE not in ranking:
        ranking.append(REFERENCE)
    record = {"key": machine_key(), "ranking": ranking, "seconds": seconds, "devices": devices,
              "skipped": skipped, "measured": time.strftime("%Y-%m-%dT%H:%M:%S")}
    _store(record)
    return record


def _store(record):
    path = cache_path(record["key"])
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True), encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:  # a read-only home: measured again next process
        log.info("fpiwarp: cannot store the default backend's measurement in %s: %s", path, exc)


def _load():
    path = cache_path()
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or not isinstance(record.get("ranking"), list):
        return None
    return record


def _requested():
    """The backend named by set_default_backend or FPIWARP_DEFAULT_BACKEND, or None for "auto"."""
    override = _state.get("override")
    if override is not None:
        return override
    value = os.environ.get(ENV_DEFAULT, "").strip().lower()
    if value in ("", "auto"):
        return None
    if value not in REGISTRY:
        from ..errors import ArgumentError  # noqa: PLC0415

        raise ArgumentError(f"{ENV_DEFAULT}={value!r} names no backend; choose from auto, {', '.join(REGISTRY)}")
    return value


def ranking() -> list[str]:
    """The backends in the order the fast default tries them (measured once,
    cached on disk; see the module docstring)."""
    with _lock:
        if "ranking" not in _state:
            if os.environ.get(ENV_CALIBRATE, "1").strip().lower() in ("0", "no", "false", "off"):
                auto = [name for name, entry in REGISTRY.items() if entry.auto]
                order = sorted(auto, key=lambda n: n in SLOW_FIRST_BUILD_ON_CPU)
                _state["ranking"], _state["devices"] = [*order, REFERENCE], {}
            else:
                record = _load() or calibrate()
                _state["ranking"], _state["devices"] = list(record["ranking"]), dict(record.get("devices", {}))
        return list(_state["ranking"])


def _device_changed(name):
    """Whether backend ``name`` now runs on another device than the one measured."""
    if name in _checked_devices or name not in _state.get("devices", {}):
        return False
    _checked_devices.add(name)
    return device_of(name) != _state["devices"][name]


def _accepts(name, dtype, order, mode, antialias, options, stages, side):
    caps = backend_capabilities(name)
    if dtype is not None and dtype not in caps.dtypes:  # numpy dtypes compare equal to their names and aliases
        return False
    if order not in caps.orders or mode not in caps.modes or antialias and not caps.antialias:
        return False
    if stages is not None and caps.max_stages is not None and stages() > caps.max_stages:
        return False
    if side is not None and caps.max_side is not None and side > caps.max_side:
        return False
    return all(caps.option(key) is not None for key in options or ())


def stage_count(transform):
    """A callable giving the number of stages the kernels evaluate for
    ``transform`` (its inverse's), computed on first use; None on error
    (the checks of the chosen backend then say what is wrong)."""
    memo = []

    def count():
        if not memo:
            try:
                memo.append(len(transform.inverse.stages()))
            except Exception:  # noqa: BLE001 - not a valid map: the reference's checks raise the right error
                memo.append(0)
        return memo[0]

    return count


def host_backend(dtype=None, order=1, mode="constant", antialias=False, options=None, stages=None,
                 side=None) -> str:
    """The backend ``backend=None`` runs for a host-array call of these
    options: the override if one is set, else the first of :func:`ranking`
    that accepts the call (``stages``: a callable giving the map's stage
    count, see :func:`stage_count`; ``side``: the largest side of the image
    or output), is not failed and may run in this thread; the reference
    where none does."""
    requested = _requested()
    if requested is not None:
        return requested
    if options:  # options belong to one backend: a default that depends on the machine would change their meaning
        if not isinstance(options, Mapping):
            return REFERENCE  # the reference's checks refuse it
        from ..errors import ArgumentError  # noqa: PLC0415

        owners = sorted({name for name in REGISTRY for key in options
                         if backend_capabilities(name).option(key) is not None})
        named = f" (declared by {', '.join(repr(n) for n in owners)})" if owners else ""
        raise ArgumentError(f"backend_options {sorted(options)} are options of one backend{named}: name it with "
                            "backend=")
    try:
        order = int(order)
    except (TypeError, ValueError, OverflowError):
        return REFERENCE  # the reference's checks give the error
    for name in ranking():
        if name == REFERENCE:
            break
        if name not in REGISTRY or not _accepts(name, dtype, order, mode, antialias, options, stages, side):
            continue
        if _usable_here(name) is not None or backend_reason(name) is not None:  # the thread first: probing gl
            continue  # makes this thread its owner
        if _device_changed(name):  # measured on another device: measure again, once
            reset()
            return host_backend(dtype, order, mode, antialias, options, stages, side)
        return name
    return REFERENCE


def _stored_is_stale():
    try:
        cache_path().unlink()
    except OSError:
        pass


def set_default_backend(name: str | None) -> None:
    """Make ``backend=None`` on host arrays run backend ``name`` in this
    process (``"numpy"``: the float64 reference), or, with None, the fast
    default again (``FPIWARP_DEFAULT_BACKEND`` does the same per environment)."""
    from . import check_backend_name  # noqa: PLC0415

    if name is not None:
        check_backend_name(name)
    _state["override"] = name


def default_backend() -> str:
    """The backend ``fpiwarp.warp_image(image, f)`` runs on a uint8 numpy
    image here (measures the candidates on first use; see
    docs/guides/choosing_a_backend.rst)."""
    return host_backend("uint8")


def reset(disk: bool = True) -> None:
    """Forget the measured ranking: in this process, and (``disk``) the file
    in the cache; the next default call measures again."""
    with _lock:
        _state.pop("ranking", None)
        _state.pop("devices", None)
        _checked_devices.clear()
        if disk:
            _stored_is_stale()
