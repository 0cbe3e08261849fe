"""map_points, inverse_points, jacobian and distortion of fpiwarp.torch, by their properties."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.torch_cases import require_torch

import fpiwarp

torch = require_torch()
import fpiwarp.torch as ft  # noqa: E402

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@st.composite
def quad_pairs(draw):
    """A square of random size and place, and a target moving each corner by up to 30% of the size;
    only pairs fpiwarp.FPI builds."""
    size = draw(st.floats(1.0, 500.0))
    origin = np.array([draw(st.floats(-300, 300)), draw(st.floats(-300, 300))])
    src = origin + size * SQUARE
    moves = np.array(draw(st.lists(st.floats(-0.3, 0.3), min_size=8, max_size=8))).reshape(4, 2)
    dst = src + size * moves
    try:
        f = fpiwarp.FPI(src, dst)
    except fpiwarp.FpiwarpError:
        from hypothesis import assume

        assume(False)
    return src, dst, f


def _points(src, rng, n=16):
    lo, hi = src.min(0), src.max(0)
    return lo + (hi - lo) * rng.uniform(-0.5, 1.5, (n, 2))


@given(quad_pairs(), st.integers(0, 2**32 - 1))
def test_map_and_inverse_match_fpiwarp_and_undo_each_other(pair, seed):
    src, dst, f = pair
    p = _points(src, np.random.default_rng(seed))
    s, d, pts = torch.tensor(src), torch.tensor(dst), torch.tensor(p)
    size = np.abs(src - src.mean(0)).max()
    mapped = ft.map_points(pts, s, d)
    np.testing.assert_allclose(mapped.numpy(), f(p), rtol=0, atol=1e-9 * size * max(1.0, f.K))
    np.testing.assert_allclose(ft.inverse_points(mapped, s, d).numpy(), p, rtol=0, atol=1e-8 * size * f.K)
    np.testing.assert_allclose(ft.map_points(s, s, d).numpy(), dst, rtol=0, atol=1e-9 * size)
    assert abs(float(ft.distortion(s, d)) - f.K) <= 1e-9 * f.K


@given(quad_pairs(), st.integers(0, 2**32 - 1))
def test_jacobian_matches_autograd_and_fpiwarp(pair, seed):
    src, dst, f = pair
    p = _points(src, np.random.default_rng(seed), n=4)
    s, d = torch.tensor(src), torch.tensor(dst)
    jac = ft.jacobian(torch.tensor(p), s, d)
    np.testing.assert_allclose(jac.numpy(), f.jacobian(p), rtol=1e-9, atol=1e-12 * f.K)
    for k in range(len(p)):
        auto = torch.autograd.functional.jacobian(lambda q: ft.map_points(q[None], s, d)[0], torch.tensor(p[k]))
        np.testing.assert_allclose(jac[k].numpy(), auto.numpy(), rtol=1e-7, atol=1e-9 * f.K)


def test_distortion_gradient_against_finite_differences_and_at_the_identity():
    src = torch.tensor(SQUARE * 20, dtype=torch.float64)
    dst = (src + torch.tensor([[1.0, -2], [3, 1], [-1, 2], [0.5, -1]], dtype=torch.float64)).requires_grad_()
    assert torch.autograd.gradcheck(lambda d: ft.distortion(src, d), (dst,), eps=1e-6, atol=1e-7)
    # at the identity (a square: a parallelogram, s = 0) the perspective terms still have their gradient
    ident = src.clone().requires_grad_()
    pts = torch.tensor([[5.0, 7.0], [13.0, 2.0]], dtype=torch.float64)
    ft.map_points(pts, src, ident).sum().backward()
    num = np.zeros((4, 2))
    for i in range(4):
        for j in range(2):
            e = torch.zeros(4, 2, dtype=torch.float64)
            e[i, j] = 1e-6
            num[i, j] = float(ft.map_points(pts, src, src + e).sum() - ft.map_points(pts, src, src - e).sum()) / 2e-6
    np.testing.assert_allclose(ident.grad.numpy(), num, rtol=1e-6, atol=1e-8)


def test_batched_points_and_float32():
    src = torch.tensor(SQUARE * 10)
    dst = torch.stack([src + 1, src * 1.5])
    pts = torch.rand(2, 5, 2, dtype=torch.float64) * 10
    out = ft.map_points(pts, src, dst)
    assert out.shape == (2, 5, 2)
    np.testing.assert_allclose(out[0].numpy(), (pts[0] + 1).numpy(), atol=1e-12)
    np.testing.assert_allclose(out[1].numpy(), (pts[1] * 1.5).numpy(), atol=1e-12)
    assert ft.map_points(pts.float(), src, dst).dtype == torch.float32
    assert ft.distortion(src, dst).shape == (2,)
    assert ft.jacobian(pts, src, dst).shape == (2, 5, 2, 2)
    with pytest.raises(fpiwarp.ArgumentError, match="points must have shape"):
        ft.map_points(torch.zeros(5, 3), src, dst)


def test_fpiwarp_module_starts_at_the_identity_and_learns_dst():
    layer = ft.FPIWarp(SQUARE * 7)
    img = torch.rand(1, 2, 8, 8, dtype=torch.float64)
    assert torch.allclose(layer(img), img, atol=1e-12)
    assert [n for n, _ in layer.named_parameters()] == ["dst"]
    (layer(img) * torch.rand_like(img)).sum().backward()
    assert layer.dst.grad is not None and torch.isfinite(layer.dst.grad).all() and layer.dst.grad.abs().sum() > 0
