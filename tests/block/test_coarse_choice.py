"""The coarse pass's choice (fpiwarp.block.coarse_choice): the predicted
share of passing seeds follows the float32 reference's, grows with the
map's scale in output pixels, and the rule picks per-pixel Newton for a
map that bends within a few node cells and the pass for a smooth one;
every backend's warp (single, bound, batch) follows it."""

import numpy as np
import pytest
from support.requirements import use_backend

import fpiwarp
from fpiwarp.block import coarse_choice
from fpiwarp.block.coarse import coarse_pass, pixel_seeds
from fpiwarp.block.coarse_choice import BREAK_EVEN, curvature_share, seed_pass_share, takes_coarse_pass
from fpiwarp.block.describe import describe, stage_rows
from fpiwarp.block.layout import PAIRED_CORES, ROW_L3
from fpiwarp.block.reference import pre_mobius, region_winner, tps_core


def _quad(size, side, shift):
    """A LocalDeformation of a square quad ``side`` of a ``size``² frame
    wide, centred, its corners moved by ``shift`` of its side (edges 1, 3)."""
    c, h = (size - 1) / 2, side * size / 2
    src = np.array([[c - h, c - h], [c + h, c - h], [c + h, c + h], [c - h, c + h]])
    moves = np.array([[0.5, -1.25], [0.75, 0.5], [-0.5, 1.5], [0.25, -0.75]]) * shift * 2 * h
    return fpiwarp.LocalDeformation(src, src + moves, edges=(1, 3))


def _measured_share(transform, size, every=3):
    """The float32 reference's share of band pixels (every ``every``-th
    row) whose coarse-pass seed passes the check."""
    block = np.asarray(transform.inverse.params(), np.float32)
    st = describe(block).stages[0]
    rows = stage_rows(block, 0)
    py, px = np.meshgrid(np.arange(0, size, every), np.arange(size), indexing="ij")
    z = (px + 1j * py).astype(np.complex64)
    band = ~region_winner(rows, st, z, np.float32)[0]
    x0 = pixel_seeds(coarse_pass(block, size, size), px[band], py[band])[0]
    t = pre_mobius(rows, z[band])
    res = tps_core(x0, rows, st.n_centers, np.float32, st.core in PAIRED_CORES)[0] - t
    return float((np.abs(res) <= rows[ROW_L3, 2]).mean())


@pytest.mark.parametrize("size, side, shift", [(128, 0.4, 0.06), (256, 0.4, 0.06), (160, 0.5, 0.12),
                                               (128, 0.7, 0.03), (384, 0.1, 0.04)])
def test_the_predicted_share_follows_the_reference(size, side, shift):
    """The sampled prediction within 0.2 of the float32 reference's share
    (measured over 27 maps: mean error 0.04, at most 0.16), the curvature
    screen never below it by more than SCREEN_MARGIN nor above it by
    SURE_MARGIN (where the rule trusts the screen alone)."""
    f = _quad(size, side, shift)
    measured = _measured_share(f, size)
    block = f.inverse.params()
    assert abs(seed_pass_share(block, size, size) - measured) <= 0.2
    screen = curvature_share(block, size, size)
    assert measured - coarse_choice.SCREEN_MARGIN <= screen < measured + coarse_choice.SURE_MARGIN


def test_the_share_grows_with_the_map_scale():
    """One map's shape drawn into ever larger frames: the predicted share
    (both estimates) never falls, and once the rule picks the pass it
    keeps it."""
    sizes = (96, 128, 192, 256, 384, 512, 768)
    shares = [seed_pass_share(_quad(s, 0.4, 0.06).inverse.params(), s, s) for s in sizes]
    screens = [curvature_share(_quad(s, 0.4, 0.06).inverse.params(), s, s) for s in sizes]
    assert shares[0] < 0.2 and shares[-1] > 0.8
    assert all(b >= a - 0.02 for a, b in zip(shares, shares[1:]))
    assert all(b >= a - 0.02 for a, b in zip(screens, screens[1:]))
    for backend in BREAK_EVEN:
        picks = [takes_coarse_pass(_quad(s, 0.4, 0.06).inverse.params(), s, s, backend) for s in sizes]
        assert picks == sorted(picks) and picks[-1] and not picks[0]


def test_a_map_bending_within_a_few_cells_solves_per_pixel():
    f = _quad(128, 0.4, 0.06)  # the benchmark's pattern at 128²: 8 % of the seeds pass
    for backend in BREAK_EVEN:
        assert not takes_coarse_pass(f.inverse.params(), 128, 128, backend)


def test_a_smooth_large_map_takes_the_pass():
    f = _quad(512, 0.6, 0.03)
    assert seed_pass_share(f.inverse.params(), 512, 512) > 0.95
    for backend in BREAK_EVEN:
        assert takes_coarse_pass(f.inverse.params(), 512, 512, backend)


def test_without_a_newton_core_there_is_no_choice(monkeypatch):
    block = fpiwarp.FPI([[0, 0], [40, 0], [40, 30], [0, 30]], [[1, 2], [41, -1], [38, 33], [-2, 29]]).inverse.params()
    assert seed_pass_share(block, 40, 30) is None and curvature_share(block, 40, 30) is None
    assert not takes_coarse_pass(block, 40, 30)
    monkeypatch.setattr(coarse_choice, "ALWAYS", True)
    assert not takes_coarse_pass(block, 40, 30)
    assert takes_coarse_pass(_quad(128, 0.4, 0.06).inverse.params(), 128, 128)


def test_a_band_outside_the_output_solves_per_pixel():
    """A deformation whose band (between its held edges' lines) misses the
    output: the regions take every pixel, the pass would solve its nodes
    for nothing."""
    src = np.array([[300.0, 10], [340, 10], [340, 50], [300, 50]])
    f = fpiwarp.LocalDeformation(src, src + [[1, -2], [2, 1], [-1, 2], [1, -1]], edges=(1, 3))
    assert seed_pass_share(f.inverse.params(), 64, 64) == 0.0
    assert curvature_share(f.inverse.params(), 64, 64) == 0.0
    assert not takes_coarse_pass(f.inverse.params(), 64, 64)


# --- the backends follow the rule

def _coordinates(size):
    y, x = np.mgrid[0:size, 0:size].astype(np.float32)
    return np.stack([x, y, np.zeros_like(x)], -1)


def _paths(backend, call, monkeypatch):
    """``call()`` with the rule, with the pass switched off, and forced on."""
    from support.batch_cases import coarse_switch

    got = call()
    with monkeypatch.context() as patch:
        patch.setattr(coarse_switch(backend), "COARSE_PASS", False)
        off = call()
    with monkeypatch.context() as patch:
        patch.setattr(coarse_choice, "ALWAYS", True)
        on = call()
    return got, off, on


SIZE = 128
#: (map, whether the rule picks the pass at SIZE² on opencl and gl)
FOLLOWED = [(_quad(SIZE, 0.4, 0.06), False), (_quad(SIZE, 0.7, 0.01), True)]


@pytest.mark.parametrize("backend", ["opencl", "gl"])
def test_each_warp_takes_the_path_the_rule_picks(backend, monkeypatch):
    """Single and bound warps of a map the rule leaves per-pixel and of one
    it seeds: bit for bit the output with the pass switched off, or forced
    on, whichever the rule picked (the two differ: the test can fail)."""
    use_backend(backend)
    img = _coordinates(SIZE)
    for f, picked in FOLLOWED:
        assert takes_coarse_pass(f.inverse.params(), SIZE, SIZE, backend) == picked
        bound = fpiwarp.backends.get_backend(backend).bind(f)
        calls = [lambda f=f: fpiwarp.warp_image(img, f, order=1, mode="constant", cval=-1.0, backend=backend),
                 lambda bound=bound: bound.warp_image(img, (SIZE, SIZE), order=1, mode="constant",
                                                      cval=(-1.0, -1.0, -1.0))]
        for call in calls:
            got, off, on = _paths(backend, call, monkeypatch)
            assert (off != on).any()
            np.testing.assert_array_equal(got, on if picked else off)


@pytest.mark.parametrize("backend", ["opencl", "gl"])
def test_a_batch_takes_each_maps_own_path(backend, monkeypatch):
    """A batch mixing both maps (each image its own): each image as its
    single warp, which the rule picked (the previous test)."""
    use_backend(backend)
    img = _coordinates(SIZE)
    maps = [f for f, _ in FOLLOWED] + [FOLLOWED[1][0], FOLLOWED[0][0]]
    stack = np.stack([img] * len(maps))
    got = fpiwarp.warp_batch(stack, maps, order=1, mode="constant", cval=-1.0, backend=backend)
    singles = [fpiwarp.warp_image(img, f, order=1, mode="constant", cval=-1.0, backend=backend) for f in maps]
    np.testing.assert_array_equal(got, np.stack(singles))
    _, off, on = _paths(backend, lambda: fpiwarp.warp_batch(stack, maps, order=1, mode="constant",
                                                                 cval=-1.0, backend=backend), monkeypatch)
    for k, f in enumerate(maps):
        picked = dict((id(m), p) for m, p in FOLLOWED)[id(f)]
        np.testing.assert_array_equal(got[k], on[k] if picked else off[k])


def test_the_share_needed_grows_as_the_band_shrinks_only_where_nodes_cost_beyond_it():
    """opencl solves every node: a smaller band (the same quad in a larger
    frame) needs a larger share; gl's split draw solves only the band's
    nodes: its share needed is its break-even whatever the band."""
    from fpiwarp.block.coarse_choice import NODE_COST, share_needed

    wide_band, narrow_band = _quad(512, 0.6, 0.03).inverse.params(), _quad(512, 0.1, 0.03).inverse.params()
    for backend in BREAK_EVEN:
        wide, narrow = share_needed(wide_band, 512, 512, backend), share_needed(narrow_band, 512, 512, backend)
        if NODE_COST.get(backend, True):
            assert BREAK_EVEN[backend] < wide < narrow
        else:
            assert wide == narrow == BREAK_EVEN[backend]


def test_answers_are_remembered_until_forgotten(monkeypatch):
    """A bound map asks once per shape; forget() makes the next question estimate again."""
    coarse_choice.forget()
    made = []
    band_cells = coarse_choice._band_cells
    monkeypatch.setattr(coarse_choice, "_band_cells", lambda *a: made.append(1) or band_cells(*a))
    block = _quad(256, 0.4, 0.06).inverse.params()
    first = takes_coarse_pass(block, 256, 256, "opencl")
    assert takes_coarse_pass(block, 256, 256, "opencl") == first and len(made) == 1
    coarse_choice.forget()
    assert takes_coarse_pass(block, 256, 256, "opencl") == first and len(made) == 2
