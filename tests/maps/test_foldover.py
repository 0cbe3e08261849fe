"""The fold-over check's local refinement (fpiwarp.maps.constrained.refine).

Small folds about a tenth of the quad's radius from a corner fall between
the check's grid points; the samples next to them show a small positive
Jacobian. These configurations were found by a random search and by
hypothesis (tests/maps/test_local_seams.py, seed 1): without the refinement the
fit was accepted and folds on a 200 x 200 grid with 1000 points per edge;
with it the fit is refused, and the default spacing moves on to one that
does not fold (or refuses when every fit within the edge bound folds).
"""

import numpy as np
import pytest

from fpiwarp import ConstrainedFPI, ConstraintError, FoldOverError
from fpiwarp.maps import constrained as _foldover
from fpiwarp.maps.constrained import inside_quad, roi_samples, worst_fold

MISSED = [
    (  # tests/test_seams.py::test_no_fold_over_where_the_paper_map_has_none, --hypothesis-seed=1
        [[-0.5, 0.2125], [0.5, 0.1], [0.5, 1.1], [-0.5, 0.5]],
        [[-0.2, 0.2125], [0.8, 0.25], [1.1, 1.4], [-1.175, 0.425]],
        (0, 2),
    ),
    (  # benchmarks/seams.py's distribution, random search
        [
            [-0.5962773741794766, -0.3058264811835672],
            [0.6121929011112451, -0.3228845930401618],
            [-0.16235054301775553, 1.1651296924453218],
            [-0.5040764420384368, 0.6963133579241433],
        ],
        [
            [-0.3049411973738672, -0.573668281559192],
            [0.4477420874445105, -0.09884393062687585],
            [0.023305085194489095, 0.7515611227473198],
            [-0.34025072149569224, 1.2189586872067415],
        ],
        (1, 3),
    ),
    (
        [
            [-0.2662490680031693, -0.6821437902388806],
            [0.6411167168617604, -0.12889690171995155],
            [0.6484405243873363, 0.21171662971637212],
            [-0.39136429130165856, 0.6298612524429922],
        ],
        [
            [-0.864598051781297, -0.6425318646794305],
            [1.2172420938608703, -0.11102627234741863],
            [0.4175046551878613, 0.3541778279793235],
            [-0.12089753654100266, 0.8117450570500622],
        ],
        (0, 2),
    ),
]


def dense_least_jacobian(f):
    """min J / median |J| on a 200 x 200 grid and 1000 points per edge."""
    p = roi_samples(f._z, 200, 1000)
    _, fz, fzb = f._wirtinger(p)
    jac = np.abs(fz) ** 2 - np.abs(fzb) ** 2
    return float(jac.min() / np.median(np.abs(jac)))


def test_the_unrefined_check_accepts_a_fold_that_the_refined_one_finds(monkeypatch):
    """MISSED[1] fitted with the graded spacing folds between the check's
    grid points: accepted without the refinement, refused with it."""
    src, dst, edges = (np.array(MISSED[1][0]), np.array(MISSED[1][1]), MISSED[1][2])
    with monkeypatch.context() as m:
        m.setattr(_foldover, "refine", lambda f, z, p, jac, cell: (p, jac))
        unrefined = ConstrainedFPI(src, dst, edges=edges, spacing="graded")
        assert worst_fold(unrefined, unrefined._z) is None
    assert dense_least_jacobian(unrefined) < 0
    point, rel = worst_fold(unrefined, unrefined._z)
    assert rel <= _foldover.FOLD_MARGIN and inside_quad(unrefined._z, np.array([point]))[0]
    with pytest.raises(FoldOverError):
        ConstrainedFPI(src, dst, edges=edges, spacing="graded")


@pytest.mark.parametrize("case", MISSED)
def test_the_default_fit_never_folds(case):
    """With the refinement, the default spacing gives a map that does not fold
    on a dense sampling, or refuses (every fit within the edge bound folds)."""
    src, dst, edges = (np.array(case[0]), np.array(case[1]), case[2])
    try:
        f = ConstrainedFPI(src, dst, edges=edges)
    except ConstraintError as exc:
        assert "fold over" in str(exc)
        return
    assert dense_least_jacobian(f) > 0


def test_refinement_adds_a_bounded_number_of_samples_inside_the_quad():
    src, dst, edges = (np.array(c) if i < 2 else c for i, c in enumerate(MISSED[1]))
    with pytest.MonkeyPatch.context() as m:  # the unrefined fit: a map that folds, to refine on
        m.setattr(_foldover, "refine", lambda f, z, p, jac, cell: (p, jac))
        f = ConstrainedFPI(src, dst, edges=edges, spacing="graded")
    z = f._z
    p = roi_samples(z)
    _, fz, fzb = f._wirtinger(p)
    jac = np.abs(fz) ** 2 - np.abs(fzb) ** 2
    q, qjac = _foldover.refine(f, z, p, jac, 0.05)
    added = q[len(p) :]
    bound = _foldover.REFINE_LEVELS * _foldover.REFINE * _foldover.REFINE_GRID**2
    assert 0 < len(added) <= bound
    assert np.all(inside_quad(z, added))
    assert np.array_equal(q[: len(p)], p) and np.array_equal(qjac[: len(p)], jac)
    _, fz, fzb = f._wirtinger(added)
    assert np.allclose(qjac[len(p) :], np.abs(fz) ** 2 - np.abs(fzb) ** 2)
    # the refined samples sit around the least ones: the first pass within a cell of them
    least = p[np.argmin(jac)]
    assert np.min(np.abs(added - least)) <= 0.05 * np.sqrt(2)
