"""Host math figures for the core: solve time, map throughput, accuracy.

Run: python3 -m benchmarks.host_math
Prints the time to solve one FPI, numpy map throughput on 1M points, and
the worst float64 errors (interpolation, inverse round trip, Jacobian
against central finite differences) over random quads at scales 1e-2..1e4.
"""


import numpy as np

import fpiwarp
from fpiwarp import testing

from .common import best_time, machine_facts, machine_line


def random_quad(rng, scale):
    """A convex quad of radius about ``scale`` (:func:`fpiwarp.testing.random_quad`)
    centered up to 2 ``scale`` from the origin."""
    return scale * (rng.uniform(-2, 2, 2) + testing.random_quad(rng))


def finite_difference_jacobian(f, p, h):
    """Fourth-order central differences (truncation error ~ h**4)."""
    cols = []
    for e in ([h, 0.0], [0.0, h]):
        e = np.array(e)
        cols.append((8 * (f(p + e) - f(p - e)) - (f(p + 2 * e) - f(p - 2 * e))) / (12 * h))
    return np.stack(cols, axis=-1)


def accuracy(rng, trials=300):
    worst = {"interpolation": 0.0, "round trip": 0.0, "jacobian vs FD": 0.0, "K spread": 0.0}
    for _ in range(trials):
        scale = 10 ** rng.uniform(-2, 4)
        z, w = random_quad(rng, scale), random_quad(rng, scale)
        za = np.sum(z[:, 0] * np.roll(z[:, 1], -1) - z[:, 1] * np.roll(z[:, 0], -1))
        wa = np.sum(w[:, 0] * np.roll(w[:, 1], -1) - w[:, 1] * np.roll(w[:, 0], -1))
        if np.sign(za) != np.sign(wa):
            w = w[[0, 3, 2, 1]]
        f = fpiwarp.FPI(z, w)
        size_w = np.abs(w).max()
        worst["interpolation"] = max(worst["interpolation"], np.abs(f(z) - w).max() / size_w)
        p = z.mean(axis=0) + scale * rng.uniform(-1, 1, size=(32, 2))
        if f.pole is not None:
            p = p[np.linalg.norm(p - f.pole, axis=1) > 0.3 * scale]
        worst["round trip"] = max(worst["round trip"], np.abs(f.inverse(f(p)) - p).max() / np.abs(z).max())
        fd = finite_difference_jacobian(f, p, 1e-5 * scale)
        jac = f.jacobian(p)
        worst["jacobian vs FD"] = max(
            worst["jacobian vs FD"], (np.abs(jac - fd).max(axis=(1, 2)) / np.abs(jac).max(axis=(1, 2))).max()
        )
        k = f.distortion(p)
        worst["K spread"] = max(worst["K spread"], np.abs(k / f.K - 1).max())
    return worst


def main():
    rng = np.random.default_rng(0)
    z, w = random_quad(rng, 500), random_quad(rng, 500)
    solve = best_time(lambda: fpiwarp.FPI(z, w), repeat=5, number=200)
    f = fpiwarp.FPI(z, w)
    pts = rng.uniform(-500, 500, size=(1_000_000, 2))
    fwd = best_time(lambda: f(pts), repeat=5)
    inv = best_time(lambda: f.inverse(pts), repeat=5)
    print(machine_line(machine_facts(backends=False)))
    print(f"solve one FPI:              {solve * 1e6:8.1f} us")
    print(f"map 1M points (numpy):      {fwd * 1e3:8.1f} ms  = {1e6 / fwd / 1e6:6.1f} M points/s")
    print(f"inverse of 1M points:       {inv * 1e3:8.1f} ms")
    for name, value in accuracy(rng).items():
        print(f"worst relative {name + ':':18s} {value:.2e}")


if __name__ == "__main__":
    main()
