"""A description of the machine a benchmark ran on, for its reports.

CPU model and core count, OS and Python, the load average (benchmarks on
a shared machine are noisy: the load says how noisy), the version of
every library the benchmark touches, and for each fpiwarp backend either
the device it runs on (its ``repr``, which names the OpenCL device, Warp
device or GL renderer) or why it is unavailable.
"""

import importlib
import os
import platform

LIBRARIES = ("fpiwarp", "numpy", "scipy", "cv2", "skimage", "matplotlib", "pyopencl", "moderngl", "warp")


def cpu_model():
    """The CPU's model name (Linux /proc/cpuinfo, else platform's guess)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


#: CPU vector extensions named in benchmark tables, widest first.
ISA_FLAGS = ("avx512f", "avx2", "avx", "sse4_2", "neon", "asimd")


def cpu_isa():
    """The widest vector ISA the CPU reports ("avx512f", "avx2", ...; Linux
    /proc/cpuinfo flags), else the machine name. Figures from an AVX2 and an
    AVX-512 machine must never be mixed in one table."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith(("flags", "features")):
                    flags = set(line.split(":", 1)[1].split())
                    found = [f for f in ISA_FLAGS if f in flags]
                    return found[0] if found else "none of " + ", ".join(ISA_FLAGS)
    except OSError:
        pass
    return platform.machine()


def opencl_device():
    """The opencl backend's device string ("Portable Computing Language:
    pthread-skylake-avx512-..." on PoCL), or why it is unavailable."""
    import fpiwarp
    from fpiwarp.backends import get_backend

    reason = fpiwarp.backend_status()["opencl"]
    if reason is not None:
        return f"unavailable: {reason}"
    backend = get_backend("opencl")
    return f"{backend.device_label} ({backend.device.platform.version.strip()})"


def facts_line():
    """One line for the head of every benchmark table: CPU model, ISA, PoCL/OpenCL device."""
    return f"CPU: {cpu_model()} ({os.cpu_count()} cores, {cpu_isa()}); OpenCL device: {opencl_device()}"


def library_versions():
    """{import name: version or None when not installed}."""
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
    """{backend: device description or 'unavailable: reason'}."""
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
        out[name] = _device_of(name, backend)
    return out


def _device_of(name, backend):
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


def describe():
    """The machine description as a JSON-ready dict."""
    try:
        load = [round(v, 2) for v in os.getloadavg()]
    except OSError:
        load = None
    return {
        "cpu": cpu_model(),
        "isa": cpu_isa(),
        "opencl_device": opencl_device(),
        "cores": os.cpu_count(),
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "load_average_1_5_15min": load,
        "libraries": library_versions(),
        "backends": backend_devices(),
    }


def markdown(info):
    """A short Markdown block of :func:`describe`'s output."""
    libs = ", ".join(f"{k} {v}" for k, v in info["libraries"].items() if v is not None)
    lines = [
        f"Machine: {info['cpu']} ({info.get('isa', '?')}), {info['cores']} cores, {info['os']}, "
        f"Python {info['python']}"
        + (f", load average {info['load_average_1_5_15min'][0]} at start" if info.get("load_average_1_5_15min") else "")
        + ".",
        "",
        f"Libraries: {libs}.",
        "",
        "Backends: " + "; ".join(f"{k}: {v}" for k, v in info["backends"].items()) + ".",
        "",
        f"OpenCL device: {info.get('opencl_device', '?')}.",
    ]
    return "\n".join(lines)
