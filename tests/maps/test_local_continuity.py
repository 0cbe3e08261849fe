"""The continuous local deformation (the default construction): no tear
along the constrained edges' lines anywhere in the picture, corners exact,
the edge bound on every accepted configuration, and the refusals that say
why no continuous map exists; the paper's construction one keyword away."""

import numpy as np
import pytest
from hypothesis import given, reject, settings
from hypothesis import strategies as st

import fpiwarp
from fpiwarp import LocalDeformation
from fpiwarp.maps.constrained import EDGE_BOUND, edge_similarity

SETTINGS = settings(max_examples=25, deadline=None)
ISSUE_SRC = np.array([[150, 100], [350, 100], [350, 300], [150, 300]], float)
ISSUE_DST = np.array([[150, 100], [350, 100], [350, 300], [110, 330]], float)


def cplx(p):
    p = np.asarray(p, dtype=np.float64)
    return p[..., 0] + 1j * p[..., 1]


def line_deviation(f, box, n=2001):
    """max over the constrained lines, inside the box and bordering the
    inner part, of |inner(p) - S_k(p)| (the jump across the line) relative
    to the extended edge's length (the paper's construction: the ROI's edge)."""
    z, w = cplx(f.src), cplx(f.dst)
    worst = 0.0
    for reg, k in zip(f.regions, f.edges):
        e = z[(k + 1) % 4] - z[k]
        a, b = edge_similarity(z, w, k)
        # the line's part in the box
        t = np.linspace(-50, 50, 200001)
        p = z[k] + t * e
        p = p[(p.real >= box[0]) & (p.real <= box[2]) & (p.imag >= box[1]) & (p.imag <= box[3])]
        p = p[f._select(p - 1e-9 * abs(e) * reg.normal) < 0]  # where the inner part borders the line
        if not p.size:
            continue
        dev = np.abs(f.inner.map_complex(p) - (a * p + b))
        # the bound is relative to the extended edge (the fit's): the line's length in the picture
        ext = abs(cplx(f.inner.dst)[(k + 1) % 4] - cplx(f.inner.dst)[k]) if f.construction == "continuous" else None
        worst = max(worst, float(dev.max()) / (ext or abs(w[(k + 1) % 4] - w[k])))
    return worst


def test_the_issue_example_no_longer_tears_at_y_100():
    f = LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1), extent=(512, 512))
    below, above = f.inverse([[50, 99.9], [50, 100.1]])
    assert np.allclose(below, [50, 99.9])
    assert np.linalg.norm(above - [50, 100.1]) < 0.01  # was (60.9, 108.9): an 11 px jump
    paper = LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1), construction="paper")
    assert np.linalg.norm(paper.inverse([[50, 100.1]])[0] - [50, 100.1]) > 10
    assert np.abs(f(ISSUE_SRC) - ISSUE_DST).max() < 1e-9 * 350  # the corners stay exact
    assert np.allclose(f.src, ISSUE_SRC) and np.allclose(f.inverse.src, ISSUE_DST)


@pytest.mark.parametrize("edges", [(0, 1), (1, 2), (2, 3), (3, 0)])
def test_adjacent_edges_are_continuous_over_the_whole_extent(edges):
    first = edges[0]
    dst = ISSUE_SRC.copy()
    dst[(first + 3) % 4] += [-30, 25]
    box = (0, 0, 512, 512)
    f = LocalDeformation(ISSUE_SRC, dst, edges=edges, extent=(512, 512))
    assert line_deviation(f, box) <= EDGE_BOUND
    paper = LocalDeformation(ISSUE_SRC, dst, edges=edges, construction="paper")
    assert line_deviation(paper, box) > 10 * EDGE_BOUND


@st.composite
def gentle(draw):
    """Other configurations than the benchmark's: a region of any aspect at
    any place and scale, every dst corner moved by up to ``spread`` (drawn,
    0.01 to 0.2) of its size, opposite or adjacent edges."""
    scale = draw(st.floats(0.5, 500.0))
    aspect = draw(st.floats(0.4, 2.5))
    spread = draw(st.floats(0.01, 0.2))
    src = scale * np.array([[0, 0], [aspect, 0], [aspect, 1], [0, 1]]) + draw(st.floats(-1e3, 1e3))
    u = st.floats(-1, 1)
    kind = draw(st.sampled_from(["opposite", "adjacent"]))
    if kind == "opposite":
        edges = draw(st.sampled_from([(0, 2), (1, 3)]))
        dst = src + spread * scale * np.array([[draw(u), draw(u)] for _ in range(4)])
    else:
        first = draw(st.integers(0, 3))
        edges = (first, (first + 1) % 4)
        dst = src.copy()
        dst[(first + 3) % 4] += spread * scale * np.array([draw(u), draw(u)])
    return src, dst, edges


@SETTINGS
@given(gentle())
def test_every_accepted_configuration_is_continuous_and_within_the_edge_bound(case):
    src, dst, edges = case
    try:
        f = LocalDeformation(src, dst, edges)
    except fpiwarp.ConstraintError as exc:  # said why, in one line
        msg = str(exc)
        assert "\n" not in msg and ("meet at" in msg or "strays by" in msg or "lies beyond" in msg), msg
        reject()
    except fpiwarp.FoldOverError:
        reject()
    z, w = cplx(src), cplx(dst)
    both = np.concatenate([z, w])
    pad = max(np.ptp(both.real), np.ptp(both.imag))
    box = (both.real.min() - pad, both.imag.min() - pad, both.real.max() + pad, both.imag.max() + pad)
    assert line_deviation(f, box) <= 1.02 * EDGE_BOUND
    assert np.abs(f(src) - dst).max() <= 1e-9 * (pad + np.abs(dst).max())


def test_opposite_lines_meeting_inside_the_picture_are_refused_with_the_point():
    src = np.array([[0, 0], [4, 0], [3, 2], [1, 2]], float)
    dst = src.copy()
    dst[1:3] += [0.3, 0.1]
    with pytest.raises(fpiwarp.ConstraintError, match=r"^the lines of constrained edges 1 and 3 \(in src\) meet at "
                                                      r"\(2, 4\), inside the picture's extent") as info:
        LocalDeformation(src, dst, edges=(1, 3))
    assert "\n" not in str(info.value) and isinstance(info.value, ValueError)
    LocalDeformation(src, dst, edges=(1, 3), extent=(-1, -1, 5, 3))  # a picture that ends before (2, 4)
    LocalDeformation(src, dst, edges=(1, 3), construction="paper")  # the seam accepted


@pytest.mark.parametrize("bad", [(0, 10), (10, 0, 5, 5), "wide", (1, 2, 3), (0, 0, float("nan"), 4)])
def test_a_bad_extent_or_construction_is_one_line(bad):
    with pytest.raises(fpiwarp.ArgumentError, match="extent must be") as info:
        LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1), extent=bad)
    assert "\n" not in str(info.value)
    with pytest.raises(fpiwarp.ArgumentError, match="construction must be one of"):
        LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1), construction="seamless")


def test_the_block_evaluates_the_continuous_construction_like_the_host():
    from fpiwarp.block import evaluate

    f = LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1), extent=(512, 512))
    ys, xs = np.mgrid[5:512:23, 5:512:23]
    p = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(float)
    assert np.abs(evaluate(f.params(), p, np.float32) - f(p)).max() < 2e-2  # px, float32
    q = f(p)
    assert np.abs(evaluate(f.inverse.params(), q, np.float32) - p).max() < 2e-2


def test_on_picture_gives_the_default_extent_the_pictures_and_keeps_the_rest():
    """The one helper of fpiwarp warp and the editors: a LocalDeformation of
    the default extent is rebuilt over the picture; one with its own extent,
    the paper's construction and any other map come back as they are."""
    from fpiwarp.maps.local import on_picture

    f = LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1))
    fitted = on_picture(f, 512, 400)
    np.testing.assert_array_equal(fitted.params(),
                                  LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1), extent=(512, 400)).params())
    assert not np.array_equal(fitted.params(), f.params())
    assert on_picture(fitted, 100, 100) is fitted  # an extent of its own is kept
    paper = LocalDeformation(ISSUE_SRC, ISSUE_DST, edges=(0, 1), construction="paper")
    fpi = fpiwarp.FPI(ISSUE_SRC, ISSUE_DST)
    assert on_picture(paper, 512, 400) is paper and on_picture(fpi, 512, 400) is fpi
    inverse = f.inverse  # derived: no settings to rebuild from
    assert on_picture(inverse, 512, 400) is inverse
