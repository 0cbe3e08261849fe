"""Measure how well the constrained FPI's fold-over check samples the Jacobian.

A measurement, not a test::

    python3 -m benchmarks.foldover_sampling --configs 3000 --seed 7

For random strong deformations (opposite edges: the second edge turned up
to ±90°, scaled 0.5..2 and moved; adjacent edges: the free corner moved up
to 0.8 of the size) it fits the spline without the check, then compares
the least Jacobian determinant (relative to its median) on a dense
sampling (a 200 × 200 grid and 1000 points per edge) with the one the
check sees (its GRID and EDGE_POINTS) and prints, for each margin, how
many folds the check would miss and how many unfolded fits it would
refuse, and the cost of the check against the cost of the fit.
"""

import argparse
import time
from unittest import mock

import numpy as np

import fpiwarp
from fpiwarp.maps import constrained as _constrained
from fpiwarp.testing import random_quad

from .common import machine_facts, machine_line


def strong_deformation(rng):
    """(src, dst, edges) of one random strong deformation."""
    q = random_quad(rng, convex=rng.random() < 0.7)
    z = q[:, 0] + 1j * q[:, 1]
    if rng.random() < 0.5:
        z = np.conj(z)
    w = z.copy()
    if rng.random() < 0.6:
        first = int(rng.integers(2))
        edges, k = (first, first + 2), first + 2
        idx = [k, (k + 1) % 4]
        mid = w[idx].mean()
        turn = rng.uniform(0.5, 2) * np.exp(1j * rng.uniform(-1.6, 1.6))
        w[idx] = mid + turn * (z[idx] - mid) + complex(*rng.uniform(-0.5, 0.5, 2))
    else:
        first = int(rng.integers(4))
        edges = (first, (first + 1) % 4)
        w[(first + 3) % 4] += complex(*rng.uniform(-0.8, 0.8, 2))
    w = np.exp(1j * rng.uniform(-3, 3)) * rng.uniform(0.5, 2) * w + complex(*rng.uniform(-1, 1, 2))
    as_xy = lambda c: np.stack([c.real, c.imag], axis=1)  # noqa: E731
    return as_xy(z), as_xy(w), edges


def least_jacobian(f, z, grid, edge_points):
    """min J / median |J| over the check's sampling of quad z."""
    p = _constrained.roi_samples(z, grid, edge_points)
    _, fz, fzb = f.wirtinger(p)
    jac = np.abs(fz) ** 2 - np.abs(fzb) ** 2
    return float(jac.min() / np.median(np.abs(jac)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    dense, sparse, fit_s, check_s = [], [], 0.0, 0.0
    with mock.patch.object(_constrained, "refuse_fold", lambda *a: None):
        for _ in range(args.configs):
            src, dst, edges = strong_deformation(rng)
            t0 = time.perf_counter()
            try:
                f = fpiwarp.ConstrainedFPI(src, dst, edges=edges)
            except ValueError:
                continue
            t1 = time.perf_counter()
            sparse.append(least_jacobian(f, f._z, _constrained.GRID, _constrained.EDGE_POINTS))
            t2 = time.perf_counter()
            dense.append(least_jacobian(f, f._z, 200, 1000))
            fit_s, check_s = fit_s + t1 - t0, check_s + t2 - t1
    dense, sparse = np.array(dense), np.array(sparse)
    folds = dense <= 0
    print(machine_line(machine_facts(backends=False)))
    print(f"{len(dense)} fits, {folds.sum()} fold on the dense sampling")
    for margin in (0.0, 0.01, 0.02, 0.05, 0.1):
        refused = sparse <= margin
        print(
            f"margin {margin:g}: folds missed {(folds & ~refused).sum()}, "
            f"unfolded fits refused {(~folds & refused).sum()}"
        )
    print(f"fit {1e3 * fit_s / len(dense):.2f} ms, check {1e3 * check_s / len(dense):.2f} ms per fit")


if __name__ == "__main__":
    main()
