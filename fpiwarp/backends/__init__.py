"""Backends by name: the registry, which holds everything fpiwarp knows about them.

A backend is one folder under ``fpiwarp/backends/`` and one
:class:`BackendEntry` in :data:`REGISTRY`. Its module defines
``probe()``, which returns None when the backend can run or a one-line
reason when it cannot, and ``Backend``, a class that follows
:class:`fpiwarp.backends.protocol.Backend` (``map_points``,
``warp_image``, and ``warp_batch`` where it batches) working on arrays
already validated by :mod:`fpiwarp.validation`. Everything the rest of
the package asks about a backend is declared in its entry, so that calls
are checked and routed before a backend is even imported:

* what it accepts (dtypes, orders, modes, limits, options, whether it
  batches, antialiases, is thread safe): ``capabilities``
  (:func:`backend_capabilities`);
* which array kinds (:data:`fpiwarp.arrays.KINDS`) it reads in place,
  and the module of its in-place calls (``reads``, ``arrays``): the
  dispatch of :mod:`fpiwarp.arrays` asks the entry instead of branching
  on names (:func:`readers_of`, :func:`array_calls`);
* for which kinds it is the default when the caller names no backend
  (``default_for``), and whether it is a candidate of the fast default on
  host arrays (``auto``, see :mod:`fpiwarp.backends.default`);
* whether its batches read maps as parameter blocks only (``block_maps``:
  each map's inverse is then computed once by the caller).

Backends are imported and probed lazily, once. See
docs/guides/adding_a_backend.rst for what a new backend provides.
"""

import importlib
import threading
from dataclasses import dataclass

from ..errors import ArgumentError, BackendUnavailableError
from . import capabilities as _caps
from .capabilities import Capabilities


@dataclass(frozen=True)
class BackendEntry:
    """Everything fpiwarp knows about one backend without importing it.

    Attributes
    ----------
    module : str
        The module defining ``probe()`` and ``Backend``.
    extra : str or None
        The pip extra that brings its Python packages.
    system : str
        What else it needs from the system (a driver), for error messages.
    capabilities : Capabilities
        What a call may ask of it (checked by :mod:`fpiwarp.validation`).
    reads : tuple of str
        Array kinds (keys of :data:`fpiwarp.arrays.KINDS`) it reads and
        writes in place, besides host memory (numpy arrays, and Warp or
        DLPack arrays on the CPU through a numpy view, which every backend
        takes).
    arrays : str or None
        The module of its calls on the kinds in ``reads``: functions
        ``warp_image(image, info, transform, call)``,
        ``map_points(transform, points, info, out)``,
        ``warp_batch(images, info, transforms, call)`` and
        ``map_points_batch(transforms, points, info, out)``, each where the
        backend takes that call (a missing one: the kind is refused with
        :class:`~fpiwarp.DeviceMismatchError`); ``writes_host_out()`` (True:
        a numpy ``out=`` is written in place by its ``warp_image``).
    default_for : tuple of str
        Array kinds it runs when the caller names no backend.
    auto : bool
        A candidate of the fast default for host arrays (``backend=None``,
        see :mod:`fpiwarp.backends.default`).
    block_maps : bool
        Its ``warp_batch`` and ``map_points_batch`` read each map only as
        its parameter block (``.inverse.stages()`` / ``.stages()``), so the
        caller computes each map's stages once.
    """

    module: str
    extra: str | None
    system: str = ""
    capabilities: Capabilities = Capabilities()
    reads: tuple = ()
    arrays: str | None = None
    default_for: tuple = ()
    auto: bool = False
    block_maps: bool = False


REGISTRY = {
    "numpy": BackendEntry("fpiwarp.backends.numpy.backend", None, capabilities=_caps.NUMPY,
                          default_for=("numpy", "host")),
    "opencl": BackendEntry(
        "fpiwarp.backends.opencl.backend",
        "opencl",
        "an OpenCL driver (e.g. Debian's pocl-opencl-icd)",
        capabilities=_caps.OPENCL,
        reads=("opencl",),
        arrays="fpiwarp.backends.opencl.arrays",
        default_for=("opencl",),
        auto=True,
        block_maps=True,
    ),
    "warp": BackendEntry(
        "fpiwarp.backends.nvwarp.backend",
        "warp",
        capabilities=_caps.WARP,
        reads=("warp", "dlpack", "cuda_array_interface"),
        arrays="fpiwarp.backends.nvwarp.arrays",
        default_for=("warp", "dlpack", "cuda_array_interface"),
        auto=True,
        block_maps=True,
    ),
    "gl": BackendEntry(
        "fpiwarp.backends.gl",
        "gl",
        "an EGL/OpenGL 3.3+ driver (e.g. Debian's libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri)",
        capabilities=_caps.GL,
        reads=("texture",),
        arrays="fpiwarp.backends.gl.arrays",
        default_for=("texture",),
        auto=True,
        block_maps=True,
    ),
}

_lock = threading.Lock()
_status = {}
_instances = {}
_failed = {}  # backend -> why it failed after its probe passed (see mark_failed)


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
        return {name: _failed.get(name, _status[name][1]) for name in REGISTRY}


def backend_reason(name: str) -> str | None:
    """:func:`backend_status` of one backend (None: it can run here), probing
    only that one (the first time)."""
    check_backend_name(name)
    with _lock:
        if name not in _status:
            _status[name] = _probe(name)
        return _failed.get(name, _status[name][1])


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
    reason = backend_reason(name)
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


def backend_entry(name: str) -> BackendEntry:
    """The registry's :class:`BackendEntry` of ``name`` (ArgumentError for an unknown name)."""
    return REGISTRY[check_backend_name(name)]


def readers_of(kind: str) -> list[str]:
    """Names of the backends that read arrays of ``kind`` in place."""
    return [name for name, entry in REGISTRY.items() if kind in entry.reads]


def default_for_kind(kind: str) -> str:
    """The backend that runs arrays of ``kind`` when the caller names none
    (for host kinds, the reference the fast default falls back to)."""
    return next(name for name, entry in REGISTRY.items() if kind in entry.default_for)


def array_calls(name: str):
    """The module of backend ``name``'s in-place calls (its entry's
    ``arrays``), imported on first use; None where it reads no array kind
    in place."""
    entry = backend_entry(name)
    return importlib.import_module(entry.arrays) if entry.arrays else None


def mark_failed(name: str, reason: str) -> None:
    """Record that backend ``name``, available by its probe, failed to run
    here (a device that cannot build its kernels, say): from now on
    :func:`backend_status` reports ``reason`` and :func:`get_backend`
    refuses it with :class:`~fpiwarp.BackendUnavailableError`, for the
    rest of the process. The fast default skips it."""
    check_backend_name(name)
    with _lock:
        _failed[name] = reason
        _instances.pop(name, None)
