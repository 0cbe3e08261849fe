"""Finding fold-over of a map over its region of interest (the source quad).

A map folds where its Jacobian determinant J = |f_z|² - |f_zbar|² is <= 0:
there it is no longer one-to-one, and a numerical inverse returns one of
several preimages without noticing. The constrained FPI's thin-plate
spline can fold for strong deformations, so its fit is checked here:
J is sampled on a GRID × GRID grid over the quad's bounding box (the
points inside the quad), at EDGE_POINTS points along each edge, where
folds usually start (the spline is pinned along the constrained edges and
free across the others), denser towards the corners, and on small fans
around each corner, where the smallest folds sit (next to reflex corners). J is smooth (the spline's second derivatives
grow only like log of the distance to a center); a sample with J below
FOLD_MARGIN of the median counts as a fold. Measured with
``tests/fold_fuzz.py``: this finds every fold that a 200 × 200 grid with
1000 points per edge finds.
"""

import numpy as np

from ._errors import FoldOverError

#: Interior sampling: a GRID × GRID grid over the quad's bounding box.
GRID = 32
#: Samples along each edge, ends included.
EDGE_POINTS = 64
#: A sample whose J is at most this fraction of the median J counts as a
#: fold: on 5,431 fuzzed fits (tests/fold_fuzz.py, seeds 7 and 11) a margin
#: of 0 missed 1 of the 605 folds a 200 × 200 sampling found, 0.01 missed
#: none and refused 13 unfolded fits that compress area over 100 times.
FOLD_MARGIN = 0.01
#: Offsets (in units of the quad's radius) of the points sampled around each
#: corner: folds of the spline can be as small as 1% of the quad next to a
#: reflex corner (measured), finer than the grid.
CORNER_FAN = np.outer([0.003, 0.01, 0.03], np.exp(2j * np.pi * np.arange(16) / 16)).ravel()


def inside_quad(z, p):
    """Boolean mask: which points p (complex) lie strictly inside the simple
    polygon z (complex), by the even-odd rule."""
    inside = np.zeros(p.shape, dtype=bool)
    for a, b in zip(z, np.roll(z, -1)):
        crosses = (a.imag > p.imag) != (b.imag > p.imag)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = a.real + (p.imag - a.imag) * (b.real - a.real) / (b.imag - a.imag)
        inside ^= crosses & (p.real < x)
    return inside


def roi_samples(z, grid=GRID, edge_points=EDGE_POINTS):
    """Points of the quad z (complex (4,)): its interior grid points, points
    along its four edges (Chebyshev-spaced: dense near the corners), and
    fans of points around each corner inside the quad, complex 1-D."""
    lo = complex(z.real.min(), z.imag.min())
    hi = complex(z.real.max(), z.imag.max())
    xs = np.linspace(lo.real, hi.real, grid)
    ys = np.linspace(lo.imag, hi.imag, grid)
    p = (xs[None, :] + 1j * ys[:, None]).ravel()
    t = 0.5 * (1 - np.cos(np.linspace(0.0, np.pi, edge_points)))
    edges = [a + t * (b - a) for a, b in zip(z, np.roll(z, -1))]
    size = float(np.max(np.abs(z - z.mean())))
    fans = (z[:, None] + size * CORNER_FAN[None, :]).ravel()
    return np.concatenate([p[inside_quad(z, p)], *edges, fans[inside_quad(z, fans)]])


def worst_fold(f, z, margin=FOLD_MARGIN, **kw):
    """(point, J/J_typical) where the map f folds over quad z worst, or None.

    J is compared with its median over the samples (J_typical), so the
    second value says how strongly orientation is reversed relative to the
    map's usual area scale; a sample with J <= margin J_typical counts (a
    fold between samples shows as a near-zero J at its neighbours)."""
    p = roi_samples(z, **kw)
    _, fz, fzb = f.wirtinger(p)
    jac = np.abs(fz) ** 2 - np.abs(fzb) ** 2
    k = int(np.argmin(jac))
    typical = float(np.median(np.abs(jac)))
    if jac[k] > margin * typical:
        return None
    return complex(p[k]), float(jac[k] / typical)


def refuse_fold(f, z, what):
    """Raise FoldOverError if the map f folds over the quad z (complex (4,));
    ``what`` names the map in the message."""
    fold = worst_fold(f, z)
    if fold is not None:
        p, rel = fold
        raise FoldOverError(
            f"{what} folds over inside src: its Jacobian determinant is {rel:.3g} times its typical "
            f"size at ({p.real:.6g}, {p.imag:.6g}) (it must stay above {FOLD_MARGIN:g}), so it is not "
            "one-to-one there and its inverse would return one of several preimages; deform the "
            "constrained edges less"
        )
