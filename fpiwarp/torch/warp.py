"""warp_image and sample: fpiwarp's warp of torch tensors, differentiable."""

from collections.abc import Sequence

import torch

import fpiwarp

from . import checks, quads
from .positions import fold, fpi_positions, inside, precision, transform_positions
from .sampling import GatherSample, grid_sample_path

#: Samplers :func:`sample` can be told to use ("auto": grid_sample on CPU for
#: orders 0 and 1, else the gathering sampler; CUDA sorts, CPU scatters).
SAMPLERS = ("auto", "grid_sample", "gather-scatter", "gather-sort")


def sample(
    image: torch.Tensor,
    positions: torch.Tensor,
    *,
    order: int = 1,
    mode: str = "constant",
    cval: float | Sequence[float] = 0.0,
    sampler: str = "auto",
) -> torch.Tensor:
    """Sample ``image`` at source ``positions`` with fpiwarp's rules, differentiably.

    Parameters
    ----------
    image : torch.Tensor, float32 or float64, (B, C, H, W) or (C, H, W)
    positions : torch.Tensor, float, (B, rows, cols, 2) or (rows, cols, 2)
        Source (x, y) of each output pixel, x = column, pixel centres at
        integers (what :func:`fpiwarp.source_positions` returns). A batch
        of 1 is shared by every image.
    order, mode, cval
        As :func:`warp_image`.
    sampler : {'auto', 'grid_sample', 'gather-scatter', 'gather-sort'}
        Which implementation (all give the same values; for tests and
        benchmarks). 'grid_sample' takes orders 0 and 1 only.

    Returns
    -------
    torch.Tensor (B, C, rows, cols), or (C, rows, cols) for an unbatched image and positions.
    """
    img, single = checks.image(image)
    pos = checks.points(positions, "positions", img.device)
    if pos.ndim not in (3, 4):
        raise fpiwarp.ArgumentError(f"positions must have shape (rows, cols, 2) or (B, rows, cols, 2), "
                                    f"got {tuple(pos.shape)}")
    unbatched = single and pos.ndim == 3
    pos = pos if pos.ndim == 4 else pos[None]
    n = checks.batch(img.shape[0], pos.shape[0], "image", "positions")
    x, y = pos[..., 0].to(torch.float64), pos[..., 1].to(torch.float64)
    out = _sample(img.expand(n, -1, -1, -1), x, y, checks.order(order), checks.mode(mode),
                  checks.cval(cval, img.shape[1], img.dtype, img.device), sampler)
    return out[0] if unbatched else out


def warp_image(
    image: torch.Tensor,
    src: object,
    dst: object = None,
    output_shape: tuple[int, int] | None = None,
    *,
    order: int = 1,
    mode: str = "constant",
    cval: float | Sequence[float] = 0.0,
    antialias: bool = False,
) -> torch.Tensor:
    """Warp ``image`` by the FPI from ``src`` to ``dst``, differentiably in all three.

    The same warp as ``fpiwarp.warp_image(image, fpiwarp.FPI(src, dst))``
    (backward warping: each output pixel samples the source at f⁻¹ of its
    centre), on the image's device, with gradients to the image and to
    every corner coordinate. ``warp_image(image, transform)`` warps by any
    fpiwarp map (gradient to the image only).

    Parameters
    ----------
    image : torch.Tensor, float32 or float64, (B, C, H, W) or (C, H, W)
        On any device.
    src, dst : torch.Tensor, (B, 4, 2) or (4, 2)
        Source and target quads, (x, y) points, x = column, pixel centres
        at integers, of the same orientation; float tensors on the image's
        device (array-likes are taken as float64 constants). A batch of 1
        is shared. Or ``src`` an fpiwarp map (:class:`fpiwarp.Compound`,
        :class:`fpiwarp.LocalDeformation`, ...) and no ``dst``; then the
        third positional argument is ``output_shape``.
    output_shape : (rows, cols), optional
        Default the image's.
    order : {0, 1, 3}
        Nearest (gradient to the image only), bilinear (default) or Keys' cubic.
    mode : {'constant', 'edge', 'reflect', 'wrap'}
        What taps outside the image read, as :func:`fpiwarp.warp_image`.
    cval : float or sequence of float
        The value outside in 'constant' mode, and where the source position
        is not finite or lies more than 2**24 px away (the pole rule), in every mode.
    antialias : bool
        Must be False: no differentiable footprint filter here
        (:class:`fpiwarp.ArgumentError` for True).

    Returns
    -------
    torch.Tensor
        (B, C, rows, cols) of the image's dtype on its device; (C, rows,
        cols) when neither the image nor the quads have a batch axis.

    Raises
    ------
    ArgumentTypeError
        ``image`` not a float32/float64 tensor; quads of an integer dtype.
    ArgumentError
        Bad shapes, batch sizes, order, mode, cval or output_shape; antialias=True.
    DeviceMismatchError
        Quads on another device than the image.
    DegenerateQuadError
        Quads fpiwarp.FPI refuses (message prefixed with the batch item).

    Notes
    -----
    The backward pass is deterministic (two runs give the same bits, on
    CPU and CUDA): no float atomics (see :mod:`fpiwarp.torch.sampling`).
    The corner checks synchronise with the device once per call.

    Examples
    --------
    >>> import torch, fpiwarp.torch as ft
    >>> img = torch.arange(12.0).reshape(1, 3, 4)
    >>> src = torch.tensor([[0.0, 0], [3, 0], [3, 2], [0, 2]])
    >>> ft.warp_image(img, src, src + torch.tensor([1.0, 0]), order=0, cval=-1)[0].tolist()
    [[-1.0, 0.0, 1.0, 2.0], [-1.0, 4.0, 5.0, 6.0], [-1.0, 8.0, 9.0, 10.0]]
    """
    img, single = checks.image(image)
    checks.antialias(antialias)
    order, mode = checks.order(order), checks.mode(mode)
    cval_t = checks.cval(cval, img.shape[1], img.dtype, img.device)
    if isinstance(src, fpiwarp.Transform):
        if dst is not None:
            if output_shape is not None:
                raise fpiwarp.ArgumentError("warp_image(image, transform) takes no dst; pass output_shape once")
            output_shape = dst
        shape = checks.output_shape(output_shape, tuple(img.shape[2:]))
        x, y = transform_positions(src, shape, img.device)
        out = _sample(img, x, y, order, mode, cval_t, "auto")
        return out[0] if single else out
    if dst is None:
        raise fpiwarp.ArgumentError("warp_image needs src and dst quads, or an fpiwarp map as src")
    s, d, unbatched = checks.quads(src, dst, img.device)
    n = checks.batch(img.shape[0], s.shape[0], "image", "src/dst")
    shape = checks.output_shape(output_shape, tuple(img.shape[2:]))
    parts, ok = quads.build(s, d)
    quads.refuse(s, d, ok)
    x, y = fpi_positions(parts, shape, img.device, precision(img.dtype, order, mode))
    out = _sample(img.expand(n, -1, -1, -1), x, y, order, mode, cval_t, "auto")
    return out[0] if single and unbatched else out


def _sample(img, x, y, order, mode, cval, sampler):
    """img (B, C, H, W); x, y float64 (B or 1, rows, cols) raw positions."""
    if sampler not in SAMPLERS:
        raise fpiwarp.ArgumentError(f"sampler must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
    h, w = img.shape[2:]
    ok = inside(x, y)
    if ok is not None:
        x = torch.where(ok, x, 0.0)
        y = torch.where(ok, y, 0.0)
    if sampler == "auto":
        sampler = "grid_sample" if img.device.type == "cpu" and order != 3 else "gather"
    if sampler == "grid_sample":
        if order == 3:
            raise fpiwarp.ArgumentError("sampler 'grid_sample' takes orders 0 and 1 only")
        if mode in ("constant", "edge") and order == 1:  # grid_sample's zero/border padding is that rule already
            xf, yf = x, y
        else:
            xf, yf = fold(x, w, mode, order), fold(y, h, mode, order)
        out = grid_sample_path(img, xf, yf, order, mode, cval)
    else:
        xf, yf = fold(x, w, mode, order), fold(y, h, mode, order)
        method = {"gather-scatter": "scatter", "gather-sort": "sort"}.get(
            sampler, "sort" if img.device.type == "cuda" else "scatter")
        if method == "scatter" and img.device.type != "cpu":
            raise fpiwarp.ArgumentError("sampler 'gather-scatter' runs on CPU only (elsewhere index_add_ adds "
                                        "floats atomically, in no fixed order)")
        out = GatherSample.apply(img, xf, yf, order, mode, cval, method)
    return out if ok is None else torch.where(ok[:, None], out, cval.view(1, -1, 1, 1))
