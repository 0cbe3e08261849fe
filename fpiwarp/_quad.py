"""Checking quads and finding the Möbius map that makes one a parallelogram.

``parallelogram_mobius`` is the closed form of ../DESIGN notes §1, which
agrees with the paper's Algorithm 1 (SVD of a 4×6 matrix) but stays
well conditioned as the quad approaches a parallelogram. In coordinates
v = (z - q) / rho centered at the centroid q and scaled by the quad's
radius rho, the map v -> v / (1 - s v) sends the quad to a parallelogram
iff sum_j (-1)^j v_j / (1 - s v_j) = 0. The cubic terms cancel, leaving
C2 s² - C1 s + C0 = 0 with C0 = v1 - v2 + v3 - v4: a parallelogram has
the root s = 0 (no pole). Of the two roots the one whose parallelogram
keeps the quad's orientation is the map (the other is that map followed
by 1/z, which turns the quad inside out).
"""

import cmath
import itertools

import numpy as np

from ._errors import DegenerateQuadError
from ._mobius import Mobius

ALTERNATING = (1.0, -1.0, 1.0, -1.0)
#: |z1 - z2 + z3 - z4| / radius below which a quad counts as a parallelogram
#: (a few rounding errors; the map changes by less than that much).
PARALLELOGRAM_TOL = 1e-14
#: Relative tolerance below which points coincide or are collinear.
DEGENERACY_TOL = 1e-9
#: Largest |x| or |y| of a quad point: products of three coordinates (the
#: Möbius coefficients, squared distances times a coordinate) stay finite.
MAX_COORDINATE = 1e100


def signed_area(z):
    """Shoelace area of the polygon z (complex), > 0 for counter-clockwise
    in (x, y) coordinates (which is clockwise on screen, y down).

    Computed from the points relative to their centroid, so the sign does
    not depend on where in the plane the polygon sits (in absolute
    coordinates the products of large coordinates cancel catastrophically).
    """
    z = [complex(v) for v in z]
    center = sum(v / len(z) for v in z)
    u = [v - center for v in z]
    return 0.5 * sum((a.conjugate() * b).imag for a, b in zip(u, u[1:] + u[:1]))


def _as_float_points(points, name):
    """points as a float64 array, refusing what would be converted silently:
    complex numbers (the imaginary part would be dropped) and text."""
    try:
        raw = np.asarray(points)
    except (TypeError, ValueError) as exc:  # ragged lists
        raise DegenerateQuadError(f"{name} must be four numeric (x, y) points: {exc}") from None
    values = raw.ravel() if raw.dtype == object else ()
    if raw.dtype.kind == "c" or any(isinstance(v, (complex, np.complexfloating)) for v in values):
        raise DegenerateQuadError(f"{name} must be real (x, y) points, got complex numbers")
    if raw.dtype.kind in "USa" or any(isinstance(v, (str, bytes)) for v in values):
        raise DegenerateQuadError(f"{name} must be four numeric (x, y) points, got text")
    try:
        return np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise DegenerateQuadError(f"{name} must be four numeric (x, y) points: {exc}") from None


def check_quad(points, name="quad"):
    """Validate four (x, y) points; return them as complex128 of shape (4,).

    Raises DegenerateQuadError naming what is wrong: wrong shape or dtype
    (complex or text included), NaN or inf, a coordinate beyond
    ±MAX_COORDINATE, coincident points, three collinear points, zero area,
    or self-intersecting (bow-tie) edges. Non-convex simple quads are fine.
    Every test is made on the points relative to their centroid, divided
    by the quad's radius, so it does not change when the quad is moved or
    scaled.
    """
    arr = _as_float_points(points, name)
    if arr.shape != (4, 2):
        raise DegenerateQuadError(f"{name} must have shape (4, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise DegenerateQuadError(f"{name} contains NaN or inf: {arr.tolist()}")
    big = np.flatnonzero(np.abs(arr).max(axis=1) > MAX_COORDINATE)
    if big.size:
        k = int(big[0])
        raise DegenerateQuadError(
            f"{name} point {k} {arr[k].tolist()} lies beyond ±{MAX_COORDINATE:g}, the largest "
            "coordinate whose products of three stay finite in float64"
        )
    z = arr[:, 0] + 1j * arr[:, 1]
    u, scale = _normalized(z)
    if scale == 0:
        raise DegenerateQuadError(f"{name} has all four points coincident")
    for i, j in itertools.combinations(range(4), 2):
        if abs(u[i] - u[j]) <= DEGENERACY_TOL:
            raise DegenerateQuadError(f"{name} points {i} and {j} coincide: {arr[i].tolist()}")
    for tri in itertools.combinations(range(4), 3):
        a, b, c = (u[k] for k in tri)
        if abs(_cross(c - a, b - a)) <= DEGENERACY_TOL:
            raise DegenerateQuadError(f"{name} points {tri} are collinear")
    for e, f in ((0, 2), (1, 3)):
        if _segments_cross(u[e], u[(e + 1) % 4], u[f], u[(f + 1) % 4]):
            raise DegenerateQuadError(
                f"{name} is self-intersecting (bow-tie): edge {e}-{(e + 1) % 4} "
                f"crosses edge {f}-{(f + 1) % 4}"
            )
    if abs(signed_area(u)) <= DEGENERACY_TOL:
        raise DegenerateQuadError(f"{name} has zero area")
    return z


def _normalized(z):
    """(u, scale): the points relative to their centroid divided by the
    largest distance from it (so |u| <= 1), and that distance."""
    zs = [complex(v) for v in z]
    center = sum(v / 4 for v in zs)
    d = [v - center for v in zs]
    scale = max(abs(v) for v in d)
    if scale == 0:
        return d, 0.0
    return [v / scale for v in d], scale


def check_quad_pair(src, dst, names=("src", "dst")):
    """Validate a source and a target quad of the same orientation.

    Returns (z, w, clockwise): the quads as complex128 (4,) and whether
    they run clockwise in (x, y), where the closed forms (written for
    counter-clockwise quads) solve the mirrored problem. ``names`` name
    the two quads in messages.
    """
    z = check_quad(src, names[0])
    w = check_quad(dst, names[1])
    clockwise = signed_area(z) < 0
    if clockwise != (signed_area(w) < 0):
        raise DegenerateQuadError(
            f"{names[0]} and {names[1]} have opposite orientations (one is clockwise, the other "
            "counter-clockwise): no orientation-preserving map joins them"
        )
    return z, w, clockwise


def _cross(a, b):
    return (a.conjugate() * b).imag


def _segments_cross(a, b, c, d):
    """Do the segments ab and cd intersect (properly)?"""
    d1, d2 = _cross(b - a, c - a), _cross(b - a, d - a)
    d3, d4 = _cross(d - c, a - c), _cross(d - c, b - c)
    return d1 * d2 < 0 and d3 * d4 < 0


def parallelogram_mobius(z):
    """The Möbius map sending the quad z (complex, shape (4,), validated)
    to the corners of a parallelogram of unit radius, keeping orientation."""
    z = [complex(v) for v in z]
    q = sum(z) / 4
    rho = max(abs(v - q) for v in z)
    v = [(p - q) / rho for p in z]
    e = ALTERNATING
    s1 = sum(v)
    sum_e2 = sum(ej * vj * vj for ej, vj in zip(e, v))
    c0 = sum(ej * vj for ej, vj in zip(e, v))
    if abs(c0) <= PARALLELOGRAM_TOL:
        # a parallelogram up to rounding: the affine map, with no pole
        return Mobius.centered(q, 0, 1 / rho, 0)
    s2 = 0.5 * (s1 * s1 - sum(vj * vj for vj in v))
    c1 = s1 * c0 - sum_e2
    c2 = s2 * c0 - s1 * sum_e2 + sum(ej * vj**3 for ej, vj in zip(e, v))
    root = cmath.sqrt(c1 * c1 - 4 * c2 * c0)
    big = c1 + root if abs(c1 + root) >= abs(c1 - root) else c1 - root
    candidates = []
    if big != 0:
        candidates.append(2 * c0 / big)  # the small root, 0 for a parallelogram
    if c2 != 0:
        candidates.append(big / (2 * c2))
    orientation = signed_area(v) > 0
    best = None
    for s in candidates:
        dens = [1 - s * vj for vj in v]
        if any(abs(d) <= 1e-12 for d in dens):
            continue
        p = [vj / d for vj, d in zip(v, dens)]
        if all(cmath.isfinite(pj) for pj in p) and (signed_area(p) > 0) == orientation:
            if best is None or abs(s) < abs(best):
                best = s
    if best is None:
        raise DegenerateQuadError("no orientation-preserving Möbius map to a parallelogram")
    return Mobius.centered(q, best / rho, 1 / rho, 0)
