"""Gradients of fpiwarp.torch: gradcheck in float64, and a deterministic backward."""

import numpy as np
import pytest
from support.torch_cases import DST, MODES, SRC, require_torch

torch = require_torch()
from torch.autograd import gradcheck  # noqa: E402

import fpiwarp.torch as ft  # noqa: E402


def _inputs(seed=0):
    g = torch.Generator().manual_seed(seed)
    img = torch.rand(2, 2, 8, 10, generator=g, dtype=torch.float64, requires_grad=True)
    src = torch.tensor(SRC[:, :] * [9 / 31, 7 / 23], dtype=torch.float64)
    dst = src + torch.tensor((DST - SRC) * 0.4, dtype=torch.float64)
    return img, src.requires_grad_(), dst.requires_grad_()


def _pixels(rows, cols):
    ys, xs = torch.meshgrid(torch.arange(rows, dtype=torch.float64), torch.arange(cols, dtype=torch.float64),
                            indexing="ij")
    return torch.stack([xs, ys], -1).reshape(-1, 2)


@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", MODES)
def test_warp_image_gradcheck(order, mode):
    """Image, src and dst (order 0: image only); a 9 × 12 output of an 8 × 10 source: pixels outside it."""
    img, src, dst = _inputs()
    if order == 0:
        src, dst = src.detach(), dst.detach()
    assert gradcheck(lambda i, s, d: ft.warp_image(i, s, d, (9, 12), order=order, mode=mode, cval=0.3),
                     (img, src, dst), eps=1e-6, atol=1e-6, fast_mode=True)


@pytest.mark.parametrize("sampler", ["gather-sort", "gather-scatter"])
@pytest.mark.parametrize("order", [1, 3])
@pytest.mark.parametrize("mode", MODES)
def test_gathering_sampler_gradcheck(sampler, order, mode):
    """The CUDA sampler (gather-sort), run on the CPU, through differentiable positions."""
    img, src, dst = _inputs(1)

    def f(i, s, d):
        pos = ft.inverse_points(_pixels(9, 12), s, d).reshape(1, 9, 12, 2)
        return ft.sample(i, pos, order=order, mode=mode, cval=0.3, sampler=sampler)

    assert gradcheck(f, (img, src, dst), eps=1e-6, atol=1e-6, fast_mode=True)


def _grads(fn, *tensors):
    for t in tensors:
        t.grad = None
    out = fn()
    out.backward(torch.linspace(-1, 1, out.numel(), dtype=out.dtype).reshape(out.shape))
    return [t.grad.clone() for t in tensors]


def _many_to_one_case(device, dtype=torch.float32):
    """A strong shrink with edge mode: many output pixels and taps land on each source pixel."""
    g = torch.Generator().manual_seed(5)
    img = torch.rand(3, 3, 40, 50, generator=g).to(device, dtype).requires_grad_()
    src = torch.tensor([[0.0, 0], [49, 0], [49, 39], [0, 39]], dtype=torch.float64, device=device)
    dst = torch.tensor([[10.0, 8], [30, 12], [28, 30], [12, 26]], dtype=torch.float64, device=device)
    return img, src, dst.expand(3, 4, 2).clone().requires_grad_()


@pytest.mark.parametrize("sampler", ["auto", "gather-sort", "gather-scatter"])
@pytest.mark.parametrize("order", [1, 3])
def test_backward_is_bit_identical_run_to_run_on_cpu(sampler, order):
    if sampler == "auto":
        img, src, dst = _many_to_one_case("cpu")
        run = lambda: ft.warp_image(img, src.expand(3, 4, 2), dst, (60, 70), order=order, mode="edge")  # noqa: E731
    else:
        img, src, dst = _many_to_one_case("cpu")

        def run():
            pos = ft.inverse_points(_pixels(60, 70), src.expand(3, 4, 2), dst).reshape(3, 60, 70, 2)
            return ft.sample(img, pos, order=order, mode="edge", sampler=sampler)

    first = _grads(run, img, dst)
    for _ in range(3):
        again = _grads(run, img, dst)
        assert all(torch.equal(a, b) for a, b in zip(first, again))


@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", MODES)
def test_sorted_and_scattered_image_gradients_agree_bit_for_bit(order, mode):
    """Both add each source pixel's terms in the same order: the CUDA method is checked here, on the CPU."""
    img, src, dst = _many_to_one_case("cpu", torch.float64)
    pos = ft.inverse_points(_pixels(60, 70), src.expand(3, 4, 2), dst).reshape(3, 60, 70, 2).detach()
    grads = [_grads(lambda s=s: ft.sample(img, pos, order=order, mode=mode, sampler=s), img)[0]
             for s in ("gather-sort", "gather-scatter")]
    assert torch.equal(grads[0], grads[1])
    if order != 3:
        auto = _grads(lambda: ft.sample(img, pos, order=order, mode=mode, sampler="grid_sample"), img)[0]
        np.testing.assert_allclose(auto.numpy(), grads[0].numpy(), rtol=1e-12, atol=1e-12)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device here (benchmarks/gpu_torch.py runs these)")
@pytest.mark.parametrize("order", [1, 3])
@pytest.mark.parametrize("mode", MODES)
def test_cuda_backward_is_bit_identical_and_matches_the_cpu(order, mode):
    img, src, dst = _many_to_one_case("cuda", torch.float64)
    run = lambda: ft.warp_image(img, src.expand(3, 4, 2), dst, (60, 70), order=order, mode=mode)  # noqa: E731
    first = _grads(run, img, dst)
    for _ in range(3):
        assert all(torch.equal(a, b) for a, b in zip(first, _grads(run, img, dst)))
    ci, cs, cd = (t.detach().cpu() for t in (img, src, dst))
    ci.requires_grad_(), cd.requires_grad_()
    cpu = _grads(lambda: ft.warp_image(ci, cs.expand(3, 4, 2), cd, (60, 70), order=order, mode=mode), ci, cd)
    for a, b in zip(first, cpu):
        np.testing.assert_allclose(a.cpu().numpy(), b.numpy(), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("order,mode", [(1, "constant"), (3, "wrap")])
def test_full_gradcheck_of_every_input_element(order, mode):
    """The full Jacobian (fast_mode=False) on a small case: every pixel and corner coordinate."""
    g = torch.Generator().manual_seed(2)
    img = torch.rand(1, 1, 5, 6, generator=g, dtype=torch.float64, requires_grad=True)
    src = torch.tensor([[0.0, 0], [5, 0], [5, 4], [0, 4]], dtype=torch.float64, requires_grad=True)
    dst = (src.detach() + torch.tensor([[0.4, -0.3], [0.2, 0.5], [-0.6, 0.3], [-0.2, -0.4]],
                                       dtype=torch.float64)).requires_grad_()
    assert gradcheck(lambda i, s, d: ft.warp_image(i, s, d, (6, 7), order=order, mode=mode, cval=0.3),
                     (img, src, dst), eps=1e-6, atol=1e-6)
