"""Points through the FPI of tensors: map, inverse, Jacobian and distortion, differentiable."""

import torch

import fpiwarp

from . import checks, quads


def _prepare(points, src, dst):
    """(points (B, N, 2), src, dst (B, 4, 2), unbatched) on the points' device."""
    if not isinstance(points, torch.Tensor):
        points = torch.as_tensor(points, dtype=torch.float64)
    p = checks.points(points, "points", points.device)
    if p.ndim not in (2, 3):
        raise fpiwarp.ArgumentError(f"points must have shape (N, 2) or (B, N, 2), got {tuple(p.shape)}")
    s, d, single = checks.quads(src, dst, p.device)
    n = checks.batch(1 if p.ndim == 2 else p.shape[0], s.shape[0], "points", "src/dst")
    pts = (p if p.ndim == 3 else p[None]).expand(n, -1, -1)
    parts, ok = quads.build(s.expand(n, 4, 2), d.expand(n, 4, 2))
    quads.refuse(s.expand(n, 4, 2), d.expand(n, 4, 2), ok)
    return pts, parts, single and p.ndim == 2, p.dtype


def _complex(p):
    p = p.to(torch.float64)
    return torch.complex(p[..., 0], p[..., 1])


def _real(z, dtype, single):
    out = torch.stack([z.real, z.imag], dim=-1).to(dtype)
    return out[0] if single else out


def map_points(points: torch.Tensor, src: torch.Tensor, dst: torch.Tensor) -> torch.Tensor:
    """f(points) for the FPI from ``src`` to ``dst``: (N, 2) or (B, N, 2) (x, y) points.

    Evaluated in float64 (returned in the points' dtype), differentiable in
    the points and the corners; points at the pole come out inf or NaN.
    ``src``/``dst`` (4, 2) or (B, 4, 2) as in :func:`warp_image`.

    >>> import torch, fpiwarp.torch as ft
    >>> sq = torch.tensor([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    >>> ft.map_points(torch.tensor([[0.5, 0.5]]), sq, sq * torch.tensor([2.0, 1])).tolist()
    [[1.0, 0.5]]
    """
    pts, parts, single, dtype = _prepare(points, src, dst)
    return _real(quads.forward_map(parts, _complex(pts)), dtype, single)


def inverse_points(points: torch.Tensor, src: torch.Tensor, dst: torch.Tensor) -> torch.Tensor:
    """f⁻¹(points): the exact inverse (the FPI from ``dst`` to ``src``), as :func:`map_points`."""
    pts, parts, single, dtype = _prepare(points, src, dst)
    return _real(quads.inverse_map(parts, _complex(pts)), dtype, single)


def jacobian(points: torch.Tensor, src: torch.Tensor, dst: torch.Tensor) -> torch.Tensor:
    """The analytic Jacobian of f at ``points``: (N, 2, 2) or (B, N, 2, 2), J[..., i, j] = d f_i / d x_j.

    From the Wirtinger derivatives (f_x = f_z + f_zbar, f_y = i (f_z - f_zbar)), differentiable."""
    pts, parts, single, dtype = _prepare(points, src, dst)
    _, fz, fzb = quads.forward_wirtinger(parts, _complex(pts))
    fx, fy = fz + fzb, 1j * (fz - fzb)
    jac = torch.stack([torch.stack([fx.real, fy.real], -1), torch.stack([fx.imag, fy.imag], -1)], -2).to(dtype)
    return jac[0] if single else jac


def distortion(src: torch.Tensor, dst: torch.Tensor) -> torch.Tensor:
    """The constant conformal distortion K >= 1 of the FPI from ``src`` to ``dst``, differentiable.

    A scalar for (4, 2) quads, (B,) for (B, 4, 2); in the quads' dtype. A
    loss can penalise ``K - 1`` or bound it.

    >>> import torch, fpiwarp.torch as ft
    >>> sq = torch.tensor([[0.0, 0], [1, 0], [1, 1], [0, 1]], dtype=torch.float64)
    >>> round(float(ft.distortion(sq, sq * torch.tensor([2.0, 1], dtype=torch.float64))), 12)
    2.0
    """
    s = src if isinstance(src, torch.Tensor) else torch.as_tensor(src, dtype=torch.float64)
    s, d, single = checks.quads(s, dst, s.device)
    parts, ok = quads.build(s, d)
    quads.refuse(s, d, ok)
    k = parts.K.to(torch.promote_types(s.dtype, d.dtype))
    return k[0] if single else k
