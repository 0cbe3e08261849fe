"""Refusing maps that float64 cannot build exactly (ill-conditioned quad pairs).

The closed-form FPI is exact in exact arithmetic, but in float64 a pair of
thin quads, or a large distortion K between them, loses digits: the
Möbius maps no longer send the quads exactly onto parallelograms, so the
map misses its corners, and its inverse stops undoing it. Measured on
20,000 fuzzed pairs (``tests/quad_fuzz.py``) the loss has no single
threshold in K or in the quads' thinness (area / radius²): K ≈ 30 with
thin quads can fail while K = 1e4 with fat ones holds. So each map is
checked where it is built, at a few points, against the limit it
promises: corners hit, inverse corners hit, and round trips f⁻¹(f(p)) of
points around the source, each to EXACT_RTOL of the quad's radius plus
the rounding of the coordinates themselves (REPRESENTATION_ULPS units in
the last place of the largest coordinate; for a round trip also the
rounding of f(p), pulled back by f⁻¹, which stretches by up to
K · radius(src) / radius(dst)).

The check costs three evaluations of a few dozen points, and outputs are
unchanged: a map is either refused or built exactly as before.
"""

import numpy as np

from ._errors import IllConditionedPairError

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
