"""Möbius and R-linear parts, composition, and the parameter block."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fpiwarp
from fpiwarp import Compound, Mobius, RLinear
from fpiwarp.block import LAYOUT_VERSION, MAX_STAGES, STAGE_ROWS, Stage, evaluate, pack

complexes = st.complex_numbers(min_magnitude=0.1, max_magnitude=10, allow_nan=False, allow_infinity=False)


def pts(seed, n=40, spread=5.0):
    return np.random.default_rng(seed).normal(size=(n, 2)) * spread


@settings(max_examples=100, deadline=None)
@given(complexes, complexes, complexes, complexes)
def test_mobius_coefficients_and_inverse(a, b, c, d):
    if abs(a * d - b * c) < 1e-2 * (abs(a * d) + abs(b * c)):
        return
    m = Mobius(a, b, c, d)
    p = pts(0)
    z = p[:, 0] + 1j * p[:, 1]
    expected = (a * z + b) / (c * z + d)
    keep = np.abs(c * z + d) > 1e-3 * (abs(c) + abs(d))
    got = m(p)[keep]
    assert np.allclose(got[:, 0] + 1j * got[:, 1], expected[keep], rtol=1e-9, atol=1e-9)
    back = m.inverse(m(p))
    assert np.allclose(back[keep], p[keep], rtol=1e-7, atol=1e-7)


def test_mobius_from_three_points():
    src = np.array([[0, 0], [1, 0], [0, 1.0]])
    dst = np.array([[2, 1], [-1, 3], [0.5, 0.25]])
    m = Mobius.from_points(src, dst)
    assert np.allclose(m(src), dst)
    assert m.K == 1.0 and m.dilation == 0.0
    with pytest.raises(ValueError, match="three"):
        Mobius.from_points(src[:2], dst[:2])


def test_mobius_pole_and_singular_coefficients():
    m = Mobius(1, 0, 1, -2)  # z / (z - 2)
    assert np.allclose(m.pole, [2, 0])
    assert np.allclose(m.pole_image, [1, 0])
    assert Mobius(2, 1, 0, 1).pole is None
    with pytest.raises(ValueError, match="ad - bc"):
        Mobius(1, 2, 2, 4)
    with pytest.raises(ValueError, match="finite"):
        Mobius(np.nan, 0, 0, 1)
    with pytest.raises(fpiwarp.ArgumentError, match="outside float64's range"):  # (c q + d)² underflows
        Mobius(1, 0, 0, 1e-170)  # z * 1e170: valid, but its centered form squares c q + d = 1e-170
    with pytest.raises(fpiwarp.ArgumentError, match="outside float64's range"):
        Mobius(1, 0, 0, 1e-170, center=5)
    with pytest.raises(fpiwarp.ArgumentError, match="outside float64's range"):  # ... or overflows
        Mobius(1, 0, 0, 1e170)


def test_rlinear_from_matrix_and_inverse():
    matrix = np.array([[2.0, 0.5], [-0.3, 1.5]])
    offset = np.array([3.0, -1.0])
    A = RLinear.from_matrix(matrix, offset)
    p = pts(1)
    assert np.allclose(A(p), p @ matrix.T + offset)
    assert np.allclose(A.jacobian(p), matrix)
    assert np.allclose(A.inverse(A(p)), p)
    sv = np.linalg.svd(matrix, compute_uv=False)
    assert A.K == pytest.approx(sv[0] / sv[1])
    with pytest.raises(ValueError, match="singular"):
        RLinear(1, 1)
    tiny = RLinear(1e-166)  # a valid map whose |l1|² underflows: its inverse is refused in one line
    with pytest.raises(fpiwarp.ArgumentError, match="cannot invert the R-linear map.*outside float64's normal range"):
        tiny.inverse.stages()
    with pytest.raises(fpiwarp.ArgumentError, match="outside float64's normal range"):
        RLinear(1e160).inverse.stages()
    with pytest.raises(fpiwarp.ArgumentError, match="RLinear cannot be packed.*outside float64's normal range"):
        tiny.params()  # the block carries the inverse too (the device Newton's seed)


def test_composition_is_in_mathematical_order_and_fuses():
    f = Mobius(1, 2j, 0.1, 1)
    g = Mobius(2, 0, 0.05j, 1)
    h = RLinear(1.5, 0.2, 1 - 1j)
    p = pts(2, spread=2)
    gf = g @ f
    assert isinstance(gf, Compound) and len(gf.steps) == 1  # two Möbius fuse into one
    assert np.allclose(gf(p), g(f(p)))
    hgf = h @ g @ f
    assert np.allclose(hgf(p), h(g(f(p))))
    assert np.allclose(hgf.inverse(hgf(p)), p)
    assert np.allclose((h @ h)(p), h(h(p)))
    assert len((h @ h).steps) == 1


def test_compound_jacobian_by_chain_rule(sample_fpi):
    h = RLinear(1.2, 0.3j, 2)
    c = h @ sample_fpi
    p = np.random.default_rng(3).uniform(0, 60, size=(10, 2))
    eps = 1e-6
    fd = np.stack(
        [(c(p + [eps, 0]) - c(p - [eps, 0])) / (2 * eps), (c(p + [0, eps]) - c(p - [0, eps])) / (2 * eps)], axis=-1
    )
    assert np.allclose(c.jacobian(p), fd, rtol=1e-6, atol=1e-6)
    assert np.allclose(c.distortion(p), np.linalg.cond(c.jacobian(p)), rtol=1e-9)


def test_params_block_layout(sample_fpi):
    block = sample_fpi.params()
    assert block.dtype == np.float32 and block.shape == (1 + STAGE_ROWS, 4)
    assert tuple(block[0, :2]) == (1, LAYOUT_VERSION)
    compound = RLinear(1, 0, 5) @ sample_fpi @ Mobius(1, 0, 0.001, 1)
    assert compound.params().shape == (1 + 3 * STAGE_ROWS, 4)
    with pytest.raises(ValueError, match="stages"):
        pack([Stage()] * (MAX_STAGES + 1))


@pytest.mark.parametrize("dtype, rtol", [(np.float64, 1e-6), (np.float32, 1e-5)])
def test_params_block_evaluates_like_the_map(sample_fpi, dtype, rtol):
    """The block reference (what kernels mirror) equals the float64 maps,
    to float32 rounding of the coefficients."""
    p = np.random.default_rng(4).uniform(-10, 70, size=(200, 2))
    for f in [
        sample_fpi,
        sample_fpi.inverse,
        Mobius(1, 2j, 0.01, 1),
        RLinear(1.1, 0.2, 3j),
        RLinear(2, 0, 1) @ sample_fpi,
        sample_fpi.inverse @ Mobius(1, 0, 0.001j, 1),
    ]:
        ref = f(p)
        got = evaluate(f.params(), p, dtype)
        scale = np.abs(ref).max()
        assert np.allclose(got, ref, rtol=rtol, atol=rtol * scale), f


@pytest.mark.parametrize("center", [-1.0, -1.0 + 1e-13, 0.0])
def test_mobius_centered_on_its_pole_recenters(center):
    m = Mobius(1, 0, 1, 1, center=center)  # z / (z + 1), pole at -1
    z = np.array([0.5, 2.0, -3.0, 1j])
    got = m(np.stack([z.real, z.imag], axis=-1))
    assert np.allclose(got[:, 0] + 1j * got[:, 1], z / (z + 1), rtol=1e-12)
    assert np.allclose(m.pole, [-1, 0])


def test_mobius_from_points_names_coincident_points():
    with pytest.raises(ValueError, match="distinct"):
        Mobius.from_points([[0, 0], [0, 0], [1, 1]], [[0, 0], [1, 0], [0, 1]])
