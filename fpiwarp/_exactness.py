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

from ._errors import DegenerateQuadError

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


class IllConditionedPairError(DegenerateQuadError):
    """A quad pair valid on paper whose map float64 cannot build exactly
    (thin quads, large distortion): the message names the measured error
    and the limit."""


def radius(z):
    """Largest distance of the points z (complex) from their centroid."""
    return float(np.max(np.abs(z - z.mean())))


def allowed_error(z):
    """The error a map may make at points of quad z: EXACT_RTOL of its
    radius plus the rounding of its largest coordinate."""
    return EXACT_RTOL * radius(z) + REPRESENTATION_ULPS * EPS * float(np.max(np.abs(np.concatenate([z.real, z.imag]))))


def _probe_points(z, n=5):
    """An n × n grid over the source's bounding box grown to three times its size."""
    lo = complex(z.real.min(), z.imag.min())
    hi = complex(z.real.max(), z.imag.max())
    pad = hi - lo
    xs = np.linspace(lo.real - pad.real, hi.real + pad.real, n)
    ys = np.linspace(lo.imag - pad.imag, hi.imag + pad.imag, n)
    return (xs[None, :] + 1j * ys[:, None]).ravel()


def _inside_box(c, p):
    """Is c inside the bounding box of the points p?"""
    return p.real.min() <= c.real <= p.real.max() and p.imag.min() <= c.imag <= p.imag.max()


def _refuse(what, err, allowed, K):
    """Raise IllConditionedPairError; err and allowed are relative to the quad's radius."""
    raise IllConditionedPairError(
        f"src -> dst is too ill-conditioned for float64{'' if K is None else f' (K = {K:.3g})'}: {what} by "
        f"{err:.2g} of the quad's size, beyond the limit {allowed:.2g} (thin quads "
        "or a large distortion lose digits); use fatter quads or a smaller distortion"
    )


def check_corners(f, z, w):
    """Refuse the map f (any Transform) if it misses w's corners."""
    err = float(np.max(np.abs(f._map(z) - w)))
    if not err <= allowed_error(w):
        _refuse("the map misses the dst corners", err / radius(w), allowed_error(w) / radius(w), getattr(f, "K", None))


def check_exact(f, z, w):
    """Refuse the FPI f from quad z to quad w (complex (4,)) unless its
    corners, its inverse's corners and round trips around z are within
    the promised accuracy and K is in 1..MAX_K."""
    if not f.K >= 1:
        raise IllConditionedPairError(
            f"src -> dst is too ill-conditioned for float64: the computed distortion K = {f.K:.6g} "
            "is not >= 1 (the map would reverse orientation); use fatter quads"
        )
    if f.K > MAX_K:
        raise IllConditionedPairError(
            f"src -> dst is too ill-conditioned for float64: its distortion K = {f.K:.3g} exceeds "
            f"the limit {MAX_K:g}, beyond which round trips miss by more than {EXACT_RTOL:g} of the "
            "quad's size; use fatter quads or a smaller distortion"
        )
    check_corners(f, z, w)
    inv = f.inverse
    err = float(np.max(np.abs(inv._map(w) - z)))
    if not err <= allowed_error(z):
        _refuse("the inverse misses the src corners", err / radius(z), allowed_error(z) / radius(z), f.K)
    p = _probe_points(z)
    pole = f.pole
    if pole is not None:
        pole = complex(pole[0], pole[1])
        p = p[np.abs(p - pole) > POLE_MARGIN * radius(z)]
        if _inside_box(pole, p):  # round trips lose most digits near the pole: probe there too
            circle = np.exp(2j * np.pi * np.arange(8) / 8)
            rings = [pole + r * POLE_MARGIN * radius(z) * circle for r in (1.05, 2.0)]
            p = np.concatenate([p, *rings])
    with np.errstate(all="ignore"):
        back = inv._map(f._map(p))
    err = float(np.max(np.abs(back - p), initial=0.0))
    w_max = float(np.max(np.abs(np.concatenate([w.real, w.imag]))))
    pull_back = f.K * radius(z) / radius(w)
    allowed = allowed_error(z) + pull_back * REPRESENTATION_ULPS * EPS * w_max
    if not err * ROUND_TRIP_MARGIN <= allowed:
        _refuse("the inverse's round trip f⁻¹(f(p)) misses p", err / radius(z), allowed / ROUND_TRIP_MARGIN / radius(z), f.K)
