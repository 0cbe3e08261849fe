"""Finding fold-over of a map over its region of interest (the source quad).

A map folds where its Jacobian determinant J = |f_z|² - |f_zbar|² is <= 0:
there it is no longer one-to-one, and a numerical inverse returns one of
several preimages without noticing. The constrained FPI's thin-plate
spline can fold for strong deformations, so its fit is checked here:
J is sampled on a GRID × GRID grid over the quad's bounding box (the
points inside the quad), at EDGE_POINTS points along each edge, where
folds usually start (the spline is pinned along the constrained edges and
free across the others), denser towards the corners, and on small fans
around each corner, where the smallest folds sit (next to reflex corners).
The samples of least J then get a local refinement (REFINE_LEVELS passes
of small grids around the REFINE samples of least J, each a third as wide
as the one before): some folds sit between the grid points about a tenth
of the quad's radius from a corner, where the samples next to them show a
small but positive J. J is smooth (the spline's second derivatives grow
only like log of the distance to a center); a sample with J below
FOLD_MARGIN of the median (over the samples before refinement) counts as
a fold. Measured with ``tests/fold_fuzz.py`` and a random search of 7,500
configurations of the default fit: accepted fits that fold on a 200 × 200
grid with 1000 points per edge went from 6 of 6,030 to 2, both folds within
1e-3 of the quad's radius of a corner that nearly touches another one
(finer than the corner fans).
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
#: Local refinement: around each of the REFINE samples of least J (at
#: least a grid cell apart) a REFINE_GRID × REFINE_GRID grid one grid cell
#: wide either side, REFINE_LEVELS times, each time a third as wide around
#: the new least samples: at most REFINE_LEVELS · REFINE · REFINE_GRID²
#: more samples, whatever the map.
REFINE = 6
REFINE_GRID = 7
REFINE_LEVELS = 2


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


def _jacobian(f, p):
    _, fz, fzb = f.wirtinger(p)
    return np.abs(fz) ** 2 - np.abs(fzb) ** 2


def _least(p, jac, n, apart):
    """Up to n of the points p of least jac, each at least ``apart`` from
    those before it."""
    kept = []
    for k in np.argsort(jac)[: 64 * n]:
        if all(abs(p[k] - q) >= apart for q in kept):
            kept.append(p[k])
            if len(kept) == n:
                break
    return np.array(kept, dtype=complex)


def refine(f, z, p, jac, cell, levels=REFINE_LEVELS):
    """The samples p (with Jacobian jac) and, around those of least J, finer
    grids inside the quad z, ``levels`` times (see REFINE); ``cell`` is the
    width of the first grid's cells."""
    steps = np.linspace(-1.0, 1.0, REFINE_GRID)
    offsets = (steps[None, :] + 1j * steps[:, None]).ravel()
    for _ in range(levels):
        q = (_least(p, jac, REFINE, cell)[:, None] + cell * offsets[None, :]).ravel()
        q = q[inside_quad(z, q)]
        p, jac = np.concatenate([p, q]), np.concatenate([jac, _jacobian(f, q)])
        cell /= 3
    return p, jac


def worst_fold(f, z, margin=FOLD_MARGIN, **kw):
    """(point, J/J_typical) where the map f folds over quad z worst, or None.

    J is compared with its median over the samples (J_typical), so the
    second value says how strongly orientation is reversed relative to the
    map's usual area scale; a sample with J <= margin J_typical counts (a
    fold between samples shows as a near-zero J at its neighbours). The
    samples of least J are refined locally (see REFINE) before the test."""
    p = roi_samples(z, **kw)
    jac = _jacobian(f, p)
    typical = float(np.median(np.abs(jac)))
    span = max(np.ptp(z.real), np.ptp(z.imag))
    p, jac = refine(f, z, p, jac, span / (kw.get("grid", GRID) - 1))
    k = int(np.argmin(jac))
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
