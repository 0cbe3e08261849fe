"""A seeded fuzz of quad pairs for the FPI: generators and a classifier.

Used by ``test_quad_fuzz.py`` (a few thousand pairs, every CI run) and as
a script to count outcomes on a larger run, for instance on the code of
another checkout (``PYTHONPATH=that/checkout python tests/quad_fuzz.py``)::

    python tests/quad_fuzz.py --pairs 100000 --seed 1

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


def random_quad(rng, convex=True):
    """A random simple quad of radius about 1 around the origin, counter-clockwise in (x, y)."""
    gaps = rng.uniform(0.35, 1.0, 4)
    angles = rng.uniform(0, 2 * np.pi) + np.cumsum(gaps / gaps.sum() * 2 * np.pi)
    radii = rng.uniform(0.4, 1.0, 4)
    if not convex:
        radii[rng.integers(4)] *= 0.15
    return radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def squashed(pts, rng, aspect):
    """pts stretched by ``aspect`` along a random direction (aspect < 1 squashes)."""
    t = rng.uniform(0, np.pi)
    c, s = np.cos(t), np.sin(t)
    rot = np.array([[c, -s], [s, c]])
    return pts @ rot @ np.diag([1.0, aspect]) @ rot.T


def mirrored(pts):
    return pts * np.array([-1.0, 1.0])


def unit_pairs(rng, n, offset):
    """n valid pairs of unit-size quads of the same orientation, both moved by ``offset``."""
    out = []
    for _ in range(n):
        z, w = random_quad(rng), random_quad(rng)
        if rng.random() < 0.5:
            z, w = mirrored(z), mirrored(w)  # clockwise pairs too
        out.append((z + offset, w + offset))
    return out


def mirrored_pairs(rng, n, offset):
    """n pairs of opposite orientation (no orientation-preserving map joins them)."""
    return [(z, mirrored(w) + offset) for z, w in ((z + offset, w) for z, w in unit_pairs(rng, n, 0.0))]


def broad_pairs(rng, n):
    """n pairs spread over scales 1e-6..1e9, offsets up to 1e9, aspect ratios
    up to 1e9 (thin quads) and near-degenerate corners, some mirrored."""
    out = []
    for _ in range(n):
        quads = []
        for _ in range(2):
            q = random_quad(rng, convex=rng.random() < 0.8)
            kind = rng.random()
            if kind < 0.4:
                q = squashed(q, rng, 10.0 ** -rng.uniform(0, 9))
            elif kind < 0.5:  # one corner pulled close to the line of its neighbours
                k = rng.integers(4)
                a, b = q[(k - 1) % 4], q[(k + 1) % 4]
                q[k] = 0.5 * (a + b) + (q[k] - 0.5 * (a + b)) * 10.0 ** -rng.uniform(0, 9)
            quads.append(q)
        z, w = quads
        if rng.random() < 0.05:
            w = mirrored(w)
        scale = 10.0 ** rng.uniform(-6, 9)
        offset = rng.choice([0.0, 1.0]) * 10.0 ** rng.uniform(0, 9) * rng.choice([-1, 1], size=2)
        out.append((z * scale + offset, w * scale + offset * rng.uniform(0.5, 2)))
    return out


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
