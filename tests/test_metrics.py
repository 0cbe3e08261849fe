"""Distortion metrics (paper §5.1) and the FPI curve (paper Fig. 6)."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from support.strategies import quads

import fpiwarp
from fpiwarp import FPI, ConstrainedFPI, RLinear
from fpiwarp.curves import curve_map, fpi_curve
from fpiwarp.metrics import (
    area_distortion,
    conformal_dilation,
    conformal_distortion,
    grid,
    jacobian_determinant,
    summarize,
)

UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def test_fpi_has_constant_dilation():
    f = FPI(UNIT, [[0, 0], [2, 0], [2.5, 1.2], [0, 1]])
    s = summarize(f, grid(UNIT, 30))
    assert s.max_dilation == pytest.approx(f.dilation, rel=1e-12)
    assert s.mean_dilation == pytest.approx(f.dilation, rel=1e-12)
    assert s.std_dilation < 1e-12
    assert s.max_distortion == pytest.approx(f.K, rel=1e-12)
    d = conformal_dilation(f, grid(UNIT, 5))
    k = conformal_distortion(f, grid(UNIT, 5))
    assert np.allclose(d, (k - 1) / (k + 1))


def test_area_distortion_of_a_scaling():
    s = 1.7
    f = RLinear(s, 0, 3 - 1j)
    pts = grid([[0, 0], [4, 3]], 6)
    assert area_distortion(f, pts) == pytest.approx(s**2 + 1 / s**2)
    assert np.allclose(jacobian_determinant(f, pts), s**2)


def test_fold_over_gives_infinite_distortion():
    mirror = RLinear(0.2, 1.0, 0)  # orientation reversing: |l2| > |l1|
    pts = grid(UNIT, 4)
    assert area_distortion(mirror, pts) == np.inf
    assert np.all(np.isinf(conformal_distortion(mirror, pts)))
    assert np.all(conformal_dilation(mirror, pts) > 1)
    assert summarize(mirror, pts).area_distortion == np.inf


def test_finite_differences_for_plain_callables_match_the_analytic_derivatives():
    src = UNIT * 10
    dst = src.copy()
    dst[[1, 2]] += [[1.5, 0.5], [2.0, 1.0]]
    f = ConstrainedFPI(src, dst, edges=(3, 1))
    pts = grid(src * 0.9 + 0.5, 9)
    a, b = summarize(f, pts), summarize(lambda p: f(p), pts)
    for x, y in zip(vars(a).values(), vars(b).values()):
        assert x == pytest.approx(y, rel=1e-6, abs=1e-8)
    with pytest.raises(TypeError, match="Transform or a callable"):
        conformal_dilation(42, pts)


def test_grid_spans_the_quad():
    q = np.array([[0, 0], [4, 1], [5, 5], [-1, 3]], float)
    g = grid(q, 7)
    assert g.shape == (7, 7, 2)
    assert np.allclose([g[0, 0], g[0, -1], g[-1, -1], g[-1, 0]], q)
    with pytest.raises(ValueError, match="corners"):
        grid(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="n >= 2"):
        grid(q, 1)


# --- FPI curve ------------------------------------------------------------------


def _segments_cross(a, b, c, d):
    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    d1, d2 = cross(b - a, c - a), cross(b - a, d - a)
    d3, d4 = cross(d - c, a - c), cross(d - c, b - c)
    return (d1 * d2 < 0) & (d3 * d4 < 0)


def self_intersects(curve):
    n = len(curve)
    a, b = curve, np.roll(curve, -1, axis=0)
    for i in range(n):
        j = np.arange(i + 2, n)
        if i == 0:
            j = j[j != n - 1]  # neighbours share a point
        if j.size and np.any(_segments_cross(a[i], b[i], a[j], b[j])):
            return True
    return False


@settings(max_examples=30, deadline=None)
@given(quads(min_scale=1e-1, max_scale=1e3))
def test_fpi_curve_passes_through_the_anchors_without_crossing_itself(anchors):
    f = curve_map(anchors)
    # near the pole the curve runs out towards infinity: sampling cannot show it
    assume(f.pole is None or abs(np.hypot(*f.pole) - 1) >= 0.05)
    c = fpi_curve(anchors, n=256)
    assert c.shape == (256, 2)
    assert np.array_equal(c[::64], np.asarray(anchors, dtype=float))
    assert np.all(np.isfinite(c))
    assert not self_intersects(c)


def test_fpi_curve_of_a_square_is_its_circumcircle():
    sq = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]], float) * 3 + [5, 5]
    c = fpi_curve(sq, n=40)
    assert np.allclose(np.linalg.norm(c - [5, 5], axis=1), 3)


def test_fpi_curve_refuses_bad_input():
    with pytest.raises(ValueError, match="at least 4"):
        fpi_curve(UNIT, n=3)
    with pytest.raises(fpiwarp.DegenerateQuadError):
        fpi_curve([[0, 0], [1, 1], [1, 0], [0, 1]])
