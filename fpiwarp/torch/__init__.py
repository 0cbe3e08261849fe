"""Differentiable fpiwarp warps in PyTorch: gradients to the image and the corners.

The 4-point interpolant (FPI) is closed form end to end, so every value of
it is differentiable in the eight corner coordinates: the warped image,
mapped points, the Jacobian and the constant distortion K. Conventions
are fpiwarp's: (x, y) points, x = column, pixel centres at integers; the
same sampling rules, border modes and pole rule as
``fpiwarp.warp_image(..., backend="numpy")``, which the forward matches
(float64 within 1e-9 of the range, float32 within 1e-4).

* :func:`warp_image` -- warp (B, C, H, W) tensors by the FPI of ``src`` ->
  ``dst`` quads (or by any fpiwarp map, gradient to the image);
* :func:`sample` -- sample at given source positions with the same rules;
* :func:`map_points`, :func:`inverse_points`, :func:`jacobian`, :func:`distortion`;
* :class:`FPIWarp` -- an ``nn.Module`` with learnable target corners.

Backward passes are deterministic on CPU and CUDA: no float atomics
(:mod:`fpiwarp.torch.sampling` says how). Needs ``pip install fpiwarp[torch]``.
"""

try:
    import torch  # noqa: F401
except ImportError as exc:  # pragma: no cover - exercised only without torch
    from fpiwarp import MissingDependencyError

    raise MissingDependencyError(f"fpiwarp.torch needs PyTorch: pip install 'fpiwarp[torch]' ({exc})") from None

from .module import FPIWarp
from .points import distortion, inverse_points, jacobian, map_points
from .warp import sample, warp_image

__all__ = ["FPIWarp", "distortion", "inverse_points", "jacobian", "map_points", "sample", "warp_image"]
