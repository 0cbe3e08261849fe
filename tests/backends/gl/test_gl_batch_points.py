"""GL point batches (fpiwarp.backends.gl.batch_points): one transform-feedback
pass per kind of map, bounded passes and the set-by-set fallback, each equal
bit for bit to the loop of GLWarper.map_points. (tests/test_batch_launch.py
checks map_points_batch == the map_points loop on "gl" over random sets.)"""

import numpy as np
import pytest
from support.batch_cases import make_map

KINDS = ["fpi", "tps", "fpi", "shift", "tps_inverse", "compound"]


def run(warper, pts, maps):
    """(batch, loop) of warper on the blocks of maps."""
    from fpiwarp.backends.gl import batch_points

    got = batch_points.map_points_batch(warper, [t.params() for t in maps], pts)
    per = maps * len(pts) if len(maps) == 1 else maps
    return got, np.stack([warper.map_points(t, p) for t, p in zip(per, pts)])


@pytest.fixture
def passes(monkeypatch):
    """The number of points of each transform-feedback pass, as they run."""
    from fpiwarp.backends.gl import batch_points

    seen = []
    real = batch_points._pass
    monkeypatch.setattr(batch_points, "_pass", lambda w, prog, blocks, points, out, idx: seen.append(
        (len(blocks), idx.tolist())) or real(w, prog, blocks, points, out, idx))
    return seen


def test_one_pass_per_kind_of_map(make_gl_warper, rng, passes):
    pts = rng.uniform(-5, 25, size=(6, 7, 2))
    maps = [make_map(kind, k, 20, 15) for k, kind in enumerate(KINDS)]
    got, expected = run(make_gl_warper(), pts, maps)
    np.testing.assert_array_equal(got, expected)
    assert sorted(idx for _, idx in passes) == [[0, 2, 3], [1], [4], [5]]
    passes.clear()
    got, expected = run(make_gl_warper(), pts, maps[4:5])
    np.testing.assert_array_equal(got, expected)
    assert passes == [(1, list(range(6)))]  # one shared map: one pass, one block
    passes.clear()
    got, expected = run(make_gl_warper(specialize=False), pts, maps)
    np.testing.assert_array_equal(got, expected)
    assert passes == [(6, list(range(6)))]  # a program that reads the kind at run time: one pass


def test_bounded_passes_and_the_fallback(make_gl_warper, rng, monkeypatch, passes):
    from fpiwarp.backends.gl import batch_points

    pts = rng.uniform(-5, 25, size=(5, 3, 2))
    maps = [make_map(kind, k, 20, 15) for k, kind in enumerate(["fpi", "fpi", "tps", "fpi", "tps"])]
    monkeypatch.setattr(batch_points, "sets_per_pass", lambda w, p: 2)
    got, expected = run(make_gl_warper(), pts, maps)
    np.testing.assert_array_equal(got, expected)
    assert sorted(idx for _, idx in passes) == [[0, 1], [2, 4], [3]]
    passes.clear()
    monkeypatch.setattr(batch_points, "supports_batches", lambda ctx: False)
    got, expected = run(make_gl_warper(), pts, maps)
    np.testing.assert_array_equal(got, expected)
    assert passes == []


def test_the_callers_framebuffer_stays_bound(make_gl_warper, rng):
    from fpiwarp.backends.gl.context import bound_framebuffer

    w = make_gl_warper()
    fbo = w.ctx.simple_framebuffer((4, 4))
    try:
        fbo.use()
        got, expected = run(w, rng.uniform(0, 9, size=(2, 4, 2)), [make_map("fpi", 0, 8, 8)])
        np.testing.assert_array_equal(got, expected)
        assert bound_framebuffer(w.ctx).glo == fbo.glo
    finally:
        w.ctx.detect_framebuffer(0).use()
        fbo.release()
