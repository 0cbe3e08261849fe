"""Quad checks and FPI construction that do not depend on where the quads
sit or how large they are; ill-conditioned and complex input refused
(issue 12, defects 1-2 and complex quads)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.quad_fuzz import allowed_error
from support.strategies import orient_like, quads

import fpiwarp
from fpiwarp import FPI, ConstrainedFPI, DegenerateQuadError, IllConditionedPairError, LocalDeformation
from fpiwarp.curves import curve_map, fpi_curve
from fpiwarp.maps.quad import EXACT_RTOL, MAX_COORDINATE, MAX_K, check_quad, signed_area
from fpiwarp.testing import mirrored, mirrored_pairs, unit_pairs

SQ = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
D = np.array([[0.0, 0.0], [2.0, 0.1], [1.9, 1.2], [-0.1, 1.0]])
SETTINGS = settings(max_examples=120, deadline=None)


def max_miss(f, src, dst):
    return float(np.max(np.hypot(*(f(src) - dst).T)))


# --- defect 1: the reported cases -----------------------------------------------


@pytest.mark.parametrize("offset", [1e8, 3e8, 1e9, -7.3e8])
def test_the_reported_pair_far_out_is_accepted_and_exact(offset):
    f = FPI(SQ + offset, D + offset)
    near = FPI(SQ, D)
    assert f.K == pytest.approx(near.K, rel=1e-6)
    assert max_miss(f, SQ + offset, D + offset) <= allowed_error(D + offset)


@pytest.mark.parametrize("offset", [3e8, 1e9])
def test_random_unit_pairs_far_out_are_all_accepted(offset):
    for z, w in unit_pairs(np.random.default_rng(12), 300, offset):
        f = FPI(z, w)
        assert f.K >= 1 and max_miss(f, z, w) <= allowed_error(w)


@pytest.mark.parametrize("offset", [0.0, 3e8, 1e9])
def test_mirrored_pairs_far_out_are_all_refused(offset):
    for z, w in mirrored_pairs(np.random.default_rng(12), 300, offset):
        with pytest.raises(DegenerateQuadError, match="opposite orientations"):
            FPI(z, w)


def test_thin_quads_near_the_origin_never_give_k_below_one():
    """The report's thin quad near (10.7, 7.5) (K = -1.067): thin quads
    around there, paired with mirrored and unmirrored targets."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        thin = SQ * [1.0, 10.0 ** -rng.uniform(2, 8)] @ np.array([[0.8, 0.6], [-0.6, 0.8]]) + [10.7, 7.5]
        target = (D if rng.random() < 0.5 else mirrored(D)) + [10.7, 7.5]
        try:
            f = FPI(thin, target)
        except DegenerateQuadError:
            continue
        assert 1 <= f.K <= MAX_K


# --- defect 1: generated families -------------------------------------------------


def moved(pts, scale, shift):
    return np.asarray(pts) * scale + np.asarray(shift)


@SETTINGS
@given(quads(min_scale=0.5, max_scale=2), quads(min_scale=0.5, max_scale=2),
       st.floats(-1e9, 1e9), st.floats(-1e9, 1e9), st.floats(-6, 9))
def test_moving_and_scaling_a_pair_keeps_its_map(z, w, tx, ty, log_scale):
    """Translations up to 1e9 and scales 1e-6..1e9 (as long as the inputs
    keep 6 digits of the quad: |shift| <= 1e6 scale): same verdict, same
    K, corners met to the documented tolerance."""
    w = orient_like(w, z)
    scale = 10.0**log_scale
    shift = np.array([tx, ty]) * min(1.0, 1e6 * scale / 1e9)
    try:
        ref = FPI(z, w)
    except IllConditionedPairError:
        return
    zs, ws = moved(z, scale, shift), moved(w, scale, shift)
    f = FPI(zs, ws)
    assert f.K == pytest.approx(ref.K, rel=1e-4)
    assert max_miss(f, zs, ws) <= allowed_error(ws)
    assert max_miss(f.inverse, ws, zs) <= allowed_error(zs)


@SETTINGS
@given(quads(), st.floats(-1e9, 1e9), st.floats(-1e9, 1e9), st.floats(-6, 9))
def test_checks_are_invariant_under_moves_and_scales(z, tx, ty, log_scale):
    scale = 10.0**log_scale
    shift = np.array([tx, ty]) * min(1.0, 1e6 * scale / 1e9)
    u = check_quad(z)
    v = check_quad(moved(z, scale, shift))
    assert np.sign(signed_area(u)) == np.sign(signed_area(v))
    assert signed_area(v) / scale**2 == pytest.approx(signed_area(u), rel=1e-6)


@SETTINGS
@given(quads(), quads(), st.floats(-1e9, 1e9), st.floats(-1e9, 1e9), st.floats(-6, 9))
def test_far_or_tiny_pairs_are_refused_or_exact_with_k_at_least_one(z, w, tx, ty, log_scale):
    """Any shift and scale, even where the inputs' rounding ruins the
    quads: refused, or K >= 1 and the corners met; mirrored: refused."""
    scale = 10.0**log_scale
    zs, ws = moved(z, scale, (tx, ty)), moved(w, scale, (tx, ty))
    for target in (ws, mirrored(ws - (tx, ty)) + (tx, ty)):
        try:
            f = FPI(zs, target)
        except DegenerateQuadError:
            continue
        assert 1 <= f.K <= MAX_K
        assert max_miss(f, zs, target) <= allowed_error(target)


# --- defect 2: ill-conditioned pairs ------------------------------------------------


@pytest.mark.parametrize("first", range(4))
def test_the_reported_thin_source_to_a_fat_target_is_refused(first):
    """A 4e5 x 4e-3 source onto a fat target (K ~ 1e8: round trips were 5.4
    quad sizes off), in every vertex order."""
    thin = np.roll(np.array([[0.0, 0.0], [4e5, 0.0], [4e5, 4e-3], [1e3, 4.1e-3]]), first, axis=0)
    fat = np.array([[0.0, 0.0], [3.0, 0.2], [2.8, 3.1], [-0.2, 2.9]])
    with pytest.raises(IllConditionedPairError, match=r"too ill-conditioned for float64"):
        FPI(thin, fat)


def test_a_thin_trapezoid_with_a_moderate_distortion_is_kept():
    """Thinness alone is no reason to refuse: this one has K = 26 and is exact."""
    thin = np.array([[0.0, 0.0], [4e5, 0.0], [3.9e5, 4e-3], [2e4, 3.5e-3]])
    fat = np.array([[0.0, 0.0], [3.0, 0.2], [2.8, 3.1], [-0.2, 2.9]])
    f = FPI(thin, fat)
    assert 1 <= f.K < 100 and max_miss(f, thin, fat) <= allowed_error(fat)


@settings(max_examples=60, deadline=None)
@given(quads(min_scale=1, max_scale=1), quads(min_scale=1, max_scale=1), st.floats(0, 9), st.floats(0, np.pi))
def test_thin_pairs_are_refused_or_exact(z, w, log_thinness, angle):
    """Near-degenerate sources squashed up to 1e9 along any direction: a
    map that is built meets its corners, its inverse's corners and round
    trips around the source within EXACT_RTOL of the size."""
    w = orient_like(w, z)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    thin = z @ rot @ np.diag([1.0, 10.0**-log_thinness]) @ rot.T
    try:
        f = FPI(thin, w)
    except DegenerateQuadError:
        return
    assert 1 <= f.K <= MAX_K
    assert max_miss(f, thin, w) <= allowed_error(w)
    assert max_miss(f.inverse, w, thin) <= allowed_error(thin)


def test_refusal_names_the_measured_error_and_the_limit():
    with pytest.raises(IllConditionedPairError) as info:
        FPI(SQ * [1, 1e-7], SQ @ np.array([[1, 0.3], [0, 1]]))
    message = str(info.value)
    assert "\n" not in message and "K = " in message and ("limit" in message)
    assert isinstance(info.value, DegenerateQuadError)


def test_the_documented_tolerances():
    assert EXACT_RTOL == 1e-9 and MAX_K == 1e6 and MAX_COORDINATE == 1e100


# --- complex and text quads ---------------------------------------------------------


COMPLEX = SQ + 0.5j
TEXT = [["0", "0"], ["1", "0"], ["1", "1"], ["0", "1"]]
OBJECT = np.array([[0, 0], [1, 0], [1, 1j], [0, 1]], dtype=object)


@pytest.mark.parametrize("bad", [COMPLEX, COMPLEX.astype(np.complex64), OBJECT, SQ.astype(complex)])
@pytest.mark.parametrize(
    "build",
    [
        lambda q: FPI(q, D),
        lambda q: FPI(SQ, q),
        lambda q: ConstrainedFPI(q, SQ, edges=(0, 2)),
        lambda q: LocalDeformation(SQ * 2, q, edges=(0, 2)),
        lambda q: fpi_curve(q),
        lambda q: curve_map(q),
        lambda q: check_quad(q),
    ],
)
def test_complex_quads_are_refused_everywhere(bad, build):
    with pytest.raises(DegenerateQuadError, match="must be real"):
        build(bad)


@pytest.mark.parametrize("bad", [TEXT, np.array(TEXT), np.array(TEXT, dtype=bytes)])
def test_text_quads_are_refused(bad):
    with pytest.raises(DegenerateQuadError, match="got text"):
        FPI(bad, D)


@pytest.mark.parametrize("bad", [[[0, 0], [1], [1, 1], [0, 1]], [[0, 0], [1, 0], [1, 1]], "abcd", None])
def test_malformed_quads_are_one_line_degenerate_quad_errors(bad):
    with pytest.raises(DegenerateQuadError) as info:
        FPI(bad, D)
    assert "\n" not in str(info.value) and str(info.value).startswith("src ")


@pytest.mark.parametrize("value", [1.0000001e100, 1e200, -1e308])
def test_coordinates_beyond_the_limit_are_refused_with_the_point(value):
    q = SQ.copy()
    q[2, 1] = value
    with pytest.raises(DegenerateQuadError, match=r"^dst point 2 .* lies beyond ±1e\+100"):
        FPI(SQ, q)


def test_huge_but_allowed_coordinates_still_build_an_exact_map():
    big = 1e90
    f = FPI(SQ * big, D * big)
    assert f.K == pytest.approx(FPI(SQ, D).K, rel=1e-9)
    assert max_miss(f, SQ * big, D * big) <= allowed_error(D * big)


def test_integer_and_object_real_quads_are_still_fine():
    assert FPI(SQ.astype(int), D).K == FPI(SQ, D).K
    assert FPI(SQ.astype(object), D).K == FPI(SQ, D).K
    assert fpiwarp.FPI(SQ.tolist(), D.tolist()).K == FPI(SQ, D).K
