"""The user-facing entry points: ``warp_image`` and ``map_points``.

They check their arguments once in :mod:`fpiwarp.validation`, against the
chosen backend's declared capabilities, then hand normalized arrays to the
backend, so every backend sees the same contract.
"""

from .backends import backend_capabilities, get_backend
from .validation import check_map_size, check_point_count, check_points, check_transform, check_warp_arguments


def map_points(transform, points, backend="numpy"):
    """Map (..., 2) points through ``transform`` on a backend (per vertex).

    Returns float64 (..., 2). Points sent to the pole come out non-finite.
    """
    check_transform(transform)
    pts = check_points(points)
    caps = backend_capabilities(backend)
    check_point_count(pts, caps, backend)
    check_map_size(transform, caps, backend)
    return get_backend(backend).map_points(transform, pts)


def warp_image(image, transform, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy",
               backend_options=None, antialias=False):
    """Warp ``image`` by ``transform``, which maps source to output coordinates.

    Each output pixel samples the source at ``transform.inverse`` of its
    position (backward warping; exact for the FPI). Pixel centers are at
    integer coordinates, x = column, y = row.

    Parameters
    ----------
    image : ndarray, uint8, uint16 or float32, (H, W) or (H, W, C), C in 1..4
    transform : an fpiwarp map (FPI, Mobius, RLinear, Compound, ...)
    output_shape : (rows, cols), default the input's
    order : 0 (nearest), 1 (bilinear) or 3 (cubic convolution); integral
        floats such as 1.0 are taken as those integers
    mode : 'constant', 'edge', 'reflect' or 'wrap'
    cval : value (or one per channel) outside the image in 'constant' mode,
        and wherever the source position is not finite (near the pole);
        finite; clamped to the range of uint8/uint16 images, within ±1e38
        for float32 images
    backend : name from :func:`fpiwarp.backends.backend_status`
    backend_options : dict of options the backend declares (see
        :func:`fpiwarp.backends.backend_capabilities`), e.g.
        ``{"hardware_filter": True}`` on "gl"
    antialias : bool, default False. True filters each output pixel over
        its footprint in the source (the pixel square under the inverse
        map, from its analytic Jacobian): no aliasing where the warp
        shrinks, plain interpolation of ``order`` where it does not; at
        most 16×16 sub-samples per pixel (see :mod:`fpiwarp._antialias`).
        Backends that antialias declare it (``capabilities.antialias``).

    Returns an array of the input's dtype and channel layout. Sizes beyond
    a limit (2**31 - 1 values per call, the backend's pixels per side, this
    machine's memory) raise :class:`~fpiwarp.SizeLimitError` before any work.
    """
    caps = backend_capabilities(backend)
    args = check_warp_arguments(image, transform, output_shape, order, mode, cval, caps, backend, backend_options,
                                antialias)
    out = get_backend(backend).warp_image(
        args.image, transform, args.output_shape, order=args.order, mode=args.mode, cval=args.cval, **args.options
    )
    return out[:, :, 0] if args.squeeze else out
