"""A seeded fuzz of quad pairs for the FPI: tolerances and a classifier.

Used by ``test_quad_fuzz.py`` (a few thousand pairs, every CI run) and as
a script to count outcomes on a larger run, for instance on the code of
another checkout (``PYTHONPATH=that/checkout python tests/support/quad_fuzz.py``)::

    python tests/support/quad_fuzz.py --pairs 100000 --seed 1

The pairs come from :mod:`fpiwarp.testing` (shared with the benchmarks).
Every pair is classified as refused (by error class and the first words of
its message) or accepted; an accepted pair is checked for K >= 1, for its
corners (|f(src) - dst| relative to the size of dst), for its inverse
corners and for the round trip f⁻¹(f(p)) of points around src.
"""

import argparse
import collections
import json
import sys

import numpy as np

import fpiwarp
from fpiwarp.testing import broad_pairs, mirrored_pairs, unit_pairs

#: Accepted maps must meet their corners and round-trip to this fraction of
#: the quad's size, plus what rounding the inputs' coordinates forces
#: (REPRESENTATION_ULPS units in the last place of the largest coordinate).
REL_TOL = 1e-9
REPRESENTATION_ULPS = 64
EPS = np.finfo(np.float64).eps


def size_of(pts):
    pts = np.asarray(pts, dtype=np.float64)
    return float(np.max(np.hypot(*(pts - pts.mean(axis=0)).T)))


def allowed_error(pts):
    """The error an accepted map may make at points of quad ``pts``."""
    pts = np.asarray(pts, dtype=np.float64)
    return REL_TOL * size_of(pts) + REPRESENTATION_ULPS * EPS * float(np.abs(pts).max())


def allowed_round_trip_error(f, z, w):
    """The error a round trip f⁻¹(f(p)) may make around quad ``z``: that of a
    point of z, plus the rounding of the intermediate f(p) to float64 in the
    target's coordinates, pulled back by f⁻¹ (which stretches by up to
    K size(z) / size(w))."""
    pull_back = f.K * size_of(z) / size_of(w)
    return allowed_error(z) + pull_back * REPRESENTATION_ULPS * EPS * float(np.abs(w).max())


def orientation(pts):
    """+1 counter-clockwise, -1 clockwise in (x, y), from coordinates relative to the centroid."""
    u = np.asarray(pts, dtype=np.float64) - np.mean(pts, axis=0)
    x, y = u[:, 0], u[:, 1]
    return np.sign(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def round_trip_points(z, rng, n=32):
    """Points in the quad's bounding box grown to three times its size."""
    lo, hi = z.min(axis=0), z.max(axis=0)
    pad = hi - lo
    return rng.uniform(lo - pad, hi + pad, size=(n, 2))


def measure(f, z, w, rng):
    """Errors of an accepted FPI, each divided by what is allowed (> 1: a failure)."""
    corner = np.max(np.hypot(*(f(z) - w).T)) / allowed_error(w)
    inv_corner = np.max(np.hypot(*(f.inverse(w) - z).T)) / allowed_error(z)
    p = round_trip_points(z, rng)
    pole = f.pole
    if pole is not None:  # near the pole f(p) is huge and loses the digits of p
        p = p[np.hypot(*(p - pole).T) > 0.05 * size_of(z)]
    with np.errstate(all="ignore"):
        back = f.inverse(f(p))
    trip = np.max(np.hypot(*(back - p).T), initial=0.0) / allowed_round_trip_error(f, z, w)
    return corner, inv_corner, trip


#: What an ill-conditioned pair's message says failed (counted separately).
ILL_CONDITIONED_REASONS = (
    "exceeds the limit",
    "is not >= 1",
    "parallelograms is singular",
    "misses the dst corners",
    "inverse misses the src corners",
    "round trip",
)


def classify(z, w, rng):
    """('refused', reason) or ('accepted', problem or 'ok'), plus the map's K (or None)."""
    try:
        f = fpiwarp.FPI(z, w)
    except Exception as exc:  # noqa: BLE001 - counting every class is the point
        message = str(exc)
        words = " ".join(message.split(":")[0].split()[1:6])  # the problem, without the quad's name
        for phrase in ILL_CONDITIONED_REASONS:
            if phrase in message:
                words = phrase
                break
        return ("refused", f"{type(exc).__name__}: {words}"), None
    if not f.K >= 1:
        return ("accepted", "K < 1"), f.K
    corner, inv_corner, trip = measure(f, z, w, rng)
    if corner > 1:
        return ("accepted", "misses its corners"), f.K
    if inv_corner > 1:
        return ("accepted", "inverse misses the corners"), f.K
    if not trip <= 1:
        return ("accepted", "round trip fails"), f.K
    return ("accepted", "ok"), f.K


def tally(pairs, seed=0):
    rng = np.random.default_rng(seed)
    counts = collections.Counter()
    for z, w in pairs:
        (verdict, reason), _ = classify(z, w, rng)
        counts[f"{verdict}: {reason}"] += 1
    return dict(sorted(counts.items()))


def report(n_broad, seed):
    rng = np.random.default_rng(seed)
    out = {}
    for offset in (0.0, 1e8, 3e8, 1e9):
        out[f"300 valid unit pairs at offset {offset:g}"] = tally(unit_pairs(rng, 300, offset))
        out[f"300 mirrored unit pairs at offset {offset:g}"] = tally(mirrored_pairs(rng, 300, offset))
    out[f"{n_broad} broad pairs"] = tally(broad_pairs(rng, n_broad))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=20000)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    json.dump(report(args.pairs, args.seed), sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
