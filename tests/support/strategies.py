"""Hypothesis strategies for quads, shared by the math tests."""

import numpy as np
from hypothesis import reject
from hypothesis import strategies as st

from fpiwarp.maps.quad import check_quad, signed_area


@st.composite
def quads(draw, min_scale=1e-2, max_scale=1e4, convex=None):
    """A valid simple quad (4, 2): random angles around a center, radii and
    scale, optionally made non-convex by pulling one vertex inward."""
    scale = draw(st.floats(min_scale, max_scale))
    center = np.array(draw(st.tuples(st.floats(-3, 3), st.floats(-3, 3)))) * scale
    base = draw(st.floats(0, 2 * np.pi))
    gaps = np.array(draw(st.lists(st.floats(0.35, 1.0), min_size=4, max_size=4)))
    angles = base + np.cumsum(gaps / gaps.sum() * 2 * np.pi)
    radii = np.array(draw(st.lists(st.floats(0.4, 1.0), min_size=4, max_size=4)))
    if convex is False:
        radii[draw(st.integers(0, 3))] *= 0.15
    pts = center + scale * radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    if draw(st.booleans()):
        pts = pts[::-1].copy()  # clockwise
    try:
        z = check_quad(pts)
    except ValueError:
        reject()
    if abs(signed_area(z)) < 1e-3 * scale**2:
        reject()
    return pts


def same_orientation(p, q):
    zp = p[:, 0] + 1j * p[:, 1]
    zq = q[:, 0] + 1j * q[:, 1]
    return np.sign(signed_area(zp)) == np.sign(signed_area(zq))


def orient_like(q, p):
    """q reordered (reversed, keeping vertex 0) to the orientation of p."""
    return q if same_orientation(p, q) else q[[0, 3, 2, 1]]
