"""fpiwarp.torch.warp_image and sample: the forward against fpiwarp's numpy reference, and refusals."""

import numpy as np
import pytest
from support.torch_cases import DST, MODES, SRC, pole_map, reference_sample, require_torch

import fpiwarp

torch = require_torch()
import fpiwarp.torch as ft  # noqa: E402

SAMPLERS = ("auto", "gather-scatter", "gather-sort", "grid_sample")


@pytest.fixture
def image():
    return np.random.default_rng(7).random((24, 32, 3))


def _chw(image, dtype):
    return torch.tensor(image, dtype=dtype).permute(2, 0, 1)


def _hwc(t):
    return t.detach().permute(1, 2, 0).double().numpy()


@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", MODES)
def test_the_test_sampler_is_fpiwarps_numpy_reference(image, order, mode):
    f = fpiwarp.FPI(SRC, DST)
    want = fpiwarp.warp_image(image.astype(np.float32), f, (30, 40), order=order, mode=mode, cval=0.25,
                              backend="numpy")
    got = reference_sample(image.astype(np.float32).astype(np.float64), fpiwarp.source_positions(f, (30, 40)),
                           order, mode, 0.25)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-7)


@pytest.mark.parametrize("dtype,tol", [("float64", 1e-9), ("float32", 1e-4)])
@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", MODES)
def test_warp_matches_the_reference(image, dtype, tol, order, mode):
    """Output 30 × 40 from a 24 × 32 source: pixels outside the source, near and across its border."""
    dtype = getattr(torch, dtype)
    f = fpiwarp.FPI(SRC, DST)
    want = reference_sample(image, fpiwarp.source_positions(f, (30, 40)), order, mode, [0.25, 0.5, 0.75])
    got = ft.warp_image(_chw(image, dtype), torch.tensor(SRC, dtype=dtype), torch.tensor(DST, dtype=dtype),
                        (30, 40), order=order, mode=mode, cval=[0.25, 0.5, 0.75])
    assert got.dtype == dtype and got.shape == (3, 30, 40)
    np.testing.assert_allclose(_hwc(got), want, rtol=0, atol=tol)
    if dtype == torch.float32:  # and the library's own float32 result
        ref32 = fpiwarp.warp_image(image.astype(np.float32), f, (30, 40), order=order, mode=mode,
                                   cval=[0.25, 0.5, 0.75], backend="numpy")
        np.testing.assert_allclose(_hwc(got), ref32, rtol=0, atol=tol)


@pytest.mark.parametrize("sampler", SAMPLERS)
@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", MODES)
def test_every_sampler_gives_the_reference_at_the_pole(sampler, order, mode):
    """The pole's image lies inside the output: positions huge or infinite there -> cval (pole rule)."""
    if sampler == "grid_sample" and order == 3:
        pytest.skip("grid_sample has no Keys cubic")
    f = pole_map()
    img = np.random.default_rng(3).random((21, 31, 2))
    pos = fpiwarp.source_positions(f, (30, 40))
    assert np.abs(pos).max() > 500  # pixels next to w∞ sample far away
    raw = pos.copy()
    pos[0, :5] = [[np.inf, 1], [np.nan, 2], [3e7, 3], [4, -(2.0**24) - 1], [2.0**24, 5]]  # what the pole rule is about
    want = reference_sample(img, pos, order, mode, [5.0, 6.0])
    got = ft.sample(_chw(img, torch.float64), torch.tensor(pos), order=order, mode=mode, cval=[5.0, 6.0],
                    sampler=sampler)
    np.testing.assert_allclose(_hwc(got), want, rtol=0, atol=1e-9)
    whole = ft.warp_image(_chw(img, torch.float64), torch.tensor(f.src), torch.tensor(f.dst), (30, 40),
                          order=order, mode=mode, cval=[5.0, 6.0])
    np.testing.assert_allclose(_hwc(whole), reference_sample(img, raw, order, mode, [5.0, 6.0]), rtol=0, atol=1e-9)


def test_batches_broadcast_and_unbatched_inputs_stay_unbatched(image):
    img = _chw(image, torch.float64)
    src = torch.tensor(SRC)
    dsts = torch.stack([torch.tensor(DST), torch.tensor(SRC)])
    out = ft.warp_image(img, src, dsts)
    assert out.shape == (2, 3, 24, 32)
    np.testing.assert_allclose(out[1].numpy(), img.numpy(), atol=1e-9)  # the identity
    np.testing.assert_allclose(out[0].numpy(), ft.warp_image(img, src, torch.tensor(DST)).numpy(), atol=1e-12)
    assert ft.warp_image(img[None].expand(2, -1, -1, -1), src, torch.tensor(DST)).shape == (2, 3, 24, 32)


def test_warp_by_any_fpiwarp_map_matches_the_reference(image):
    local = fpiwarp.LocalDeformation(SRC, DST, edges=(0, 2))
    g = fpiwarp.Compound([fpiwarp.FPI(SRC, DST), fpiwarp.RLinear(1, 0.05, 1 + 2j)])
    for transform in (local, g):
        want = fpiwarp.warp_image(image.astype(np.float32), transform, (26, 30), order=1, mode="reflect",
                                  backend="numpy")
        got = ft.warp_image(_chw(image.astype(np.float32), torch.float32), transform, (26, 30), mode="reflect")
        np.testing.assert_allclose(_hwc(got), want, atol=1e-4)


@pytest.mark.parametrize("call,error,words", [
    (lambda i, s, d: ft.warp_image(i.long(), s, d), fpiwarp.ArgumentTypeError, "image must be float32"),
    (lambda i, s, d: ft.warp_image(i.numpy(), s, d), fpiwarp.ArgumentTypeError, "image must be a torch.Tensor"),
    (lambda i, s, d: ft.warp_image(i[0, 0], s, d), fpiwarp.ArgumentError, "image must have shape"),
    (lambda i, s, d: ft.warp_image(i, s[:3], d), fpiwarp.ArgumentError, "src must have shape"),
    (lambda i, s, d: ft.warp_image(i, s, d.long()), fpiwarp.ArgumentTypeError, "dst must be a float32"),
    (lambda i, s, d: ft.warp_image(i, s, d.to("meta")), fpiwarp.DeviceMismatchError, "dst is on meta"),
    (lambda i, s, d: ft.warp_image(i, s, d, order=2), fpiwarp.ArgumentError, "order must be 0, 1 or 3"),
    (lambda i, s, d: ft.warp_image(i, s, d, mode="mirror"), fpiwarp.ArgumentError, "mode must be one of"),
    (lambda i, s, d: ft.warp_image(i, s, d, cval=[1, 2]), fpiwarp.ArgumentError, "cval must be finite"),
    (lambda i, s, d: ft.warp_image(i, s, d, cval=float("nan")), fpiwarp.ArgumentError, "cval must be finite"),
    (lambda i, s, d: ft.warp_image(i, s, d, (0, 4)), fpiwarp.ArgumentError, "output_shape must be two positive"),
    (lambda i, s, d: ft.warp_image(i, s, d, antialias=True), fpiwarp.ArgumentError, "antialias=True is not supported"),
    (lambda i, s, d: ft.warp_image(i, s), fpiwarp.ArgumentError, "needs src and dst"),
    (lambda i, s, d: ft.warp_image(i[None].expand(3, -1, -1, -1), s.expand(2, 4, 2), d), fpiwarp.ArgumentError,
     "batch of 3"),
    (lambda i, s, d: ft.sample(i, s, sampler="fast"), fpiwarp.ArgumentError, "positions must have shape"),
])
def test_bad_arguments_get_one_line_errors_naming_them(image, call, error, words):
    img = _chw(image, torch.float32)
    with pytest.raises(error, match=words) as info:
        call(img, torch.tensor(SRC, dtype=torch.float32), torch.tensor(DST, dtype=torch.float32))
    assert "\n" not in str(info.value)


def test_degenerate_quads_get_fpiwarps_error_with_the_item(image):
    img = _chw(image, torch.float64)
    bad = torch.tensor(SRC).clone()
    bad[2] = bad[1]  # two coincident corners
    with pytest.raises(fpiwarp.DegenerateQuadError, match=r"^item 1: dst points 1 and 2 coincide"):
        ft.warp_image(img, torch.tensor(SRC), torch.stack([torch.tensor(DST), bad]))
    flipped = torch.tensor(SRC)[[0, 3, 2, 1]]
    with pytest.raises(fpiwarp.DegenerateQuadError, match="opposite orientations"):
        ft.warp_image(img, torch.tensor(SRC), flipped)
    with pytest.raises(fpiwarp.DegenerateQuadError, match="NaN"):
        ft.warp_image(img, torch.tensor(SRC), torch.full((4, 2), float("nan"), dtype=torch.float64))


def test_clockwise_quads_and_the_identity(image):
    """Quads in either orientation, as fpiwarp.FPI; dst = src is the identity to rounding."""
    img = _chw(image, torch.float64)
    cw = SRC[[0, 3, 2, 1]]
    got = ft.warp_image(img, torch.tensor(cw), torch.tensor(DST[[0, 3, 2, 1]]), order=3)
    want = reference_sample(image, fpiwarp.source_positions(fpiwarp.FPI(cw, DST[[0, 3, 2, 1]]), (24, 32)), 3,
                            "constant", 0.0)
    np.testing.assert_allclose(_hwc(got), want, atol=1e-9)
    np.testing.assert_allclose(ft.warp_image(img, torch.tensor(SRC), torch.tensor(SRC)).numpy(), img.numpy(),
                               atol=1e-12)
