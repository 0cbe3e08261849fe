"""Backends by name, each reporting whether it can run here and why not.

A backend module defines ``probe()``, which returns None when the backend
can run or a one-line reason when it cannot, and ``Backend``, a class that
follows :class:`fpiwarp.backends.protocol.Backend` (``map_points``,
``warp_image``, and ``warp_batch`` where it batches) working on arrays
already validated by :mod:`fpiwarp.validation`. What each backend accepts
is declared here, in its registry entry (:func:`backend_capabilities`),
so that calls are checked before a backend is even imported. Backends are
imported and probed lazily, once.
"""

import importlib
import threading
from dataclasses import dataclass

from ..errors import ArgumentError, BackendUnavailableError
from . import capabilities as _caps
from .capabilities import Capabilities


@dataclass(frozen=True)
class _Entry:
    module: str
    extra: str | None  # the pip extra that brings its Python packages
    system: str = ""  # what else it needs from the system
    capabilities: Capabilities = Capabilities()


REGISTRY = {
    "numpy": _Entry("fpiwarp.backends.numpy.backend", None, capabilities=_caps.NUMPY),
    "opencl": _Entry(
        "fpiwarp.backends.opencl.backend",
        "opencl",
        "an OpenCL driver (e.g. Debian's pocl-opencl-icd)",
        capabilities=_caps.OPENCL,
    ),
    "warp": _Entry("fpiwarp.backends.nvwarp.backend", "warp", capabilities=_caps.WARP),
    "gl": _Entry(
        "fpiwarp.backends.gl",
        "gl",
        "an EGL/OpenGL 3.3+ driver (e.g. Debian's libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri)",
        capabilities=_caps.GL,
    ),
}

_lock = threading.Lock()
_status = {}
_instances = {}


def _probe(name):
    entry = REGISTRY[name]
    try:
        module = importlib.import_module(entry.module)
    except ModuleNotFoundError as exc:
        if exc.name == entry.module:
            return None, "not implemented in this version of fpiwarp"
        return None, f"cannot import {exc.name}"
    except ImportError as exc:  # pragma: no cover - broken installs
        return None, f"import failed: {exc}"
    try:
        reason = module.probe()
    except Exception as exc:  # a driver failing to load must not crash the chooser
        reason = f"{type(exc).__name__}: {exc}"
    return module, reason


def backend_status() -> dict[str, str | None]:
    """Which backends can run here, and why the others cannot.

    Each backend is imported and probed once (a driver that fails to load
    is reported, not raised); later calls return the cached answer.

    Returns
    -------
    dict of str to (str or None)
        For every backend name ("numpy", "opencl", "warp", "gl"): None if
        it can run, else a one-line reason.

    Examples
    --------
    >>> import fpiwarp
    >>> status = fpiwarp.backend_status()
    >>> sorted(status)
    ['gl', 'numpy', 'opencl', 'warp']
    >>> status["numpy"] is None                 # the reference always runs
    True
    """
    with _lock:
        for name in REGISTRY:
            if name not in _status:
                _status[name] = _probe(name)
        return {name: _status[name][1] for name in REGISTRY}


def available_backends() -> list[str]:
    """Names of the backends that can run here.

    Returns
    -------
    list of str
        In the registry's order; always includes "numpy".

    Examples
    --------
    >>> import fpiwarp
    >>> "numpy" in fpiwarp.available_backends()
    True
    """
    return [name for name, reason in backend_status().items() if reason is None]


def check_backend_name(name):
    """``name`` if it names a backend, else ArgumentError listing them."""
    if not isinstance(name, str) or name not in REGISTRY:
        raise ArgumentError(f"unknown backend {name!r}; choose from {sorted(REGISTRY)}")
    return name


def backend_capabilities(name: str) -> Capabilities:
    """What backend ``name`` accepts, known without importing it.

    Parameters
    ----------
    name : str
        A backend name.

    Returns
    -------
    Capabilities
        dtypes, orders, modes, size limits, the ``backend_options`` it
        declares (:class:`~fpiwarp.backends.capabilities.BackendOption`),
        whether it batches and whether it is thread safe.

    Raises
    ------
    ArgumentError
        An unknown name.

    Examples
    --------
    >>> import fpiwarp
    >>> caps = fpiwarp.backend_capabilities("gl")
    >>> [opt.name for opt in caps.options]
    ['hardware_filter']
    >>> fpiwarp.backend_capabilities("numpy").batches
    True
    """
    return REGISTRY[check_backend_name(name)].capabilities


def get_backend(name):
    """The backend object for ``name``, created once per process.

    Parameters
    ----------
    name : str
        A backend name.

    Returns
    -------
    object
        Follows :class:`fpiwarp.backends.protocol.Backend` (``map_points``,
        ``warp_image``, and ``warp_batch`` where it batches), on arrays
        already validated; most callers want :func:`fpiwarp.warp_image`
        instead.

    Raises
    ------
    ArgumentError
        An unknown name.
    BackendUnavailableError
        It cannot run here; the message gives the reason and the extra to
        install.

    Examples
    --------
    >>> from fpiwarp.backends import get_backend
    >>> backend = get_backend("numpy")
    >>> backend is get_backend("numpy"), callable(backend.warp_image)
    (True, True)
    """
    check_backend_name(name)
    with _lock:
        if name not in _status:
            _status[name] = _probe(name)
        reason = _status[name][1]
    if reason is not None:
        entry = REGISTRY[name]
        hint = f"install it with: pip install 'fpiwarp[{entry.extra}]'" if entry.extra else ""
        if entry.system:
            hint += f" and provide {entry.system}"
        raise BackendUnavailableError(f"backend {name!r} is unavailable: {reason}; {hint}")
    with _lock:
        if name not in _instances:
            _instances[name] = _status[name][0].Backend()
        return _instances[name]
