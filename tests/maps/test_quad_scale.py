"""Quads too small for float64 (subnormal coordinates) are refused naming the user's quad (issue 25, item 8)."""

import numpy as np
import pytest

import fpiwarp
from fpiwarp.maps.quad import MIN_RADIUS

SRC = np.array([[0, 0], [63, 0], [63, 47], [0, 47]], float)
DST = np.array([[4, 2], [60, 1], [62, 45], [1, 44]], float)


@pytest.mark.parametrize("scale", [1e-310 / 63, 1e-320, 5e-324 * 8, 1e-300, 1e-295])
@pytest.mark.parametrize("which", ["src", "dst"])
def test_a_subnormal_scale_quad_is_refused_naming_it(scale, which):
    src, dst = (SRC * scale, DST) if which == "src" else (SRC, DST * scale)
    with pytest.raises(fpiwarp.DegenerateQuadError) as info:
        fpiwarp.FPI(src, dst)
    text = str(info.value)
    assert text.startswith(which) and "alpha" not in text and "\n" not in text and len(text) < 300


@pytest.mark.parametrize("scale", [1e-280, 1e-200, 1e-100, 1.0, 1e90])
def test_quads_above_the_limit_map_exactly(scale):
    f = fpiwarp.FPI(SRC * scale, DST * scale)
    np.testing.assert_allclose(f(SRC * scale) / scale, DST, atol=1e-10)
    assert np.isfinite(f.K)


def test_the_limit_is_the_radius_not_the_position():
    """A quad of radius 1e-280 far from the origin would be coincident points: refused as such, not by the limit."""
    assert MIN_RADIUS < 1e-280
    with pytest.raises(fpiwarp.DegenerateQuadError, match="coincide|coincident"):
        fpiwarp.FPI(SRC * 1e-280 + 1e6, DST)


@pytest.mark.parametrize("make", [lambda s: fpiwarp.Mobius.from_points(s[:3], DST[:3]) if hasattr(
    fpiwarp.Mobius, "from_points") else fpiwarp.FPI(s, DST), lambda s: fpiwarp.ConstrainedFPI(s, DST, edges=(0, 2))])
def test_other_quad_maps_refuse_it_too(make):
    with pytest.raises(fpiwarp.FpiwarpError) as info:
        make(SRC * 1e-312)
    assert "alpha" not in str(info.value)
