"""FPI.many: N FPIs built on arrays (FPIStack) give what N FPI objects give:
the same acceptance and refusals, parts within 1e-12 relative, K within
1e-14 K² (the rounding of |l1| - |l2|), blocks
within one float32 ulp (most bit for bit), and warp_batch takes the stack."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.quad_fuzz import broad_pairs, mirrored_pairs, unit_pairs

import fpiwarp
from fpiwarp.maps.fpi import FPI, FPIStack


def parts(f):
    return np.array([f.m_src.q, f.m_src.s, f.m_src.alpha, f.linear.l1, f.linear.l2, f.linear.l3, f.m_dst.q, f.m_dst.s,
                     f.m_dst.alpha])


def outcome(src, dst):
    try:
        return FPI(src, dst)
    except fpiwarp.FpiwarpError as exc:
        return exc


def assert_same_as_one_by_one(src, dst):
    """FPI.many(src, dst) refuses what the first refused FPI refuses, else equals the FPIs."""
    each = [outcome(s, d) for s, d in zip(src, dst)]
    bad = [i for i, f in enumerate(each) if isinstance(f, Exception)]
    if bad:
        with pytest.raises(type(each[bad[0]])) as err:
            FPI.many(src, dst)
        assert str(err.value) == f"map {bad[0]} of {len(src)}: {each[bad[0]]}"
        return None
    stack = FPI.many(src, dst)
    assert isinstance(stack, FPIStack) and len(stack) == len(src)
    for i, f in enumerate(each):
        scale = np.abs(parts(f)) + 1e-300
        np.testing.assert_array_less(np.abs(parts(stack[i]) - parts(f)), 1e-12 * scale + 1e-300)
        block, expect = stack.block_stack().array[i], f.params()
        assert np.abs(block.view(np.int32).astype(np.int64) - expect.view(np.int32)).max() <= 1
        inv = stack.inverse.block_stack().array[i]
        assert np.abs(inv.view(np.int32).astype(np.int64) - f.inverse.params().view(np.int32)).max() <= 1
    K = np.array([f.K for f in each])
    assert np.all(np.abs(stack.K - K) <= 1e-14 * K * K)  # K's rounding grows with K (|l1| - |l2| cancels)
    return stack


@settings(max_examples=30)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 40), offset=st.floats(-1e4, 1e4))
def test_unit_pairs_equal_the_fpis(seed, n, offset):
    pairs = unit_pairs(np.random.default_rng(seed), n, offset)
    assert_same_as_one_by_one(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))


@pytest.mark.parametrize("seed", range(6))
def test_broad_pairs_accept_and_refuse_as_the_fpis(seed):
    # scales 1e-6..1e9, offsets to 1e9, thin quads: the ill-conditioned cases FPI refuses
    pairs = broad_pairs(np.random.default_rng(seed), 60)
    src, dst = np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])
    accepted = [i for i in range(len(src)) if not isinstance(outcome(src[i], dst[i]), Exception)]
    assert_same_as_one_by_one(src, dst)  # the first refusal
    assert_same_as_one_by_one(src[accepted], dst[accepted])  # the accepted ones, all built


def test_opposite_orientations_and_bad_shapes_are_refused():
    pairs = mirrored_pairs(np.random.default_rng(1), 3, 0.0)
    assert_same_as_one_by_one(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))
    with pytest.raises(fpiwarp.DegenerateQuadError, match=r"shape \(N, 4, 2\)"):
        FPI.many(np.zeros((2, 3, 2)), np.zeros((2, 3, 2)))
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    with pytest.raises(fpiwarp.DegenerateQuadError, match="map 1 of 2: dst contains NaN"):
        FPI.many([square, square], [square, square * np.nan])


def test_points_inverse_and_items():
    rng = np.random.default_rng(2)
    square = np.array([[0, 0], [40, 0], [40, 30], [0, 30]], float)
    src = np.broadcast_to(square, (5, 4, 2))
    dst = src + rng.uniform(-4, 4, (5, 4, 2))
    stack = FPI.many(src, dst)
    pts = rng.uniform(-5, 45, (5, 7, 2))
    each = np.stack([FPI(s, d)(p) for s, d, p in zip(src, dst, pts)])
    np.testing.assert_allclose(stack(pts), each, atol=1e-10)
    np.testing.assert_allclose(stack.inverse(stack(pts)), pts, atol=1e-9)
    np.testing.assert_allclose(stack(src), dst, atol=1e-10)
    assert len(stack[1:3]) == 2 and isinstance(stack[4], FPI)


@pytest.mark.parametrize("channels", ["last", "first"])
def test_warp_batch_takes_the_stack(any_backend, channels):
    rng = np.random.default_rng(3)
    square = np.array([[0, 0], [31, 0], [31, 23], [0, 23]], float)
    src = np.broadcast_to(square, (4, 4, 2))
    dst = src + rng.uniform(-3, 3, (4, 4, 2))
    images = rng.integers(0, 256, (4, 24, 32, 3)).astype(np.uint8)
    if channels == "first":
        images = np.ascontiguousarray(images.transpose(0, 3, 1, 2))
    stack = FPI.many(src, dst)
    expect = fpiwarp.warp_batch(images, [FPI(s, d) for s, d in zip(src, dst)], backend=any_backend, channels=channels)
    np.testing.assert_array_equal(fpiwarp.warp_batch(images, stack, backend=any_backend, channels=channels), expect)
