"""The user-facing entry points: ``warp_image`` and ``map_points``.

They check their arguments once in :mod:`fpiwarp.validation`, against the
chosen backend's declared capabilities, then hand normalized arrays to the
backend, so every backend sees the same contract.
"""

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ._transform import Transform
from .arrays import array_info, dispatch
from .backends import backend_capabilities, get_backend
from .validation import check_map_size, check_point_count, check_points, check_transform, check_warp_arguments


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
        where the image lives, "numpy" for numpy arrays, "opencl" for
        pyopencl arrays, "gl" for textures, "warp" for Warp, DLPack and
        CUDA arrays (:class:`~fpiwarp.DeviceMismatchError` where the named
        backend cannot read the image in place).
    backend_options : dict, optional
        Options the backend declares (see
        :func:`fpiwarp.backend_capabilities`), e.g.
        ``{"hardware_filter": True}`` on "gl".
    antialias : bool, optional
        True filters each output pixel over its footprint in the source
        (the pixel square under the inverse map, from its analytic
        Jacobian): no aliasing where the warp shrinks, plain interpolation
        of ``order`` where it does not; at most 16×16 sub-samples per pixel
        (the numpy reference is fpiwarp/_antialias.py). Default False. Backends that
        antialias declare it (``capabilities.antialias``).

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
    if out is not None or channels != "last" or not _on_host(image):
        return dispatch.warp_image(image, transform, output_shape, order=order, mode=mode, cval=cval,
                                   backend=backend, backend_options=backend_options, antialias=antialias, out=out,
                                   channels=channels, host_warp=warp_image)
    backend = "numpy" if backend is None else backend
    caps = backend_capabilities(backend)
    args = check_warp_arguments(image, transform, output_shape, order, mode, cval, caps, backend, backend_options,
                                antialias)
    out = get_backend(backend).warp_image(
        args.image, transform, args.output_shape, order=args.order, mode=args.mode, cval=args.cval, **args.options
    )
    return out[:, :, 0] if args.squeeze else out
