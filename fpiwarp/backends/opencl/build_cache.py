"""Built OpenCL programs kept on disk, so a new process does not compile again.

A program's binary (``CL_PROGRAM_BINARIES``) is stored under the user's
cache directory (:func:`fpiwarp.backends.default.cache_dir`, folder
``opencl``), in a file named by a hash of everything the binary depends
on: the program's source (the generated preamble and the kernels, so a
changed kernel never loads an old binary), its build options, the
device's name, vendor, driver and OpenCL versions, the platform's name
and version, and pyopencl's version. Loading a binary is a few
milliseconds where even a cached source build costs PoCL a tenth of a
second per program, and drivers without a cache of their own (pyopencl
caches only where the driver does not) compile from scratch. A binary
the driver refuses is deleted and the program built from source.
``FPIWARP_OPENCL_BUILD_CACHE=0`` turns the cache off.

Writes are atomic (a temporary file renamed into place): two processes
building the same program both write the same bytes.
"""

import hashlib
import os

ENV_BUILD_CACHE = "FPIWARP_OPENCL_BUILD_CACHE"


def enabled():
    return os.environ.get(ENV_BUILD_CACHE, "1").strip().lower() not in ("0", "no", "false", "off")


def _folder():
    from ..default import cache_dir  # noqa: PLC0415

    return cache_dir() / "opencl"


def _device_key(backend):
    """What a binary of ``backend``'s device depends on, computed once per backend."""
    key = getattr(backend, "_binary_key", None)
    if key is None:
        import pyopencl  # noqa: PLC0415

        parts = [*_device_parts(backend), pyopencl.VERSION_TEXT, backend._source]
        key = hashlib.sha256("\0".join(str(p) for p in parts).encode()).digest()
        backend._binary_key = key
    return key


def _device_parts(backend):
    """The device, its driver and its platform (names and versions)."""
    device = backend.device
    platform = device.platform
    return [device.name, device.vendor, device.driver_version, device.version, platform.name, platform.version]


def device_path(backend, name):
    """A file of measurements called ``name`` for ``backend``'s device and
    driver, whatever the kernels' source (a measured choice that gives the
    same outputs in every case, like the tile, outlives a change of the
    kernels)."""
    h = hashlib.sha256("\0".join(str(p) for p in _device_parts(backend)).encode())
    return _folder() / f"{h.hexdigest()[:32]}.{name}.json"


def path(backend, options):
    """The cache file of the program built with ``options`` on ``backend``'s device."""
    h = hashlib.sha256(_device_key(backend))
    h.update("\0".join(options).encode())
    return _folder() / f"{h.hexdigest()[:32]}.bin"


def load(backend, options):
    """The stored binary, or None."""
    if not enabled():
        return None
    try:
        return path(backend, options).read_bytes()
    except OSError:
        return None


def store(backend, options, program):
    """Keep ``program``'s binary for the next process (best effort)."""
    if not enabled():
        return
    try:
        binaries = program.get_info(backend._cl.program_info.BINARIES)
    except Exception:  # noqa: BLE001 - a driver without binaries: nothing to keep
        return
    if len(binaries) != 1 or not binaries[0]:
        return
    target = path(backend, options)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(bytes(binaries[0]))
        os.replace(tmp, target)
    except OSError:
        pass


def forget(backend, options):
    """Delete a stored binary the driver refused."""
    try:
        path(backend, options).unlink()
    except OSError:
        pass
