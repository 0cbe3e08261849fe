"""Properties of the 4-point interpolant (paper §2-3), tested on random quads."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.strategies import orient_like, quads

import fpiwarp
from fpiwarp import FPI, DegenerateQuadError, Mobius, RLinear
from fpiwarp.maps.quad import check_quad, parallelogram_mobius

SETTINGS = settings(max_examples=150, deadline=None)
UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def scale_of(pts):
    return float(np.max(np.abs(pts - pts.mean(axis=0))))


def points_around(pts, rng, n=64):
    """Random points in the quad's bounding box, grown by half its size."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.5 * (hi - lo)
    return rng.uniform(lo - pad, hi + pad, size=(n, 2))


def away_from_pole(f, p, src_scale):
    """Drop points closer than 5 % of the quad's size to the pole z∞."""
    if f.pole is None:
        return p
    return p[np.linalg.norm(p - f.pole, axis=1) > 0.05 * src_scale]


@SETTINGS
@given(quads(), quads())
def test_interpolates_the_corners(z, w):
    w = orient_like(w, z)
    f = FPI(z, w)
    assert np.allclose(f(z), w, rtol=0, atol=1e-12 * scale_of(w) + 1e-12 * np.abs(w).max())


@SETTINGS
@given(quads(), quads(), st.integers(0, 2**32 - 1))
def test_inverse_round_trip(z, w, seed):
    w = orient_like(w, z)
    f = FPI(z, w)
    p = away_from_pole(f, points_around(z, np.random.default_rng(seed)), scale_of(z))
    back = f.inverse(f(p))
    assert np.allclose(back, p, rtol=0, atol=1e-9 * (scale_of(z) + np.abs(z).max()))
    assert np.allclose(f.inverse(w), z, rtol=0, atol=1e-11 * (scale_of(z) + np.abs(z).max()))


@SETTINGS
@given(quads(), quads())
def test_distortion_is_constant_and_symmetric(z, w):
    w = orient_like(w, z)
    f = FPI(z, w)
    p = away_from_pole(f, points_around(z, np.random.default_rng(0)), scale_of(z))
    k = f.distortion(p)
    assert f.K >= 1
    assert np.allclose(k, f.K, rtol=1e-9)
    assert f.inverse.K == pytest.approx(f.K, rel=1e-10)
    assert f.dilation == pytest.approx((f.K - 1) / (f.K + 1), rel=1e-12)


def finite_difference_jacobian(f, p, h):
    jac = np.empty(p.shape[:-1] + (2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = h
        jac[..., :, j] = (f(p + e) - f(p - e)) / (2 * h)
    return jac


@SETTINGS
@given(quads(), quads())
def test_jacobian_matches_finite_differences(z, w):
    w = orient_like(w, z)
    f = FPI(z, w)
    s = scale_of(z)
    p = away_from_pole(f, points_around(z, np.random.default_rng(1), 16), s)
    p = p[np.linalg.norm(p - f.pole, axis=1) > 0.3 * s] if f.pole is not None else p
    jac = f.jacobian(p)
    fd = finite_difference_jacobian(f, p, 1e-5 * s)
    norm = np.abs(jac).max(axis=(-1, -2), keepdims=True)
    assert np.all(np.abs(jac - fd) <= 1e-6 * norm)
    # K is the ratio of the Jacobian's singular values (eq. 11)
    sv = np.linalg.svd(jac, compute_uv=False)
    assert np.allclose(sv[:, 0] / sv[:, 1], f.K, rtol=1e-8)


@SETTINGS
@given(quads(), st.complex_numbers(max_magnitude=3, min_magnitude=0.2), st.floats(0.1, 10))
def test_reproduces_a_mobius_map(z, pole_offset, size):
    """The FPI of (Z, m(Z)) is m itself, with K = 1."""
    s = scale_of(z)
    zc = z[:, 0] + 1j * z[:, 1]
    q = zc.mean()
    m = Mobius.centered(q, 1 / (pole_offset * s * 2), size * np.exp(1j * size), 0.3 * s)
    w = m(z)
    if not np.all(np.isfinite(w)):
        return
    try:
        check_quad(w)
    except DegenerateQuadError:
        return  # a Möbius map can bend a quad into a bow-tie: no FPI then
    from support.strategies import same_orientation

    if not same_orientation(z, w):
        return  # the pole inside the quad turns it inside out: no FPI then
    f = FPI(z, w)
    assert f.K == pytest.approx(1.0, abs=1e-9)
    p = points_around(z, np.random.default_rng(2), 32)
    p = p[np.linalg.norm(p - m.pole, axis=1) > 0.3 * s]
    scale_w = scale_of(w) + np.abs(w).max()
    assert np.allclose(f(p), m(p), rtol=1e-9, atol=1e-9 * scale_w)


@SETTINGS
@given(st.lists(st.floats(-5, 5), min_size=6, max_size=6), st.lists(st.floats(-5, 5), min_size=6, max_size=6))
def test_parallelograms_give_the_affine_map(a, b):
    def parallelogram(v):
        o, e1, e2 = v[0] + 1j * v[1], v[2] + 1j * v[3], v[4] + 1j * v[5]
        pts = np.array([o, o + e1, o + e1 + e2, o + e2])
        return np.stack([pts.real, pts.imag], axis=1), (e1 * np.conj(e2)).imag

    z, area_z = parallelogram(a)
    w, area_w = parallelogram(b)
    if abs(area_z) < 0.5 or abs(area_w) < 0.5 or np.sign(area_z) != np.sign(area_w):
        return
    try:
        f = FPI(z, w)
    except DegenerateQuadError:
        return  # near-collinear corners
    assert f.is_affine and f.pole is None and f.pole_image is None
    full = np.linalg.lstsq(np.c_[z, np.ones(4)], w, rcond=None)[0]
    affine = RLinear.from_matrix(full[:2].T, full[2])
    p = np.random.default_rng(3).normal(size=(20, 2)) * 10
    assert np.allclose(f(p), affine(p), atol=1e-9)


def hyperbolic_bound(z, w):
    """exp(d_H(tau_Z, tau_W)) of eq. (2) for parallelograms z, w (complex),
    tau = xi / nu of P(nu, xi) with corners {0, nu, nu + xi, xi}."""
    tz = (z[3] - z[0]) / (z[1] - z[0])
    tw = (w[3] - w[0]) / (w[1] - w[0])
    return (abs(tw - np.conj(tz)) + abs(tw - tz)) / (abs(tw - np.conj(tz)) - abs(tw - tz))


@SETTINGS
@given(quads(), quads())
def test_parallelogram_bound_met_with_equality(z, w):
    """K equals the lower bound of eq. (2) between the Möbius parallelograms."""
    w = orient_like(w, z)
    f = FPI(z, w)
    pz = f.m_src._map(z[:, 0] + 1j * z[:, 1])
    pw = f.m_dst._map(w[:, 0] + 1j * w[:, 1])
    assert f.K == pytest.approx(hyperbolic_bound(pz, pw), rel=1e-8)


def algorithm1_pole(z):
    """The fifth point z∞ from the paper's Algorithm 1 (SVD), for comparison."""
    g = np.exp(1j * 2 * np.pi * np.arange(4) / 4)
    gb = np.conj(g)
    M = np.stack([z, np.ones(4), -z * g, -g, -z * gb, -gb], axis=1)
    _, _, vh = np.linalg.svd(M)
    v = vh.conj().T
    u, w = v[:, 4], v[:, 5]  # the two null vectors
    # x = u + t w must satisfy x6 / x4 == x5 / x3: x6 x3 - x5 x4 = 0 (0-based: 5,2,4,3)
    a = w[5] * w[2] - w[3] * w[4]
    b = w[5] * u[2] + u[5] * w[2] - u[4] * w[3] - w[4] * u[3]
    c = u[5] * u[2] - u[4] * u[3]
    best = None
    for t in np.roots([a, b, c]):
        x = u + t * w
        ell = x[5] / x[3]
        if best is None or abs(ell) < abs(best[0]):
            best = (ell, x)
    x = best[1]
    return -x[3] / x[2]  # the root of c z + d


@settings(max_examples=100, deadline=None)
@given(quads(min_scale=0.5, max_scale=50))
def test_pole_agrees_with_algorithm_1(pts):
    z = pts[:, 0] + 1j * pts[:, 1]
    if np.sign(np.sum((np.conj(z) * np.roll(z, -1)).imag)) < 0:
        z = z[::-1]
    m = parallelogram_mobius(z)
    if m.s == 0 or abs(1 / m.s) > 1e6 * scale_of(pts):
        return
    ours = m.q + 1 / m.s
    assert abs(ours - algorithm1_pole(z)) <= 1e-7 * (abs(ours) + scale_of(pts))


def test_continuous_as_quad_approaches_a_parallelogram():
    w = np.array([[0.5, -0.2], [3.1, 0.4], [2.7, 2.2], [-0.3, 1.9]])
    p = np.random.default_rng(4).uniform(-0.5, 1.5, size=(50, 2))
    reference = FPI(UNIT, w)(p)
    for eps in [1e-3, 1e-6, 1e-9, 1e-12, 1e-15]:
        z = UNIT + [[0, 0], [0, 0], [eps, eps], [0, 0]]
        err = np.abs(FPI(z, w)(p) - reference).max()
        assert err <= 20 * eps + 1e-14


def test_same_orientation_quads_both_work():
    screen_ccw = np.array([[0, 0], [0, 10], [10, 10], [10, 0]], float)  # clockwise in (x, y)
    f = FPI(screen_ccw, screen_ccw * 2 + 1)
    assert np.allclose(f(screen_ccw), screen_ccw * 2 + 1)
    assert f.K == pytest.approx(1.0)


@pytest.mark.parametrize(
    "src, message",
    [
        ([[0, 0], [1, 0], [1, 1]], "shape"),
        ([[0, 0], [1, 0], [1, 1], [0, np.nan]], "NaN"),
        ([[0, 0], [1, 0], [1, 1], [0, np.inf]], "inf"),
        ([[0, 0], [1, 0], [1, 0], [0, 1]], "coincide"),
        ([[0, 0], [1, 0], [2, 0], [0, 1]], "collinear"),
        ([[0, 0], [1, 1], [1, 0], [0, 1]], "self-intersecting"),
        ([[0, 0], [0, 0], [0, 0], [0, 0]], "coincident"),
        ("abcd", "numeric"),
    ],
)
def test_degenerate_sources_are_refused(src, message):
    with pytest.raises(DegenerateQuadError, match=message):
        FPI(src, UNIT)
    with pytest.raises(ValueError):  # DegenerateQuadError is a ValueError
        FPI(UNIT, src)


def test_opposite_orientations_are_refused():
    with pytest.raises(DegenerateQuadError, match="opposite orientations"):
        FPI(UNIT, UNIT[::-1])


def test_nonconvex_simple_quads_are_accepted():
    dart = np.array([[0, 0], [4, 2], [0, 4], [1, 2]], float)
    f = FPI(UNIT * 4, dart)
    assert np.allclose(f(UNIT * 4), dart)
    p = np.random.default_rng(5).uniform(0, 4, size=(30, 2))
    assert np.allclose(f.inverse(f(p)), p, atol=1e-9)


def test_pole_maps_to_infinity_and_pole_image_is_not_reached():
    f = FPI(UNIT, [[0, 0], [1, 0], [1.8, 1.6], [0, 1]])
    assert f.pole is not None and f.pole_image is not None
    with np.errstate(all="ignore"):
        at_pole = f(f.pole[None])
    assert not np.all(np.isfinite(at_pole)) or np.abs(at_pole).max() > 1e12
    far = f(np.array([[1e12, 3e11]]))[0]
    assert np.allclose(far, f.pole_image, rtol=1e-6, atol=1e-6)
    assert np.allclose(f.inverse.pole, f.pole_image)


def test_map_points_numpy_backend_and_shapes(sample_fpi):
    p = np.random.default_rng(6).uniform(0, 60, size=(3, 5, 2))
    out = fpiwarp.map_points(sample_fpi, p)
    assert out.shape == (3, 5, 2) and out.dtype == np.float64
    assert np.allclose(out, sample_fpi(p))
    with pytest.raises(ValueError, match="shape"):
        fpiwarp.map_points(sample_fpi, np.zeros((4, 3)))


def test_similar_quads_give_an_affine_map_with_no_pole():
    """Both Möbius maps have poles, but they cancel: f is a similarity."""
    z = np.array([[0, 0], [2, 0], [2.5, 1.5], [0, 1]], float)
    f = FPI(z, 2 * z + [3, 1])
    assert f.K == pytest.approx(1.0)
    assert f.pole is None and f.pole_image is None and f.is_affine
    g = FPI(z, [[0, 0], [2, 0], [2.6, 1.5], [0, 1]])
    assert g.pole is not None and not g.is_affine
