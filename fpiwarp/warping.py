"""The user-facing entry points: ``warp_image``, ``map_points`` and ``Warper``.

They check their arguments once in :mod:`fpiwarp.validation`, against the
chosen backend's declared capabilities, then hand normalized arrays to the
backend, so every backend sees the same contract.
"""

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .arrays import array_info, dispatch, labels
from .backends import backend_capabilities, backend_reason, get_backend
from .backends.default import REFERENCE, host_backend, stage_count
from .backends.protocol import bind
from .errors import ArgumentError, BackendUnavailableError, SizeLimitError
from .maps.transform import Transform
from .validation import (
    check_antialias,
    check_backend_options,
    check_map_size,
    check_output_shape,
    check_point_count,
    check_points,
    check_sizes,
    check_transform,
    check_warp_arguments,
    check_warp_options,
    refuse_masked,
)

__all__ = ["Warper", "map_points", "warp_image"]


# --- The user-facing entry points: ``warp_image`` and ``map_points``.
def _on_host(array) -> bool:
    """Whether ``array`` takes the numpy path (numpy arrays, lists, ...)."""
    return isinstance(array, np.ndarray) or array_info(array).kind == "host"


def map_points(transform: Transform, points: ArrayLike, backend: str | None = None, *, out: object = None) -> object:
    """Map points through ``transform`` on a backend, one point per vertex.

    The same as ``transform(points)``, computed by the chosen backend: the
    float64 host reference (``"numpy"``) or a device kernel (float32
    evaluation of the same parameter block).

    Parameters
    ----------
    transform : Transform
        Any fpiwarp map (:class:`~fpiwarp.FPI`, :class:`~fpiwarp.Compound`, ...).
    points : array_like, shape (..., 2)
        ``(x, y)`` points; in image coordinates x = column, y = row, pixel
        centers at integers. Any leading shape; converted to float64.
        Device arrays (see :mod:`fpiwarp.arrays`) are mapped where they
        are: float64 Warp/DLPack/CUDA arrays on "warp", pyopencl arrays of
        the device's point dtype on "opencl".
    backend : str, optional
        A name from :func:`fpiwarp.backend_status`; default None: from
        where the points live ("numpy" for numpy arrays and lists).
    out : array, optional
        An array of the result's shape, dtype and kind to write into
        (returned); it must not share memory with ``points``.

    Returns
    -------
    ndarray, float64, shape (..., 2)
        The mapped points. Points sent to the pole come out non-finite.
        For device points, an array of their library on their device.

    Raises
    ------
    ArgumentError
        ``points`` not of shape (..., 2), or an unknown backend name.
    ArgumentTypeError
        ``transform`` is not an fpiwarp map.
    SizeLimitError
        More points, or a map of more stages, than the backend takes.
    BackendUnavailableError
        The backend cannot run here (the message names what to install).

    See Also
    --------
    warp_image : warp an image by the same map.

    Examples
    --------
    >>> import fpiwarp
    >>> f = fpiwarp.FPI([[0, 0], [3, 0], [3, 2], [0, 2]], [[0, 0], [6, 0], [6, 4], [0, 4]])
    >>> fpiwarp.map_points(f, [[1.5, 1.0], [3, 2]]).round(9).tolist()
    [[3.0, 2.0], [6.0, 4.0]]
    """
    check_transform(transform)
    if out is not None or not _on_host(points):
        return dispatch.map_points(transform, points, backend, out, map_points)
    backend = "numpy" if backend is None else backend
    pts = check_points(points)
    caps = backend_capabilities(backend)
    check_point_count(pts, caps, backend)
    check_map_size(transform, caps, backend)
    return get_backend(backend).map_points(transform, pts)


def warp_image(
    image: np.ndarray,
    transform: Transform,
    output_shape: tuple[int, int] | None = None,
    *,
    order: int = 1,
    mode: str = "constant",
    cval: float | Sequence[float] = 0,
    backend: str | None = None,
    backend_options: Mapping[str, object] | None = None,
    antialias: bool = False,
    out: object = None,
    channels: str = "last",
) -> object:
    """Warp ``image`` by ``transform``, which maps source to output coordinates.

    Each output pixel samples the source at ``transform.inverse`` of its
    position (backward warping; exact for the FPI). Pixel centers are at
    integer coordinates, x = column, y = row: pixel ``image[r, c]`` is the
    point ``(c, r)``.

    Parameters
    ----------
    image : ndarray, uint8, uint16 or float32, shape (H, W) or (H, W, C)
        The source, with C from 1 to 4 channels. Or an array on a device,
        warped there without a host copy (:mod:`fpiwarp.arrays`): a Warp,
        DLPack (PyTorch, CuPy, JAX) or CUDA array, a
        ``pyopencl.array.Array`` or a ``moderngl.Texture``.
    transform : Transform
        An fpiwarp map (FPI, Mobius, RLinear, Compound, ...) from source to
        output coordinates.
    output_shape : tuple of int (rows, cols), optional
        Default the input's.
    order : {0, 1, 3}, optional
        0 (nearest), 1 (bilinear, the default) or 3 (Keys' cubic
        convolution); integral floats such as 1.0 are taken as those
        integers.
    mode : {'constant', 'edge', 'reflect', 'wrap'}, optional
        What taps outside the source read: ``cval``, the nearest edge pixel,
        the mirror image without repeating the edge (``numpy.pad``'s
        'reflect') or the image tiled.
    cval : float or sequence of float, optional
        Value (or one per channel) outside the image in 'constant' mode,
        and wherever the source position is not finite or lies more than
        2**24 px away (at or next to the pole's image), in every mode;
        finite; clamped to the range of uint8/uint16 images, within ±1e38
        for float32 images.
    backend : str, optional
        A name from :func:`fpiwarp.backend_status`; default None: from
        where the image lives. For numpy arrays the fastest backend that
        works on this machine (measured once and cached on disk, see
        :func:`fpiwarp.default_backend` and
        docs/guides/choosing_a_backend.rst): results within the stated
        float32 parity of the float64 reference, which ``backend="numpy"``
        gives exactly. "opencl" for pyopencl arrays, "gl" for textures,
        "warp" for Warp, DLPack and CUDA arrays
        (:class:`~fpiwarp.DeviceMismatchError` where the named backend
        cannot read the image in place).
    backend_options : dict, optional
        Options the backend declares (see
        :func:`fpiwarp.backend_capabilities`), e.g.
        ``{"hardware_filter": True}`` on "gl".
    antialias : bool, optional
        True filters each output pixel over its footprint in the source
        (the pixel square under the inverse map, from its analytic
        Jacobian), read from a pyramid of the source (halved levels; the
        footprint's shorter edge picks the level, its longer edge is
        supersampled there): no aliasing where the warp shrinks, plain
        interpolation of ``order`` where it does not, bit for bit; a
        bounded number of samples per pixel (the numpy reference is
        ``fpiwarp/sampling/antialias.py`` and ``pyramid.py``). Backends
        that antialias declare it (``capabilities.antialias``).
        The pyramid is built once per call, and reused across calls by
        one rule on every backend
        (``fpiwarp.sampling.pyramid.SourcePyramids``): the pyramids
        of the last 2 numpy sources are kept with a copy of their pixels
        and serve a call only while the source's shape, dtype and pixels
        equal that copy, so an array changed in place (read-only or not)
        is never served stale levels, and another array of equal pixels
        reuses them; sources over 128 MiB are not kept. Device-array
        sources get their pyramid built per call.
        Default False: this call's plain result is the reference
        semantics (the exact point samples ``cv2.remap`` and
        ``skimage.transform.warp`` give, what registration and pipelines
        that compare outputs rely on), and order 0 is how label maps are
        warped, which must never be averaged. ``fpiwarp warp`` and
        ``fpiwarp batch`` antialias by default at orders 1 and 3 (see
        :doc:`/guides/antialiasing`).

    out : array, optional
        An array of the result's shape, dtype, kind and device to write
        into (returned): numpy, Warp/DLPack (not JAX), pyopencl or a
        texture; it must not share memory with ``image``.
    channels : {'last', 'first'}, optional
        The layout of 3-D images and results: (H, W, C) (default) or
        (C, H, W) as PyTorch keeps them.

    Returns
    -------
    ndarray
        Shape ``output_shape`` (plus the channel axis if the input has one),
        of the input's dtype; integer outputs are rounded. For a device
        image, an array of its kind on its device (``out`` if given).

    Raises
    ------
    ArgumentError
        A bad image, shape, order, mode, cval, option, ``out`` or ``channels`` (a ValueError).
    DeviceMismatchError
        The image (or ``out``) lives where the backend cannot read it.
    ArgumentTypeError
        ``transform`` is not an fpiwarp map (a TypeError).
    SizeLimitError
        Sizes beyond a limit (2**31 - 1 values per call, the backend's
        pixels per side, this machine's memory), before any work.
    BackendUnavailableError
        The backend cannot run here.

    See Also
    --------
    source_positions : the source position of every output pixel, for
        another resampler.
    warp_images, warp_batch : many images by one map.

    Examples
    --------
    >>> import numpy as np
    >>> import fpiwarp
    >>> img = np.arange(12, dtype=np.uint8).reshape(3, 4)
    >>> shift = fpiwarp.RLinear(1, 0, 1)            # x -> x + 1: content moves right
    >>> fpiwarp.warp_image(img, shift, order=0, cval=99).tolist()
    [[99, 0, 1, 2], [99, 4, 5, 6], [99, 8, 9, 10]]
    >>> f = fpiwarp.FPI([[0, 0], [3, 0], [3, 2], [0, 2]], [[0, 0], [3, 0], [3.3, 2], [0, 2]])
    >>> fpiwarp.warp_image(img, f, output_shape=(4, 5)).shape
    (4, 5)
    """
    refuse_masked(image)
    if labels.label_dtype(image) is not None:  # bool and integer labels: order 0 through a carrier
        return labels.warp_labels(warp_image, image, transform, output_shape, batch=False, order=order, mode=mode,
                                  cval=cval, backend=backend, backend_options=backend_options, antialias=antialias,
                                  out=out, channels=channels)
    if out is not None or channels != "last" or not _on_host(image):
        call = dispatch.WarpCall(output_shape, order, mode, cval, backend_options, antialias, out, channels)
        return dispatch.warp_image(image, transform, call, backend, host_warp=warp_image)
    if backend is None:  # the fast default (fpiwarp.backends.default), falling back past a backend that fails
        return on_default_backend(lambda name: warp_image(image, transform, output_shape, order=order, mode=mode,
                                                          cval=cval, backend=name, backend_options=backend_options,
                                                          antialias=antialias),
                                  getattr(image, "dtype", None), order, mode, antialias, backend_options,
                                  stage_count(transform), _largest_side(image, output_shape))
    caps = backend_capabilities(backend)
    args = check_warp_arguments(image, transform, output_shape, order, mode, cval, caps, backend, backend_options,
                                antialias)
    out = get_backend(backend).warp_image(
        args.image, transform, args.output_shape, order=args.order, mode=args.mode, cval=args.cval, **args.options
    )
    return out[:, :, 0] if args.squeeze else out


def _largest_side(image, output_shape):
    """The largest side of the image (H, W[, C]) or of ``output_shape``, or None."""
    sides = list(np.shape(image)[:2]) if isinstance(image, np.ndarray) else []
    if isinstance(output_shape, (tuple, list)):
        sides += [v for v in output_shape if isinstance(v, int)]
    return max(sides) if sides else None


def on_default_backend(run, dtype=None, order=1, mode="constant", antialias=False, options=None, stages=None,
                       side=None):
    """``run(name)`` on the fast default's backend for a host call of these
    options (:func:`fpiwarp.backends.default.host_backend`); where that
    backend turns out not to work here (its kernels do not build: it is then
    marked failed, see :func:`fpiwarp.backend_status`), on the next one; a
    call beyond that backend's limits (a map of more stages than its
    kernels evaluate, found in a batch's later maps) on the reference."""
    tried = set()
    while True:
        name = host_backend(dtype, order, mode, antialias, options, stages, side)
        try:
            return run(name)
        except BackendUnavailableError:
            if name in tried or backend_reason(name) is None:
                raise  # not a backend failing here: the caller's error
            tried.add(name)
        except SizeLimitError:
            if name == REFERENCE:
                raise
            return run(REFERENCE)


# --- One map and its warp options, ready to warp many images (:class:`Warper`).


class Warper:
    """One map and its warp options, ready to warp many images.

    Options are checked once here, with the errors of
    :func:`fpiwarp.warp_image`. ``backend=None`` (the default) is the fast
    default of :func:`fpiwarp.warp_image` for numpy images, chosen here
    (``backend`` names it). Calling the warper on an image returns what
    ``warp_image(image, transform, output_shape, ...)`` returns; the map is
    bound to the backend once (see ``fpiwarp.batch``). Picklable (for
    Dask workers): the bound map is rebuilt where the warper is unpickled.
    Device arrays (:mod:`fpiwarp.arrays`) of the warper's backend are
    warped in place by :func:`fpiwarp.warp_image` (the map is not bound).

    The fast path for many images: the checked arguments are kept per
    image shape and dtype (numpy arrays), so a further image of a known
    shape and dtype goes straight to the bound map, which keeps a prepared
    job (kernel, buffers, launch shape) per kind of call on the device
    backends. The map's parameter block is taken when it is bound (the
    first call): change a map by making a new warper (assigning any of its
    attributes, ``transform`` included, drops what was prepared).
    """

    #: Shapes and dtypes whose checked arguments are kept.
    MAX_PREPARED = 8

    def __init__(self, transform: Transform, output_shape: tuple[int, int] | None = None, *, order: int = 1,
                 mode: str = "constant", cval: float | Sequence[float] = 0, backend: str | None = None,
                 backend_options: Mapping[str, object] | None = None, antialias: bool = False) -> None:
        self._auto = backend is None  # the fast default: chosen here, for host images
        if backend is None:
            backend = host_backend(None, order, mode, antialias, backend_options, stage_count(transform),
                                   max(output_shape) if isinstance(output_shape, (tuple, list)) else None)
        caps = backend_capabilities(backend)
        order, mode = check_warp_options(transform, order, mode)
        if np.ndim(cval) > 1:
            raise ArgumentError(f"cval must be a number or one per channel, got {cval!r}")
        self.options = check_backend_options(backend_options, caps, backend, order, mode)
        self.antialias = check_antialias(antialias, caps, backend)
        if output_shape is not None:  # refuse a huge output before the first image is read
            check_sizes((1, 1, 1), check_output_shape(output_shape, None), np.uint8, caps, backend)
        get_backend(backend)  # fail now if unavailable
        self.transform, self.output_shape = transform, output_shape
        self.order, self.mode, self.cval, self.backend = order, mode, cval, backend
        self.capabilities = caps

    def __setattr__(self, name, value):  # a changed option or map drops what was prepared for the old one
        super().__setattr__(name, value)
        if not name.startswith("_"):
            super().__setattr__("_bound", None)
            super().__setattr__("_prepared", {})

    def __getstate__(self):  # no bound map: it may hold device state
        state = self.__dict__.copy()
        state["_bound"] = None
        state["_prepared"] = {}
        return state

    @property
    def bound(self) -> object:
        """The map bound to the backend (built on first use)."""
        if self._bound is None:
            self._bound = bind(get_backend(self.backend), self.transform)
        return self._bound

    def __call__(self, image: object) -> object:
        refuse_masked(image)
        if labels.label_dtype(image) is not None or not isinstance(image, np.ndarray) and \
                array_info(image).kind != "host":
            # a label image (fpiwarp.arrays.labels) or a device array (fpiwarp.arrays): warp_image as it is, on
            # this warper's backend (the array's with the fast default)
            return warp_image(image, self.transform, self.output_shape, order=self.order, mode=self.mode,
                              cval=self.cval, backend=None if self._auto else self.backend,
                              backend_options=self.options, antialias=self.antialias)
        if not self._auto:
            return self._warp(image)
        try:
            return self._warp(image)
        except BackendUnavailableError:
            if backend_reason(self.backend) is None:
                raise
            # the default's backend does not work here (now marked failed): the next one, for good
            replacement = Warper(self.transform, self.output_shape, order=self.order, mode=self.mode,
                                 cval=self.cval, backend=None, backend_options=self.options, antialias=self.antialias)
            self.__dict__.update(replacement.__dict__)
            return self(image)

    def _warp(self, image):
        key = None
        if type(image) is np.ndarray and image.flags.c_contiguous:
            key = (image.shape, image.dtype)
            args = self._prepared.get(key)
            if args is not None:  # checked before: a known shape and dtype
                out = self.bound.warp_image(image[:, :, None] if args.squeeze else image, args.output_shape,
                                            order=args.order, mode=args.mode, cval=args.cval, **args.options)
                return out[:, :, 0] if args.squeeze else out
        args = check_warp_arguments(image, self.transform, self.output_shape, self.order, self.mode, self.cval,
                                    self.capabilities, self.backend, self.options, self.antialias)
        out = self.bound.warp_image(args.image, args.output_shape, order=args.order, mode=args.mode, cval=args.cval,
                                    **args.options)
        if key is not None and len(self._prepared) < self.MAX_PREPARED:
            self._prepared[key] = dataclasses.replace(args, image=None)
        return out[:, :, 0] if args.squeeze else out
