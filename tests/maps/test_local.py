"""The local deformation operator (paper §4.1), compound deformations, warping."""

import numpy as np
import pytest
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from support.constrained_cases import RECT, cplx, deformations, rotate_edge, similarity, size_of, xy

import fpiwarp
from fpiwarp import Compound, ConstrainedFPI, LocalDeformation
from fpiwarp.block import evaluate
from fpiwarp.metrics import grid

CONVEX = deformations(convex=True)
CONSTRUCTIONS = st.sampled_from(["continuous", "paper"])


def build(src, dst, edges, construction):
    """LocalDeformation, rejecting the configurations the continuous
    construction refuses on purpose: lines meeting inside the extent, every
    spline within the edge bound over the extended edges folding over, or
    the chosen one folding (a one-line ConstraintError / FoldOverError; the
    refusals themselves are tested in test_local_continuity.py)."""
    try:
        return LocalDeformation(src, dst, edges=edges, construction=construction)
    except (fpiwarp.ConstraintError, fpiwarp.FoldOverError) as exc:
        if construction == "continuous" and (isinstance(exc, fpiwarp.FoldOverError) or "meet at" in str(exc)
                                             or "no spline" in str(exc) or "fold over" in str(exc)):
            reject()
        raise

SETTINGS = settings(max_examples=30, deadline=None)


def edge_and_normal(src, k):
    """Edge k's ends a, b (complex) and its unit normal pointing out of the quad."""
    z = cplx(src)
    a, b = z[k], z[(k + 1) % 4]
    orient = np.sign(((np.conj(z) * np.roll(z, -1)).imag).sum())
    return a, b, -1j * (b - a) / abs(b - a) * orient


def outward_points(src, k, depth, n=9):
    """Points beyond edge k (along its middle 80%), at ``depth`` × quad size."""
    a, b, out = edge_and_normal(src, k)
    t = np.linspace(0.1, 0.9, n)
    return xy(a + t * (b - a) + out * depth * size_of(src))


def across_edge(src, k, eps, n=21):
    """Pairs of points just inside and just outside edge k."""
    a, b, out = edge_and_normal(src, k)
    t = np.linspace(0.0, 1.0, n)
    on = a + t * (b - a)
    return xy(on - eps * out), xy(on + eps * out)


@SETTINGS
@given(CONVEX, CONSTRUCTIONS)
def test_each_outer_region_follows_its_similarity_exactly(case, construction):
    src, dst, edges = case
    f = build(src, dst, edges, construction)
    for k in f.edges:
        p = outward_points(src, k, 0.3)
        sim = similarity(src, dst, k)
        assert np.allclose(f(p), sim(p), rtol=0, atol=1e-12 * (size_of(dst) + np.abs(dst).max()))
        far = outward_points(src, k, 50.0)
        assert np.allclose(f(far), sim(far), rtol=1e-12, atol=1e-12 * np.abs(dst).max())
        _, fz, fzb = f._wirtinger(cplx(p))
        assert np.allclose(fzb, 0) and np.allclose(f.distortion(p), 1)


@SETTINGS
@given(CONVEX, CONSTRUCTIONS)
def test_continuous_across_the_constrained_edges(case, construction):
    src, dst, edges = case
    f = build(src, dst, edges, construction)
    for k in f.edges:
        inside, outside = across_edge(src, k, 1e-9 * size_of(src))
        jump = np.linalg.norm(f(inside) - f(outside), axis=1).max()
        assert jump < 0.01 * np.linalg.norm(dst[(k + 1) % 4] - dst[k])


@SETTINGS
@given(CONVEX, CONSTRUCTIONS)
def test_inside_it_is_the_constrained_fpi(case, construction):
    src, dst, edges = case
    f = build(src, dst, edges, construction)
    g = ConstrainedFPI(src, dst, edges=edges) if construction == "paper" else f.inner
    p = grid(src.mean(axis=0) + 0.95 * (src - src.mean(axis=0)), 9).reshape(-1, 2)
    assert np.array_equal(f(p), g(p))
    assert np.allclose(f(src), dst, atol=1e-9 * (size_of(dst) + np.abs(dst).max()))


@SETTINGS
@given(CONVEX, CONSTRUCTIONS)
def test_inverse_round_trips(case, construction):
    src, dst, edges = case
    f = build(src, dst, edges, construction)
    inner = grid(src.mean(axis=0) + 0.9 * (src - src.mean(axis=0)), 9).reshape(-1, 2)
    outer = np.concatenate([outward_points(src, k, 0.2) for k in f.edges])
    for p in (inner, outer):
        back = f.inverse(f(p))
        assert np.abs(back - p).max() <= 1e-8 * (size_of(src) + np.abs(src).max())
    assert np.allclose(f.inverse.inverse(inner), f(inner), atol=1e-9 * np.abs(dst).max())


def test_adjacent_edges_share_one_similarity_beyond_both_lines():
    src = RECT * 10
    dst = src.copy()
    dst[3] += [3.0, 2.0]
    f = LocalDeformation(src, dst, edges=(0, 1))
    beyond = np.array([[5.0, -4.0], [24.0, 5.0], [30.0, -20.0], [-3.0, -0.5], [21.0, 12.0]])
    assert np.allclose(f(beyond), beyond, atol=1e-12)  # the shared similarity: identity
    with pytest.raises(ValueError, match="one shared similarity"):
        LocalDeformation(src, rotate_edge(src, 1, 5), edges=(0, 1))


def test_a_quad_reaching_beyond_a_constrained_line_is_refused():
    dart = np.array([[0, 0], [4, 0], [2, 1], [2, 3]], float)  # not convex at point 2
    with pytest.raises(fpiwarp.ConstraintError, match="src point 1 lies beyond the line of constrained edge 2"):
        LocalDeformation(dart, dart, edges=(0, 2))
    ConstrainedFPI(dart, dart, edges=(0, 2))  # the map itself is fine with it


def test_where_the_outer_half_planes_meet_the_deeper_one_wins():
    """Non-parallel opposite lines: beyond both, the larger depth decides."""
    src = np.array([[0, 0], [4, 0], [3, 2], [1, 2]], float)  # lines of edges 1, 3 meet above
    dst = rotate_edge(src, 1, 10)
    with pytest.raises(
        fpiwarp.ConstraintError, match=r"lines of constrained edges 1 and 3 \(in src\) meet at \(2, 4\)"):
        LocalDeformation(src, dst, edges=(3, 1))  # the similarities disagree there: no continuous map
    f = LocalDeformation(src, dst, edges=(3, 1), construction="paper")
    s1, s3 = similarity(src, dst, 1), similarity(src, dst, 3)
    apex = np.array([[2.0, 4.0]])  # where the lines meet
    right = apex + [[0.5, 3.0]]  # beyond both lines, deeper beyond edge 1's line
    left = apex + [[-0.5, 3.0]]
    assert np.allclose(f(right), s1(right)) and np.allclose(f(left), s3(left))
    # the kernels' rule gives the same
    p = grid([[-6, -6], [10, 12]], 40).reshape(-1, 2)
    assert np.allclose(evaluate(f.params(), p), f(p), atol=1e-5 * 10)


def rounding_spread(block, points, draws=8):
    """How far the float64 evaluation of ``block`` at ``points`` moves, at
    most over ``draws`` draws, when each of its non-integer entries moves by
    half a float32 ulp up or down at random: the size of what rounding the
    host's float64 parameters to the block's float32 does to this map
    (where its terms cancel, far more than the entries' own 6e-8)."""
    rng = np.random.default_rng(0)
    exact = np.asarray(block, np.float64)
    half_ulp = np.where(exact != np.round(exact), np.spacing(np.abs(block).astype(np.float32)) / 2.0, 0.0)
    base = evaluate(exact, points)
    spread = np.zeros_like(base)
    for _ in range(draws):
        moved = exact + half_ulp * rng.choice([-1.0, 1.0], size=exact.shape)
        spread = np.maximum(spread, np.abs(evaluate(moved, points) - base))
    return spread


@SETTINGS
@given(CONVEX, CONSTRUCTIONS)
def test_block_evaluates_like_the_host(case, construction):
    src, dst, edges = case
    f = build(src, dst, edges, construction)
    c, s = src.mean(axis=0), size_of(src)
    p = grid([c - 2 * s, c + 2 * s], 25).reshape(-1, 2)
    host = f(p)
    ok = np.isfinite(host).all(axis=1) & (np.linalg.norm(host - dst.mean(axis=0), axis=1) < 100 * size_of(dst))
    # beyond the edges' ends the map jumps across the lines (documented):
    # float32 rounding may put a point on a line on either side
    for reg in f.regions:
        depth = ((cplx(p) - reg.origin) * np.conj(reg.normal)).real
        ok &= np.abs(depth) > 1e-5 * (s + np.abs(src).max())
    # float32 parameters carry ~6e-8 relative rounding, amplified by the
    # spline's cancelling terms up to two radii out: a few 1e-6 relative,
    # more where this map's own amplification is larger (rounding_spread)
    scale = size_of(dst) + np.abs(dst).max() + np.abs(host[ok]).max(axis=1, keepdims=True)
    bound = np.maximum(3e-6 * scale, 4 * rounding_spread(f.params(), p[ok]))
    assert np.all(np.abs(evaluate(f.params(), p[ok]) - host[ok]) <= bound)
    assert np.all(np.abs(evaluate(f.params(), p[ok], np.float32) - host[ok]) <= 1e-4 * scale)
    q = grid(dst.mean(axis=0) + 0.9 * (dst - dst.mean(axis=0)), 9).reshape(-1, 2)
    assert np.abs(evaluate(f.inverse.params(), q, np.float32) - f.inverse(q)).max() <= 2e-3 * (
        size_of(src) + np.abs(src).max()
    )


# --- compound deformations ------------------------------------------------------


def two_operators():
    src = RECT * 40 + [20, 20]
    f = LocalDeformation(src, rotate_edge(src, 1, 15), edges=(3, 1))
    q = RECT * 30 + [50, 30]
    w = q.copy()
    w[0] += [6.0, -4.0]  # the free point of edges (1, 2)
    g = LocalDeformation(q, w, edges=(1, 2))
    return f, g


def test_compound_composes_in_math_order_and_inverts():
    f, g = two_operators()
    h = g @ f
    assert isinstance(h, Compound) and len(h.stages()) == 2
    p = grid([[30, 30], [90, 55]], 12).reshape(-1, 2)
    assert np.array_equal(h(p), g(f(p)))
    assert np.allclose(h.inverse(h(p)), p, atol=1e-8 * 100)
    assert np.allclose(evaluate(h.params(), p), h(p), atol=1e-5)
    assert np.allclose(evaluate(h.inverse.params(), h(p), np.float32), p, atol=0.05)
    # chain-rule Jacobian
    assert np.allclose(h.jacobian(p), g.jacobian(f(p)) @ f.jacobian(p), atol=1e-9)


def ramp(h, w):
    """A float32 image whose value is a linear function of (x, y): bilinear
    sampling reproduces it exactly, so a warp can be checked pointwise."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    return np.stack([0.5 * x + 0.25 * y, 100 - 0.3 * x + 0.1 * y], axis=-1).astype(np.float32)


@pytest.mark.parametrize("which", ["operator", "compound"])
def test_warp_image_samples_at_the_inverse(which):
    f, g = two_operators()
    t = f if which == "operator" else g @ f
    img = ramp(96, 128)
    out = fpiwarp.warp_image(img, t, order=1, mode="constant", cval=-1.0, backend="numpy")  # the reference
    yy, xx = np.mgrid[0:96, 0:128]
    q = np.stack([xx, yy], axis=-1).astype(np.float64)
    src = t.inverse(q)
    inside = (src[..., 0] > 0) & (src[..., 0] < 127) & (src[..., 1] > 0) & (src[..., 1] < 95)
    expect = np.stack([0.5 * src[..., 0] + 0.25 * src[..., 1], 100 - 0.3 * src[..., 0] + 0.1 * src[..., 1]], -1)
    assert inside.mean() > 0.8
    assert np.allclose(out[inside], expect[inside], atol=1e-3)
    # outside the source image: the constant border value
    assert np.all(out[~inside & ((src[..., 0] < -1) | (src[..., 1] < -1))] == -1.0)


def test_every_backend_warps_a_compound_like_numpy(any_backend):
    """The kernels evaluate regions, the TPS and its Newton inverse from the
    block; they agree with the numpy reference within one uint8 step."""
    f, g = two_operators()
    h = g @ f
    img = (np.random.default_rng(7).random((48, 64, 3)) * 255).astype(np.uint8)
    ref = fpiwarp.warp_image(img, h, (72, 96))
    out = fpiwarp.warp_image(img, h, (72, 96), backend=any_backend)
    diff = np.abs(out.astype(int) - ref)
    # float32 positions flip the rounding of a few noisy pixels: the continuous
    # construction's spline spans the picture, its float32 Newton inverse
    # lands within ~1e-2 px here (the paper's, over the ROI only: ~3e-3 px)
    assert diff.max() <= 2 and (diff > 1).mean() < 0.002 and (diff > 0).mean() < 0.1
    # off the region lines, where float32 may pick the other side of a jump
    p = grid([[22.5, 21.5], [97.5, 58.5]], 8).reshape(-1, 2)
    assert np.allclose(fpiwarp.map_points(h, p, backend=any_backend), h(p), atol=1e-3)


@pytest.mark.parametrize("outer", ["mobius", "similarity"])
@pytest.mark.parametrize("which", ["constrained", "operator"])
def test_a_following_mobius_or_similarity_fuses_into_one_stage(outer, which):
    f, _ = two_operators()
    base = f if which == "operator" else f.inner
    if outer == "mobius":
        m = fpiwarp.Mobius.centered(60 + 40j, 0.001 + 0.002j, 1.1 + 0.2j, 3)
    else:
        m = fpiwarp.RLinear(0.9 + 0.3j, 0, 2 - 1j)
    h = m @ base
    p = grid([[22.5, 21.5], [97.5, 58.5]], 8).reshape(-1, 2)
    assert np.allclose(h(p), m(base(p)), atol=1e-9)
    assert np.allclose(h.inverse(h(p)), p, atol=1e-8)
    assert np.allclose(evaluate(h.params(), p), h(p), atol=1e-4)
    fused = which == "constrained" or outer == "similarity"  # regions take similarities only
    assert len(h.stages()) == (1 if fused else 2)
