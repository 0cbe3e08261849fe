"""The 4-point interpolant in PyTorch: parameters from the corners, differentiably.

The same closed form as :class:`fpiwarp.FPI`, written once for a batch of
quad pairs in complex128 torch arithmetic, so gradients flow from every
value of the map (its parts, its distortion K, mapped points) back to the
eight corner coordinates of ``src`` and ``dst``:

* the Möbius map m_Z (m_W) sending ``src`` (``dst``) to a parallelogram,
  from the quadratic ``C2 s² - C1 s + C0 = 0`` in the quad's centred,
  radius-scaled coordinates (fpiwarp's ``parallelogram_mobius``), taking
  the root of smaller ``|s|`` whose parallelogram keeps the orientation;
* the R-linear map A between the two parallelograms (eq. 3-4);
* clockwise quads (in (x, y)) solved mirrored and mirrored back.

One difference from the host code, kept on purpose: a quad that is a
parallelogram to rounding gets the small root ``2 C0 / (C1 ± √…)``, not an
exact ``s = 0``. The two agree to ~1e-14 of the quad's size, and the root
keeps its derivative there, so a map started at the identity (``dst =
src``, a rectangle) still has the gradient of its perspective terms.

Refusals are those of :class:`fpiwarp.FPI`: the checks run on the tensors'
device (no host copy of the corners, one synchronisation for the verdict);
for a refused item the host builds ``fpiwarp.FPI`` of that item only, to
raise its exact error, prefixed with the item's index.
"""

from typing import NamedTuple

import torch

import fpiwarp

#: Relative tolerance below which points coincide or are collinear (fpiwarp's quad checks).
DEGENERACY_TOL = 1e-9
#: Largest |x| or |y| of a quad point (fpiwarp's quad checks).
MAX_COORDINATE = 1e100
#: Promised accuracy of a built map at the corners, relative to the quad's radius (fpiwarp).
EXACT_RTOL = 1e-9
#: Largest distortion fpiwarp builds.
MAX_K = 1e6
_EPS = float(torch.finfo(torch.float64).eps)
_ALT = (1.0, -1.0, 1.0, -1.0)


class FPIParts(NamedTuple):
    """A batch of FPIs f = m_W⁻¹ ∘ A ∘ m_Z as complex128 tensors of shape (B,).

    m_Z(z) = a_z u / (1 - s_z u), u = z - q_z (likewise m_W); A(p) = l1 p +
    l2 conj(p) + l3. Every field is differentiable in the corners.
    """

    q_z: torch.Tensor
    s_z: torch.Tensor
    a_z: torch.Tensor
    l1: torch.Tensor
    l2: torch.Tensor
    l3: torch.Tensor
    q_w: torch.Tensor
    s_w: torch.Tensor
    a_w: torch.Tensor

    @property
    def K(self) -> torch.Tensor:
        """The constant conformal distortion (|l1| + |l2|) / (|l1| - |l2|), float64 (B,)."""
        a, b = self.l1.abs(), self.l2.abs()
        return (a + b) / (a - b)

    def inverse_linear(self):
        """(μ1, μ2, μ3) of A⁻¹(v) = μ1 v + μ2 conj(v) + μ3 (fpiwarp's RLinear.inverse)."""
        det = self.l1.abs() ** 2 - self.l2.abs() ** 2
        m1 = self.l1.conj() / det
        m2 = -self.l2 / det
        return m1, m2, -(m1 * self.l3 + m2 * self.l3.conj())


def _complex(points):
    """(..., 2) real -> (...) complex128."""
    p = points.to(torch.float64)
    return torch.complex(p[..., 0], p[..., 1])


def _signed_area(u):
    """Shoelace area of the (B, 4) complex polygons, relative to their centroid (> 0: counter-clockwise)."""
    u = u - u.mean(dim=-1, keepdim=True)
    nxt = torch.roll(u, -1, dims=-1)
    return 0.5 * (u.conj() * nxt).imag.sum(dim=-1)


def _cross(a, b):
    return (a.conj() * b).imag


def _quad_ok(z):
    """Per item: does the (B, 4) complex quad pass fpiwarp's check_quad? (bool (B,))."""
    finite = torch.isfinite(z.real).all(-1) & torch.isfinite(z.imag).all(-1)
    small = (z.real.abs() <= MAX_COORDINATE).all(-1) & (z.imag.abs() <= MAX_COORDINATE).all(-1)
    z = torch.where((finite & small)[:, None], z, torch.tensor([0, 1, 1 + 1j, 1j], dtype=z.dtype, device=z.device))
    d = z - z.mean(dim=-1, keepdim=True)
    scale = d.abs().amax(dim=-1, keepdim=True)
    u = d / torch.where(scale > 0, scale, 1.0)
    ok = finite & small & (scale[:, 0] > 0)
    for i in range(4):
        for j in range(i + 1, 4):
            ok = ok & ((u[:, i] - u[:, j]).abs() > DEGENERACY_TOL)
    for a, b, c in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        ok = ok & (_cross(u[:, c] - u[:, a], u[:, b] - u[:, a]).abs() > DEGENERACY_TOL)
    for e, f in ((0, 2), (1, 3)):
        a, b, c, dd = u[:, e], u[:, (e + 1) % 4], u[:, f], u[:, (f + 1) % 4]
        d1, d2 = _cross(b - a, c - a), _cross(b - a, dd - a)
        d3, d4 = _cross(dd - c, a - c), _cross(dd - c, b - c)
        ok = ok & ~((d1 * d2 < 0) & (d3 * d4 < 0))
    return ok & (_signed_area(u).abs() > DEGENERACY_TOL)


def _safe(v):
    """v where non-zero, else 1: a denominator whose unused branch must not make NaN gradients."""
    return torch.where(v != 0, v, torch.ones_like(v))


def parallelogram_mobius(z):
    """(q, s, alpha, ok) of the Möbius maps q + ... sending the (B, 4) counter-clockwise
    quads z to unit-radius parallelograms: m(z) = alpha (z - q) / (1 - s (z - q))."""
    e = torch.tensor(_ALT, dtype=torch.float64, device=z.device)
    q = z.mean(dim=-1, keepdim=True)
    rho = (z - q).abs().amax(dim=-1, keepdim=True)
    v = (z - q) / rho
    s1 = v.sum(-1)
    sum_e2 = (e * v * v).sum(-1)
    c0 = (e * v).sum(-1)
    s2 = 0.5 * (s1 * s1 - (v * v).sum(-1))
    c1 = s1 * c0 - sum_e2
    c2 = s2 * c0 - s1 * sum_e2 + (e * v**3).sum(-1)
    disc = c1 * c1 - 4 * c2 * c0
    root = torch.sqrt(torch.where(disc != 0, disc, torch.ones_like(disc))) * (disc != 0)
    plus, minus = c1 + root, c1 - root
    big = torch.where(plus.abs() >= minus.abs(), plus, minus)
    cands = [2 * c0 / _safe(big), big / (2 * _safe(c2))]
    alive = [big != 0, c2 != 0]
    orientation = _signed_area(v) > 0
    best, best_ok = torch.zeros_like(c0), torch.zeros_like(orientation)
    for s, a in zip(cands, alive):
        dens = 1 - s[:, None] * v
        p = v / _safe(dens)
        good = a & (dens.abs() > 1e-12).all(-1) & torch.isfinite(p.real).all(-1) & torch.isfinite(p.imag).all(-1)
        good = good & ((_signed_area(p) > 0) == orientation)
        take = good & (~best_ok | (s.abs() < best.abs()))
        best = torch.where(take, s, best)
        best_ok = best_ok | good
    return q[:, 0], best / rho[:, 0], (1 / rho[:, 0]).to(z.dtype), best_ok


def _frame(p):
    ea = 0.5 * ((p[:, 1] - p[:, 0]) + (p[:, 2] - p[:, 3]))
    eb = 0.5 * ((p[:, 3] - p[:, 0]) + (p[:, 2] - p[:, 1]))
    return p.mean(-1), ea, eb


def mobius(z, q, s, a):
    """m(z) = a u / (1 - s u), u = z - q (broadcast over trailing point axes)."""
    u = z - q
    return a * u / (1 - s * u)


def build(src, dst):
    """(FPIParts, ok): the FPIs from ``src`` to ``dst`` ((B, 4, 2) real tensors)
    and, per item, whether fpiwarp would build it (bool (B,), on the device)."""
    z, w = _complex(src), _complex(dst)
    ok = _quad_ok(z) & _quad_ok(w)
    flip = _signed_area(z) < 0
    ok = ok & (flip == (_signed_area(w) < 0))
    fz = torch.where(flip[:, None], z.conj(), z)
    fw = torch.where(flip[:, None], w.conj(), w)
    good = torch.tensor([0, 1, 1 + 1j, 1j], dtype=z.dtype, device=z.device)
    fz = torch.where(ok[:, None], fz, good)  # refused items get a harmless stand-in (no NaN in shared sums)
    fw = torch.where(ok[:, None], fw, good)
    q_z, s_z, a_z, ok_z = parallelogram_mobius(fz)
    q_w, s_w, a_w, ok_w = parallelogram_mobius(fw)
    pz = mobius(fz, q_z[:, None], s_z[:, None], a_z[:, None])
    pw = mobius(fw, q_w[:, None], s_w[:, None], a_w[:, None])
    cp, pa, pb = _frame(pz)
    cr, ra, rb = _frame(pw)
    det = pa * pb.conj() - pa.conj() * pb
    l1 = (ra * pb.conj() - pa.conj() * rb) / _safe(det)
    l2 = (pa * rb - pb * ra) / _safe(det)
    l3 = cr - l1 * cp - l2 * cp.conj()
    parts = [q_z, s_z, a_z, l1, l2, l3, q_w, s_w, a_w]
    parts = FPIParts(*(torch.where(flip, p.conj(), p) for p in parts))
    a1, a2 = parts.l1.abs(), parts.l2.abs()
    ok = ok & ok_z & ok_w & (det != 0) & ((a1 - a2).abs() > 1e-14 * (a1 + a2))
    K = parts.K
    ok = ok & (K >= 1) & (K <= MAX_K)
    # fpiwarp's exactness promise at the corners: f(src) = dst and f⁻¹(dst) = src
    err_w = (forward_map(parts, z) - w).abs().amax(-1)
    err_z = (inverse_map(parts, w) - z).abs().amax(-1)
    ok = ok & (err_w <= _allowed(w)) & (err_z <= _allowed(z))
    return parts, ok


def _allowed(z):
    r = (z - z.mean(-1, keepdim=True)).abs().amax(-1)
    largest = torch.maximum(z.real.abs(), z.imag.abs()).amax(-1)
    return EXACT_RTOL * r + 64 * _EPS * largest


def forward_map(parts, z):
    """f(z) for complex (B, N) points z (complex128)."""
    p = mobius(z, parts.q_z[:, None], parts.s_z[:, None], parts.a_z[:, None])
    v = parts.l1[:, None] * p + parts.l2[:, None] * p.conj() + parts.l3[:, None]
    return parts.q_w[:, None] + v / (parts.a_w[:, None] + parts.s_w[:, None] * v)


def inverse_map(parts, w):
    """f⁻¹(w) for complex (B, N) points w (complex128)."""
    m1, m2, m3 = parts.inverse_linear()
    p = mobius(w, parts.q_w[:, None], parts.s_w[:, None], parts.a_w[:, None])
    v = m1[:, None] * p + m2[:, None] * p.conj() + m3[:, None]
    return parts.q_z[:, None] + v / (parts.a_z[:, None] + parts.s_z[:, None] * v)


def forward_wirtinger(parts, z):
    """(f, f_z, f_zbar) at complex (B, N) points z (the chain rule of fpiwarp's Transform)."""
    u = z - parts.q_z[:, None]
    den = 1 - parts.s_z[:, None] * u
    p = parts.a_z[:, None] * u / den
    gz = parts.a_z[:, None] / den**2
    l1, l2 = parts.l1[:, None], parts.l2[:, None]
    v = l1 * p + l2 * p.conj() + parts.l3[:, None]
    fz, fzb = l1 * gz, l2 * gz.conj()
    e = parts.a_w[:, None] + parts.s_w[:, None] * v
    hz = parts.a_w[:, None] / e**2  # d/dv of m_W⁻¹(v) = q_w + v / (a_w + s_w v)
    return parts.q_w[:, None] + v / e, hz * fz, hz * fzb


def refuse(src, dst, ok):
    """Raise fpiwarp's error for the first item not ``ok`` (one host sync when all are)."""
    if bool(ok.all()):
        return
    i = int(torch.nonzero(~ok)[0, 0])
    s = src[i].detach().to("cpu", torch.float64).numpy()
    d = dst[i].detach().to("cpu", torch.float64).numpy()
    try:
        fpiwarp.FPI(s, d)
    except fpiwarp.FpiwarpError as err:
        prefix = f"item {i}: " if src.shape[0] > 1 else ""
        raise type(err)(f"{prefix}{err}") from None
    raise fpiwarp.IllConditionedPairError(
        f"item {i}: src -> dst is too ill-conditioned to build in the batched closed form "
        f"(the corners are not met to {EXACT_RTOL:g} of the quad's size); use fatter quads")
