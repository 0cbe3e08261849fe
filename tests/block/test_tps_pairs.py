"""The block's paired TPS cores (CORE_TPS_PAIRS, CORE_TPS_PAIRS_INVERSE):
the same spline as the plain terms in float64, and in float32 the precision
the plain terms lose for a constrained FPI's edge points and their offset
copies a small δ apart (fpiwarp/block/tps_pairs.py)."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support import kernel_cases

from fpiwarp import ConstrainedFPI
from fpiwarp import block as B
from fpiwarp.block.jacobian import wirtinger
from fpiwarp.block.reference import evaluate
from fpiwarp.maps.thin_plate_spline import paired_fields

#: The kernels' float32 tolerance for a spline: 5e-5 of its region's scale
#: (fpiwarp.maps.thin_plate_spline.DEVICE_RTOL).
DEVICE_RTOL = 5e-5


def _plain(stage):
    """The paired stage written as plain terms: b1 = W - b2 at c, b2 at c + d."""
    keep = stage.offsets != 0
    centers = np.concatenate([stage.centers, (stage.centers + stage.offsets)[keep]])
    weights = np.concatenate([stage.weights - stage.offset_weights, stage.offset_weights[keep]])
    core = B.CORE_TPS if stage.core == B.CORE_TPS_PAIRS else B.CORE_TPS_INVERSE
    return dataclasses.replace(stage, core=core, centers=centers, weights=weights,
                               offsets=np.zeros(0, complex), offset_weights=np.zeros(0, complex))


def test_paired_terms_are_the_plain_spline_in_float64_with_derivatives(rng):
    stage = kernel_cases.tps_pairs_stage()
    pts = kernel_cases.frame_points(rng, 500)
    # every center and every partner hit exactly: finite and the same
    both = np.concatenate([stage.centers, stage.centers + stage.offsets])
    pts = np.concatenate([pts, np.stack([both.real, both.imag], axis=-1)])
    paired, plain = B.pack([stage], np.float64), B.pack([_plain(stage)], np.float64)
    v1, dz1, dzb1 = wirtinger(paired, pts)
    v2, dz2, dzb2 = wirtinger(plain, pts)
    assert np.all(np.isfinite(v1)) and np.all(np.isfinite(dz1)) and np.all(np.isfinite(dzb1))
    np.testing.assert_allclose(v1, v2, rtol=0, atol=1e-10)
    np.testing.assert_allclose(dz1, dz2, rtol=0, atol=1e-10)
    np.testing.assert_allclose(dzb1, dzb2, rtol=0, atol=1e-10)
    np.testing.assert_allclose(evaluate(paired, pts), v2, rtol=0, atol=1e-10)
    inv = kernel_cases.tps_pairs_inverse_stage(tol=1e-11, iters=40)
    q = evaluate(plain, pts[:200])
    np.testing.assert_allclose(evaluate(B.pack([inv], np.float64), q), pts[:200], rtol=0, atol=1e-8)


def _pairs_one_by_one(p, rows, n, dtype, first):
    """The paired core as a loop over the pairs (the sum in the pairs' order)."""
    from fpiwarp.block.tps_pairs import pair_logs  # noqa: PLC0415

    val, dz, dzb = np.zeros_like(p), np.zeros_like(p), np.zeros_like(p)
    for j in range(0, n, 2):
        r1, r2 = rows[first + j], rows[first + j + 1]
        c, w, d, b2 = complex(r1[0], r1[1]), complex(r1[2], r1[3]), complex(r2[0], r2[1]), complex(r2[2], r2[3])
        q = p - c
        q2 = q - d
        a, b = (q.real**2 + q.imag**2).astype(dtype), (q2.real**2 + q2.imag**2).astype(dtype)
        dd = dtype(d.real) * dtype(d.real) + dtype(d.imag) * dtype(d.imag)
        e = (dd - 2 * (q.real * dtype(d.real) + q.imag * dtype(d.imag))).astype(dtype)
        near_a = a <= b
        s, m = np.where(near_a, a, b), np.where(near_a, b, a)
        ls, lm, big_l = pair_logs(e, s, m, dtype)
        la = np.where(near_a, ls, lm)
        g1, gn, qn = 0.5 * (la + 1), 0.5 * (lm + 1), np.where(near_a, q, q2)
        val = val + w * (0.5 * a * la) + b2 * (0.5 * (e * lm + s * big_l))
        dz = dz + w * (g1 * np.conj(q)) + b2 * (0.5 * big_l * np.conj(qn) - gn * np.conj(d))
        dzb = dzb + w * (g1 * q) + b2 * (0.5 * big_l * qn - gn * d)
    return val, dz, dzb


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("group", [1, 5, 64])
def test_pairs_in_groups_along_an_axis_add_as_the_loop_over_them(rng, monkeypatch, dtype, group):
    """The pairs evaluated a group at a time along an axis (one, some, all)
    sum their terms in the pairs' order: the loop's values (the logarithms
    of a longer array may round differently in the last bit, so values are
    compared to a few ulps of their terms)."""
    from fpiwarp.block import tps_pairs  # noqa: PLC0415

    stage = kernel_cases.tps_pairs_stage()
    rows = B.pack([stage], dtype)
    first, n = B.ROW_CENTERS, 2 * len(stage.centers)
    cdt = np.complex64 if dtype == np.float32 else np.complex128
    pts = kernel_cases.frame_points(rng, 300)
    both = np.concatenate([stage.centers, stage.centers + stage.offsets])  # centers hit exactly
    p = np.concatenate([pts[:, 0] + 1j * pts[:, 1], both]).astype(cdt).reshape(-1, 2)
    monkeypatch.setattr(tps_pairs, "CHUNK_ELEMENTS", group * p.size)
    assert len(stage.centers) > 5
    with np.errstate(all="ignore"):
        got = tps_pairs.tps_pairs_core(p, rows, n, dtype, first)
        want = _pairs_one_by_one(p, rows, n, dtype, first)
    for g, w in zip(got, want):
        assert g.shape == w.shape and g.dtype == w.dtype and np.all(np.isfinite(g))
        scale = np.max(np.abs(w)) + 1
        np.testing.assert_allclose(g, w, rtol=0, atol=(1e-5 if dtype == np.float32 else 1e-12) * scale)


def test_a_center_without_partner_gives_the_plain_term(rng):
    """d = 0, b2 = 0: the plain term (float32: to the rounding of a sum
    accumulated in another order)."""
    stage = kernel_cases.tps_stage()
    alone = dataclasses.replace(stage, core=B.CORE_TPS_PAIRS, offsets=np.zeros(6, complex),
                                offset_weights=np.zeros(6, complex))
    pts = kernel_cases.frame_points(rng, 300)
    for dtype, tol in ((np.float32, 1e-6), (np.float64, 1e-14)):
        a, b = B.pack([alone], dtype), B.pack([stage], dtype)
        got, want = evaluate(a, pts, dtype).astype(np.float64), evaluate(b, pts, dtype).astype(np.float64)
        kernel_cases.assert_close_relative(got, want, rtol=tol)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=12, max_size=12), st.sampled_from([1, 2, 3]))
def test_pairing_keeps_the_spline(values, copies):
    """paired_fields regroups terms without changing their sum, also for a
    center with several offset copies (a shared corner)."""
    v = np.array(values)
    centers = v[:4] + 1j * v[4:8]
    centers = np.concatenate([centers, centers[0] + 0.01 * np.exp(1j * np.arange(copies))])
    weights = np.concatenate([v[8:12] + 0.5j, -np.full(copies, 40.0 / copies)])
    partner = np.concatenate([np.full(4, -1), np.zeros(copies, int)])
    c, w, d, b2 = paired_fields(centers, weights, partner)
    assert len(c) == 3 + copies
    expanded_c = np.concatenate([c, c + d])
    expanded_w = np.concatenate([w - b2, b2])
    p = np.linspace(-4, 4, 7)[:, None] + 1j * np.linspace(-4, 4, 7)[None, :]
    p = p.reshape(-1)[:, None]

    def u(z, cc, ww):
        r2 = np.abs(z - cc) ** 2
        return np.sum(ww * 0.5 * r2 * np.log(np.where(r2 > 0, r2, 1)), axis=-1)

    np.testing.assert_allclose(u(p, expanded_c, expanded_w), u(p, centers, weights), rtol=0, atol=1e-9)


def test_the_block_refuses_malformed_paired_stages():
    stage = kernel_cases.tps_pairs_stage()
    with pytest.raises(ValueError, match="one offset and one offset weight per center"):
        B.pack([dataclasses.replace(stage, offsets=stage.offsets[:-1])])
    block = B.pack([stage])
    block[1 + B.ROW_HEADER, 1] -= 1
    with pytest.raises(ValueError, match="odd"):
        B.describe(block)
    too_many = dataclasses.replace(stage, centers=np.arange(33) * (1 + 1j), weights=np.ones(33),
                                   offsets=np.ones(33), offset_weights=np.ones(33))
    with pytest.raises(ValueError, match="at most 64 TPS center rows"):
        B.pack([too_many])


SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])


def _float32_error(f, pts):
    """Largest float32 block error against the host map, in units of the
    target's size."""
    host = f(pts)
    return np.nanmax(np.abs(evaluate(f.params(), pts, np.float32) - host)) / np.ptp(f.dst, axis=0).max()


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_float32_block_of_a_small_delta_map_evaluates_like_the_host_where_plain_terms_did_not(seed):
    """A δ = 0.002 adaptive constrained FPI (weights of order 1 / δ): the
    paired block within the device tolerance, the same spline packed as
    plain terms beyond it (measured on seeds 1..11 with the edge-bound
    spacing choice: paired 2.5e-7 to 1.5e-6, plain 3.1e-5 to 1.6e-4 of the
    size; on seeds 4, 5, 6, 9, 11 plain is beyond the device tolerance)."""
    rng = np.random.default_rng(seed)
    dst = SQUARE + 0.3 * rng.standard_normal((4, 2))
    f = ConstrainedFPI(SQUARE, dst, edges=(0, 2), points_per_edge=16, delta=0.002, spacing="adaptive")
    assert f.stage().core == B.CORE_TPS_PAIRS
    s = np.linspace(-0.25, 1.25, 61)
    pts = np.stack(np.meshgrid(s, s), axis=-1).reshape(-1, 2)
    paired = _float32_error(f, pts)
    f.tps.partner = None  # the same spline as 64 plain terms
    assert f.stage().core == B.CORE_TPS
    plain = _float32_error(f, pts)
    assert paired <= DEVICE_RTOL / 5, paired
    assert plain > DEVICE_RTOL and plain > 20 * paired, (plain, paired)
