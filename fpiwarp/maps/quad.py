"""Checking quads and finding the Möbius map that makes one a parallelogram.

``parallelogram_mobius`` is a closed form (derived below), which
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

from ..errors import DegenerateQuadError, IllConditionedPairError
from .mobius import Mobius

# --- Checking quads and finding the Möbius map that makes one a parallelogram.
ALTERNATING = (1.0, -1.0, 1.0, -1.0)
#: |z1 - z2 + z3 - z4| / radius below which a quad counts as a parallelogram
#: (a few rounding errors; the map changes by less than that much).
PARALLELOGRAM_TOL = 1e-14
#: Relative tolerance below which points coincide or are collinear.
DEGENERACY_TOL = 1e-9
#: Largest |x| or |y| of a quad point: products of three coordinates (the
#: Möbius coefficients, squared distances times a coordinate) stay finite.
MAX_COORDINATE = 1e100
#: Smallest quad radius (largest distance of a point from the centroid):
#: below it the coordinates' differences approach float64's subnormal
#: numbers (below 2.2e-308), whose reciprocals overflow to inf, and the
#: map's coefficients cannot be built. Quads of 1e-300 still map to 1e-14.
MIN_RADIUS = 1e-290


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
    if scale < MIN_RADIUS:
        raise DegenerateQuadError(
            f"{name} spans only {scale:.3g} (points {_short_points(arr)}): below {MIN_RADIUS:g}, where float64 "
            "reaches its subnormal numbers and the map cannot be built; give the points in a larger unit"
        )
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


def _short_points(arr):
    """The four points for a message, 3 significant digits each."""
    return "[" + ", ".join(f"[{x:.3g}, {y:.3g}]" for x, y in arr) + "]"


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


# --- Refusing maps that float64 cannot build exactly (ill-conditioned quad pairs).
#: Promised accuracy: corners, inverse corners and round trips within this
#: fraction of the quad's radius (plus the rounding of the coordinates).
EXACT_RTOL = 1e-9
#: Largest distortion accepted: beyond it probes no longer vouch for every
#: point (measured: 1 of 194 fuzzed maps with K > 1e7 passed the probes and
#: still missed a round trip, none of 13,334 with K <= 1e6).
MAX_K = 1e6
#: Units in the last place of the largest coordinate that rounding may cost.
REPRESENTATION_ULPS = 64
#: Round-trip errors are rounding noise that varies from point to point:
#: the probes must stay this many times below the limit (measured on
#: 20,000 fuzzed pairs: with 8, 1 accepted map still missed a round trip
#: at 32 random points by 1.06x the limit; with 16, none).
ROUND_TRIP_MARGIN = 16
#: Round-trip probes closer than this fraction of the radius to the pole are skipped.
POLE_MARGIN = 0.05
EPS = float(np.finfo(np.float64).eps)


#: Probe grid in units of the source's bounding box, from one box size
#: before it to one beyond it (a 5 × 5 grid over three times the box).
_GRID = np.linspace(-1.0, 2.0, 5)
_CIRCLE = np.exp(2j * np.pi * np.arange(8) / 8)


def _extent(z):
    """(radius, largest |coordinate|) of the quad z (complex (4,)), in plain
    Python: four points are faster there than in numpy."""
    zs = [complex(v) for v in z]
    center = sum(zs) / len(zs)
    return max(abs(v - center) for v in zs), max(max(abs(v.real), abs(v.imag)) for v in zs)


def radius(z):
    """Largest distance of the points z (complex) from their centroid."""
    return _extent(z)[0]


def allowed_error(z):
    """The error a map may make at points of quad z: EXACT_RTOL of its
    radius plus the rounding of its largest coordinate."""
    size, largest = _extent(z)
    return EXACT_RTOL * size + REPRESENTATION_ULPS * EPS * largest


def _probe_points(z, pole, size):
    """A 5 × 5 grid over the source's bounding box grown to three times its
    size, without points within POLE_MARGIN of the pole, plus two rings
    around the pole where it lies in that box (round trips lose most
    digits near the pole)."""
    lo_x, lo_y = float(z.real.min()), float(z.imag.min())
    xs = lo_x + (float(z.real.max()) - lo_x) * _GRID
    ys = lo_y + (float(z.imag.max()) - lo_y) * _GRID
    p = (xs[None, :] + 1j * ys[:, None]).ravel()
    if pole is None:
        return p
    p = p[np.abs(p - pole) > POLE_MARGIN * size]
    if xs[0] <= pole.real <= xs[-1] and ys[0] <= pole.imag <= ys[-1]:
        p = np.concatenate([p, pole + 1.05 * POLE_MARGIN * size * _CIRCLE, pole + 2 * POLE_MARGIN * size * _CIRCLE])
    return p


def _refuse(what, err, allowed, K):
    """Raise IllConditionedPairError; err and allowed are relative to the quad's radius."""
    raise IllConditionedPairError(
        f"src -> dst is too ill-conditioned for float64{'' if K is None else f' (K = {K:.3g})'}: {what} by "
        f"{err:.2g} of the quad's size, beyond the limit {allowed:.2g} (thin quads "
        "or a large distortion lose digits); use fatter quads or a smaller distortion"
    )


def check_corners(f, z, w):
    """Refuse the map f (any Transform) if it misses w's corners."""
    err = float(np.max(np.abs(f.map_complex(z) - w)))
    if not err <= allowed_error(w):
        _refuse("the map misses the dst corners", err / radius(w), allowed_error(w) / radius(w), getattr(f, "K", None))


def check_exact(f, z, w):
    """Refuse the FPI f from quad z to quad w (complex (4,)) unless its
    corners, its inverse's corners and round trips around z are within
    the promised accuracy and K is in 1..MAX_K."""
    K = f.K
    if not K >= 1:
        raise IllConditionedPairError(
            f"src -> dst is too ill-conditioned for float64: the computed distortion K = {K:.6g} "
            "is not >= 1 (the map would reverse orientation); use fatter quads"
        )
    if K > MAX_K:
        raise IllConditionedPairError(
            f"src -> dst is too ill-conditioned for float64: its distortion K = {K:.3g} exceeds "
            f"the limit {MAX_K:g}, beyond which round trips miss by more than {EXACT_RTOL:g} of the "
            "quad's size; use fatter quads or a smaller distortion"
        )
    inv = f.inverse
    (rz, largest_z), (rw, largest_w) = _extent(z), _extent(w)
    allowed_z = EXACT_RTOL * rz + REPRESENTATION_ULPS * EPS * largest_z
    allowed_w = EXACT_RTOL * rw + REPRESENTATION_ULPS * EPS * largest_w
    pole = inv.pole_image  # the pole of f
    p = _probe_points(z, None if pole is None else complex(pole[0], pole[1]), rz)
    with np.errstate(all="ignore"):
        forward = f.map_complex(np.concatenate([z, p]))
        back = inv.map_complex(np.concatenate([w, forward[4:]]))
    err = float(np.max(np.abs(forward[:4] - w)))
    if not err <= allowed_w:
        _refuse("the map misses the dst corners", err / rw, allowed_w / rw, K)
    err = float(np.max(np.abs(back[:4] - z)))
    if not err <= allowed_z:
        _refuse("the inverse misses the src corners", err / rz, allowed_z / rz, K)
    err = float(np.max(np.abs(back[4:] - p), initial=0.0))
    allowed = allowed_z + K * rz / rw * REPRESENTATION_ULPS * EPS * largest_w
    if not err * ROUND_TRIP_MARGIN <= allowed:
        _refuse("the inverse's round trip f⁻¹(f(p)) misses p", err / rz, allowed / ROUND_TRIP_MARGIN / rz, K)
