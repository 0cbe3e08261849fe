"""Where each output pixel samples the source, as differentiable float64 tensors.

For the FPI the backward map is f⁻¹ = m_Z⁻¹ ∘ A⁻¹ ∘ m_W. Written in
homogeneous form it costs a dozen passes over the pixels: with u = p - q_W
(p an output pixel centre), m_W(p) = N / D, N = a_W u, D = 1 - s_W u, and

    A⁻¹(N / D) = V / R,   R = |D|²,   V = μ1 N conj(D) + μ2 conj(N) D + μ3 R,

where V and R are quadratics in (u_x, u_y) with no u_x u_y term
(V = c0 + c_x u_x + c_y u_y + γ |u|², R likewise), i.e. a column function plus
a row function; so are E = a_Z R + s_Z V. The source position is then

    f⁻¹(p) = m_Z⁻¹(V / R) = q_Z + V / (a_Z R + s_Z V) = q_Z + V conj(E) / |E|²,

one complex division per pixel. The pole (E = 0) comes out infinite, and
is never a NaN in the gradient: its pixels get an infinite position from a
branch that carries no derivative.

The border modes are then applied to the positions themselves
(:func:`fold`), exactly, in float64: ``wrap`` and ``reflect`` fold them
into the image (Keys' and the bilinear kernel are symmetric, so sampling
at a reflected position is sampling the reflected taps), ``edge`` and
``constant`` clamp what lies so far out that every tap is clamped or
outside. Samplers then see positions within a few pixels of the image,
which float32 resolves to ~3e-5 px.
"""

import math

import torch

import fpiwarp

#: Source positions beyond this many pixels are outside (cval): fpiwarp's pole rule.
COORD_LIMIT = float(2**24)


def _split(c):
    return c.real[:, None, None], c.imag[:, None, None]


def fpi_positions(parts, output_shape, device, dtype=torch.float64):
    """(x, y), (B, rows, cols) of ``dtype``: f⁻¹ of every output pixel centre.

    The per-item coefficients (and the row and column parts) are float64;
    only the per-pixel passes run in ``dtype``."""
    rows, cols = output_shape
    m1, m2, m3 = parts.inverse_linear()
    a, s = parts.a_w, parts.s_w
    alpha, beta = m1 * a, m2 * a.conj()
    gamma = -m1 * a * s.conj() - m2 * a.conj() * s + m3 * (s.abs() ** 2)
    # V = c0 + cx ux + cy uy + gamma |u|², R = 1 - 2 Re(s u) + |s|² |u|²
    cx = alpha + beta - 2 * m3 * s.real
    cy = 1j * (alpha - beta) + 2 * m3 * s.imag
    ux = torch.arange(cols, dtype=torch.float64, device=device)[None, None, :] - parts.q_w.real[:, None, None]
    uy = torch.arange(rows, dtype=torch.float64, device=device)[None, :, None] - parts.q_w.imag[:, None, None]
    ux2, uy2 = ux * ux, uy * uy

    def col_row(c0, cx_, cy_, g):
        """(column part (B,1,cols), row part (B,rows,1)) of c0 + cx ux + cy uy + g |u|², complex coefficients."""
        c0, cx_, cy_, g = (v[:, None, None] for v in (c0, cx_, cy_, g))
        return c0 + cx_ * ux + g * ux2, cy_ * uy + g * uy2

    v_col, v_row = col_row(m3, cx, cy, gamma)
    ones = torch.ones_like(s)
    r_col, r_row = col_row(ones, -2 * s.real * ones, 2 * s.imag * ones, (s.abs() ** 2) * ones)
    az, sz = parts.a_z[:, None, None], parts.s_z[:, None, None]
    e_col, e_row = az * r_col + sz * v_col, az * r_row + sz * v_row
    v_r = v_col.real.to(dtype) + v_row.real.to(dtype)
    v_i = v_col.imag.to(dtype) + v_row.imag.to(dtype)
    e_r = e_col.real.to(dtype) + e_row.real.to(dtype)
    e_i = e_col.imag.to(dtype) + e_row.imag.to(dtype)
    den = torch.addcmul(e_r * e_r, e_i, e_i)
    pole = None if bool(den.detach().amin() > 0) else den == 0  # one reduction instead of a mask, as a rule
    inv = 1 / (den if pole is None else torch.where(pole, 1.0, den))
    qx, qy = (v.to(dtype) for v in _split(parts.q_z))
    x = torch.addcmul(qx, torch.addcmul(v_r * e_r, v_i, e_i), inv)
    y = torch.addcmul(qy, torch.addcmul(v_i * e_r, v_r, -e_i), inv)
    if pole is not None:
        x = torch.where(pole, math.inf, x)
        y = torch.where(pole, math.inf, y)
    return x, y


def transform_positions(transform, output_shape, device):
    """(x, y), float64 (1, rows, cols), of any fpiwarp map, computed where the image lives.

    CUDA: ``fpiwarp.map_points`` of ``transform.inverse`` on a CUDA tensor
    of pixel centres, evaluated in place by fpiwarp's Warp backend (its
    float32 parameter block); CPU: :func:`fpiwarp.source_positions`
    (float64 numpy reference). No gradient (the map's parameters are not tensors).
    """
    rows, cols = output_shape
    if device.type == "cuda":
        ys, xs = torch.meshgrid(torch.arange(rows, dtype=torch.float64, device=device),
                                torch.arange(cols, dtype=torch.float64, device=device), indexing="ij")
        grid = torch.stack([xs, ys], dim=-1)
        pos = fpiwarp.map_points(transform.inverse, grid)
        pos = torch.as_tensor(pos, device=device).to(torch.float64)
    else:
        pos = torch.from_numpy(fpiwarp.source_positions(transform, (rows, cols))).to(device)
    return pos[None, ..., 0], pos[None, ..., 1]


def inside(x, y):
    """Pixels whose source position is finite and within COORD_LIMIT (False for NaN); None when all are.

    Two reductions decide the common case without a mask (NaN fails the comparison)."""
    lo_x, hi_x = torch.aminmax(x.detach())
    lo_y, hi_y = torch.aminmax(y.detach())
    if bool(torch.stack([-lo_x, hi_x, -lo_y, hi_y]).amax() <= COORD_LIMIT):
        return None
    return (x.abs() <= COORD_LIMIT) & (y.abs() <= COORD_LIMIT)


def precision(image_dtype, order, mode):
    """The dtype positions are computed in: float32 images get float32 positions where float32 is
    exact enough (orders 1 and 3 in 'constant' and 'edge' mode: ~3e-5 px, the resolution of a
    float32 sampling grid), else float64 (rounding to the nearest pixel and folding
    far positions by 'reflect'/'wrap' must be exact)."""
    if image_dtype == torch.float32 and order != 0 and mode in ("constant", "edge"):
        return torch.float32
    return torch.float64


def fold(coord, n, mode, order):
    """Positions along an axis of ``n`` pixels folded by ``mode`` (see the module docstring).

    Order 0 rounds first (floor(x + 0.5), fpiwarp's nearest pixel) and folds
    the integer, as the reference folds tap indices."""
    if order == 0:
        coord = torch.floor(coord.detach() + 0.5)
    if mode == "constant":
        return coord.clamp(-4.0, n + 3.0)
    if mode == "edge":
        return coord.clamp(-2.0, n + 1.0)
    if mode == "reflect" and n == 1:
        return torch.zeros_like(coord)
    if mode == "wrap":
        return torch.remainder(coord, float(n))
    period = 2.0 * (n - 1)
    m = torch.remainder(coord, period)
    return torch.where(m > n - 1, period - m, m)
