"""FPIWarp: a torch.nn.Module whose learnable parameters are the four target corners."""

from collections.abc import Sequence

import torch

from .points import distortion
from .warp import warp_image


class FPIWarp(torch.nn.Module):
    """The FPI from fixed corners ``src`` to learnable corners ``dst``, as a layer.

    ``dst`` starts equal to ``src`` (the identity warp) and is a
    ``torch.nn.Parameter``; ``forward(image)`` warps by the current map,
    with gradients to ``dst`` (and the image). For registration: minimise
    an image loss plus a penalty on ``distortion()``.

    Parameters
    ----------
    src : tensor-like (4, 2) or (B, 4, 2)
        The source corners, (x, y) pixel points. (B, 4, 2) learns one map per image of a batch of B.
    output_shape : (rows, cols), optional
        Default the input image's.
    order, mode, cval
        As :func:`fpiwarp.torch.warp_image`.
    dtype : torch.dtype, optional
        Of the parameter; default float64 (the corners' precision matters more than their memory).

    Examples
    --------
    >>> import torch, fpiwarp.torch as ft
    >>> layer = ft.FPIWarp([[0, 0], [7, 0], [7, 5], [0, 5]])
    >>> img = torch.rand(2, 3, 6, 8, dtype=torch.float64)
    >>> bool(torch.allclose(layer(img), img)), round(float(layer.distortion().detach()), 9)
    (True, 1.0)
    """

    def __init__(self, src: object, output_shape: tuple[int, int] | None = None, *, order: int = 1,
                 mode: str = "constant", cval: float | Sequence[float] = 0.0, dtype: torch.dtype = torch.float64):
        super().__init__()
        src = torch.as_tensor(src, dtype=dtype).detach().clone()
        self.register_buffer("src", src)
        self.dst = torch.nn.Parameter(src.clone())
        self.output_shape, self.order, self.mode, self.cval = output_shape, order, mode, cval

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        """``image`` (B, C, H, W) or (C, H, W) warped by the FPI from ``src`` to the current ``dst``."""
        return warp_image(image, self.src, self.dst, self.output_shape, order=self.order, mode=self.mode,
                          cval=self.cval)

    def distortion(self) -> torch.Tensor:
        """K of the current map (differentiable in ``dst``)."""
        return distortion(self.src, self.dst)

    def extra_repr(self) -> str:
        return f"src={self.src.tolist()}, order={self.order}, mode={self.mode!r}"
