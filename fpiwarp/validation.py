"""The one place where the arguments of fpiwarp's public calls are checked.

:func:`fpiwarp.warp_image`, :func:`fpiwarp.map_points`, the batch API, the
command line and the GL renderer all check their arguments here, so an
argument means the same everywhere and fails with the same one-line
message (an :class:`~fpiwarp.FpiwarpError`, which is also a ``ValueError``
or ``TypeError``). Backends then receive normalized values: a contiguous
(H, W, C) image, Python ints for ``order`` and ``output_shape``, a float64
``cval`` per channel.

Rules every entry point shares:

* ``order`` and ``output_shape`` take integers; integral floats (``1.0``,
  ``np.float64(3)``) are accepted as those integers everywhere, anything
  else (``1.5``, ``inf``, ``True``) is refused;
* ``cval`` is finite; for uint8/uint16 images it is clamped to the
  dtype's range, for float32 images it must lie within ±:data:`CVAL_LIMIT`,
  so that float32 kernels never overflow to inf or NaN interpolating it;
* sizes are checked up front against :data:`~fpiwarp.backends.capabilities.MAX_ELEMENTS`,
  the chosen backend's own limits and this machine's memory.
"""

import numbers
import os
from dataclasses import dataclass

import numpy as np

from .errors import ArgumentError, ArgumentTypeError, SizeLimitError
from .maps.transform import Transform
from .sampling.sampler import DTYPES, MODES, ORDERS

__all__ = [
    "CVAL_LIMIT",
    "WarpArguments",
    "check_antialias",
    "check_backend_options",
    "check_cval",
    "check_image",
    "check_map_size",
    "check_mode",
    "check_order",
    "check_output_shape",
    "check_point_count",
    "check_points",
    "check_sizes",
    "check_transform",
    "check_warp_arguments",
    "check_warp_options",
    "physical_memory",
    "refuse_masked",
    "short_repr",
]

#: Largest |cval|: cubic interpolation sums up to about 1.6 × cval in
#: float32 arithmetic on the device backends, which stays below float32's
#: maximum (3.4e38) from here on down.
CVAL_LIMIT = 1e38


def short_repr(value, limit=60):
    """A repr of a user's value short enough for a one-line message: an
    array is described by its type, shape and dtype, anything else cut to
    ``limit`` characters."""
    if hasattr(value, "shape") and hasattr(value, "dtype") and getattr(value, "ndim", 0) > 0:
        return f"{type(value).__name__} of shape {tuple(value.shape)} and dtype {value.dtype}"
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a broken __repr__ must not hide the real message
        text = f"<{type(value).__name__}>"
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def refuse_masked(value, name="image"):
    """Refuse a ``numpy.ma.MaskedArray``: fpiwarp warps the stored values of
    every pixel and has no notion of a mask, so the mask would be lost
    without a word. The message says how to choose what the masked pixels are."""
    if isinstance(value, np.ma.MaskedArray):
        raise ArgumentTypeError(
            f"{name} is a numpy.ma.MaskedArray, whose mask fpiwarp cannot honour: pass {name}.filled(value) "
            f"to give the masked pixels a value, or {name}.data to warp the stored values (and warp the mask, "
            f"{name}.mask, as its own image at order=0 if you need it)"
        )


def check_transform(transform, name="transform"):
    """Refuse anything that is not an fpiwarp map."""
    if not isinstance(transform, Transform):
        raise ArgumentTypeError(
            f"{name} must be an fpiwarp map (FPI, Mobius, RLinear, ...), got {type(transform).__name__}"
        )
    return transform


def _integer(value, name):
    """``value`` as a Python int when it is an integer or an integral
    float; ArgumentTypeError for other types, ArgumentError otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ArgumentTypeError(f"{name} must be an integer, got {type(value).__name__} {short_repr(value)}")
    if isinstance(value, numbers.Integral):
        return int(value)
    if not np.isfinite(value) or float(value) != int(value):
        raise ArgumentError(f"{name} must be an integer, got {short_repr(value)}")
    return int(value)


def check_order(order):
    """The interpolation order as a Python int among :data:`ORDERS`."""
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, numbers.Real):
        raise ArgumentError(f"order must be one of {ORDERS}, got {short_repr(order)}")
    if order not in ORDERS:
        raise ArgumentError(f"order must be one of {ORDERS}, got {short_repr(order)}")
    return int(order)


def check_mode(mode):
    """The border mode, one of :data:`MODES`."""
    if not isinstance(mode, str) or mode not in MODES:
        raise ArgumentError(f"mode must be one of {MODES}, got {short_repr(mode)}")
    return mode


def check_image(image, name="image"):
    """Validate an image; return it as (H, W, C) and whether it was 2-D."""
    refuse_masked(image, name)
    if not isinstance(image, np.ndarray):
        raise ArgumentTypeError(f"{name} must be a numpy array, got {type(image).__name__}")
    if image.dtype not in DTYPES:
        raise ArgumentTypeError(
            f"{name} dtype must be uint8, uint16 or float32, got {image.dtype} "
            "(convert with image.astype(np.float32))"
        )
    if image.ndim not in (2, 3) or (image.ndim == 3 and not 1 <= image.shape[2] <= 4):
        raise ArgumentError(f"{name} must be (H, W) or (H, W, C) with C in 1..4, got shape {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ArgumentError(f"{name} is empty: shape {image.shape}")
    if image.ndim == 2:
        return image[:, :, None], True
    return image, False


def check_output_shape(output_shape, image):
    """(rows, cols) as Python ints; the (H, W, C) ``image``'s own size when None."""
    if output_shape is None:
        if image is None:
            raise ArgumentError("output_shape must be given as (rows, cols)")
        return tuple(image.shape[:2])
    problem = f"output_shape must be (rows, cols) positive integers, got {short_repr(output_shape)}"
    try:
        oh, ow = output_shape
    except (TypeError, ValueError):
        raise ArgumentError(problem) from None
    try:
        oh, ow = _integer(oh, "output_shape"), _integer(ow, "output_shape")
    except (ArgumentError, ArgumentTypeError):
        raise ArgumentError(problem) from None
    if oh <= 0 or ow <= 0:
        raise ArgumentError(f"output_shape must be positive, got {short_repr(output_shape)}")
    return oh, ow


def check_cval(cval, channels, dtype=None):
    """cval as float64 (channels,): a finite number or one per channel.

    For an integer ``dtype`` it is clamped to the dtype's range (0..255,
    0..65535): a border of 1000 in a uint8 image is 255 wherever it shows
    alone, and interpolating it in float32 could not be exact. Otherwise
    (float32 images, or no dtype) each value must lie within
    ±:data:`CVAL_LIMIT`, where float32 interpolation cannot overflow.
    """
    if type(cval) in (int, float) and abs(cval) <= CVAL_LIMIT:  # the common case, without numpy's overhead
        value = float(cval)
        if dtype is not None and np.dtype(dtype).kind == "u":
            value = min(max(value, 0.0), float(np.iinfo(dtype).max))
        return np.full(channels, value)
    problem = f"cval must be a finite number or one per channel ({channels}), got {short_repr(cval)}"
    try:
        arr = np.asarray(cval, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentError(problem) from None
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != channels) or not np.all(np.isfinite(arr)):
        raise ArgumentError(problem)
    if dtype is not None and np.dtype(dtype).kind == "u":
        arr = np.clip(arr, 0.0, float(np.iinfo(dtype).max))
    elif np.any(np.abs(arr) > CVAL_LIMIT):
        raise ArgumentError(
            f"cval must lie within ±{CVAL_LIMIT:g} for float32 images (float32 interpolation would "
            f"overflow), got {short_repr(cval)}"
        )
    return np.broadcast_to(arr, (channels,)).copy()


def check_points(points, name="points"):
    """(..., 2) real points as float64."""
    pts = np.asarray(points)
    if pts.ndim == 0 or pts.shape[-1] != 2:
        raise ArgumentError(f"{name} must have shape (..., 2), got {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number) or np.iscomplexobj(pts):
        raise ArgumentTypeError(f"{name} must be real numbers, got dtype {pts.dtype}")
    return pts.astype(np.float64, copy=False)


#: Where Linux states the memory limit of this process's control group
#: (a container's limit, often below the machine's memory).
CGROUP_MEMORY_MAX = "/sys/fs/cgroup/memory.max"


#: Outputs smaller than this skip the memory check (any machine that runs
#: fpiwarp has that much): it reads a file, a cost on every small call.
MEMORY_CHECK_MIN_BYTES = 1 << 26


def physical_memory():
    """Bytes of memory this process may use: the machine's, or its
    container's limit when lower; None where the OS does not say."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, OSError, ValueError):
        total = None
    try:
        with open(CGROUP_MEMORY_MAX, encoding="ascii") as fh:
            text = fh.read().strip()
    except OSError:
        return total
    if not text.isdigit():  # "max": no limit
        return total
    return int(text) if total is None else min(total, int(text))


def _size(shape):
    return "x".join(str(int(n)) for n in shape)


def check_sizes(image_shape, output_shape, dtype, capabilities, backend):
    """Refuse an (H, W, C) image or a (rows, cols) output beyond a limit,
    before anything is allocated: the values per call, the backend's side
    limit and this machine's memory. One line names the size and the limit."""
    h, w, c = image_shape
    oh, ow = output_shape
    for what, rows, cols in (("image", h, w), ("output", oh, ow)):
        if rows * cols * c > capabilities.max_elements:
            raise SizeLimitError(
                f"{what} of {_size((rows, cols, c))} = {rows * cols * c} values is above the limit of "
                f"{capabilities.max_elements} values per call (rows x cols x channels)"
            )
        side = capabilities.max_side
        if side is not None and max(rows, cols) > side:
            raise SizeLimitError(
                f"{what} of {_size((rows, cols))} px is above the {backend} backend's limit of {side} px per side"
            )
    need = oh * ow * c * np.dtype(dtype).itemsize
    memory = physical_memory() if need >= MEMORY_CHECK_MIN_BYTES else None  # no file read per small call
    if memory is not None and need > memory:
        raise SizeLimitError(
            f"output of {_size((oh, ow, c))} {np.dtype(dtype)} needs {need / 2**30:.1f} GiB, "
            f"more than this machine's {memory / 2**30:.1f} GiB of memory"
        )


def check_map_size(transform, capabilities, backend):
    """Refuse a map with more stages than the backend's kernels evaluate."""
    limit = capabilities.max_stages
    if limit is None:
        return
    count = len(transform.stages())
    if count > limit:
        raise SizeLimitError(
            f"the map needs {count} stages, above the {backend} backend's limit of {limit} "
            "(warp in several calls, or use the numpy backend)"
        )


def check_point_count(points, capabilities, backend):
    """Refuse more points per call than the backend takes."""
    n = int(np.prod(points.shape[:-1]))
    if capabilities.max_points is not None and n > capabilities.max_points:
        raise SizeLimitError(
            f"{n} points is above the {backend} backend's limit of {capabilities.max_points} points per call"
        )


def check_backend_options(options, capabilities, backend, order, mode):
    """``options`` (a mapping or None) checked against the backend's
    declared :class:`~fpiwarp.backends.capabilities.BackendOption` list;
    returns a plain dict."""
    if options is None:
        return {}
    if not hasattr(options, "items"):
        raise ArgumentTypeError(f"backend_options must be a dict, got {type(options).__name__}")
    known = [opt.name for opt in capabilities.options]
    checked = {}
    for name, value in options.items():
        opt = capabilities.option(name)
        if opt is None:
            raise ArgumentError(
                f"backend_options: the {backend} backend has no option {name!r}; its options: {known or 'none'}"
            )
        if opt.kind is bool and isinstance(value, np.bool_):
            value = bool(value)
        if not isinstance(value, opt.kind) or (opt.kind is not bool and isinstance(value, bool)):
            raise ArgumentTypeError(
                f"backend_options[{name!r}] must be a {opt.kind.__name__}, "
                f"got {type(value).__name__} {short_repr(value)}"
            )
        if value:
            if opt.orders is not None and order not in opt.orders:
                raise ArgumentError(f"backend_options[{name!r}] supports order {opt.orders}, got {order}")
            if opt.modes is not None and mode not in opt.modes:
                raise ArgumentError(f"backend_options[{name!r}] supports modes {opt.modes}, got {short_repr(mode)}")
        checked[name] = value
    return checked


def check_antialias(antialias, capabilities, backend):
    """``antialias`` must be a bool (numpy's too) that the backend supports
    when true (its capabilities' ``antialias``); returns a Python bool."""
    if isinstance(antialias, np.bool_):
        antialias = bool(antialias)
    if not isinstance(antialias, bool):
        raise ArgumentTypeError(f"antialias must be True or False, got {type(antialias).__name__} {antialias!r}")
    if antialias and not capabilities.antialias:
        raise ArgumentError(f"the {backend} backend does not antialias yet; use antialias=False or another backend")
    return antialias


@dataclass(frozen=True)
class WarpArguments:
    """The arguments of one warp, checked and normalized: what a backend's
    ``warp_image`` receives (``image`` is contiguous (H, W, C))."""

    image: np.ndarray
    squeeze: bool
    output_shape: tuple
    order: int
    mode: str
    cval: np.ndarray
    options: dict


def check_warp_options(transform, order, mode):
    """The options of a warp that do not depend on the image: the map, the
    order and the mode. Returns (order, mode) normalized."""
    check_transform(transform)
    return check_order(order), check_mode(mode)


def check_backend_call(image_shape, output_shape, dtype, order, mode, capabilities, backend, backend_options,
                       antialias):
    """Check that ``backend`` (of ``capabilities``) warps ``dtype`` images
    at ``order`` in ``mode``, takes ``backend_options`` and ``antialias``,
    and holds images of these (H, W, C) sizes; return the options (with
    ``antialias=True`` when it is asked for, nothing when not)."""
    if dtype not in capabilities.dtypes or order not in capabilities.orders or mode not in capabilities.modes:
        raise ArgumentError(f"the {backend} backend cannot warp {dtype} images at order {order} in mode {mode!r}")
    options = check_backend_options(backend_options, capabilities, backend, order, mode)
    if check_antialias(antialias, capabilities, backend):
        options["antialias"] = True
    check_sizes(image_shape, output_shape, dtype, capabilities, backend)
    return options


def check_warp_arguments(image, transform, output_shape, order, mode, cval, capabilities, backend,
                         backend_options=None, antialias=False):
    """Check everything :func:`fpiwarp.warp_image` takes against the
    backend's ``capabilities``; return :class:`WarpArguments` (whose
    ``options`` hold ``antialias=True`` when it is asked for, nothing when
    not, so that a backend without antialiasing never sees it)."""
    order, mode = check_warp_options(transform, order, mode)
    img, squeeze = check_image(image)
    cval = check_cval(cval, img.shape[2], img.dtype)
    shape = check_output_shape(output_shape, img)
    options = check_backend_call(img.shape, shape, img.dtype, order, mode, capabilities, backend, backend_options,
                                 antialias)
    check_map_size(transform.inverse, capabilities, backend)  # the kernels evaluate the inverse
    return WarpArguments(np.ascontiguousarray(img), squeeze, shape, order, mode, cval, options)
