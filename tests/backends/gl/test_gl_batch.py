"""GL batches (fpiwarp.backends.gl.batch): one instanced draw per kind of
map, split into bounded draws, column tiles and the image-by-image
fallbacks, each equal bit for bit to the loop of GLWarper.warp_block.
(tests/test_batch_launch.py checks warp_batch == the warp_image loop on
"gl" over random stacks, kinds and sampling.)"""

import numpy as np
import pytest
from support.batch_cases import make_map


def run(warper, stack, maps, shape, **options):
    """(batch, loop) of warper on the inverse blocks of maps."""
    from fpiwarp.backends.gl import batch

    blocks = [t.inverse.params() for t in maps]
    got = batch.warp_batch(warper, stack, blocks, shape, **options)
    per = blocks * len(stack) if len(blocks) == 1 else blocks
    expected = np.stack([warper.warp_block(im, b, shape, **options) for im, b in zip(stack, per)])
    return got, expected


def recorded_draws(batch, monkeypatch):
    """A list that each instanced draw of ``batch`` (the module) appends its images' indices to."""
    draws = []
    real = batch.draw_group
    monkeypatch.setattr(batch, "draw_group", lambda w, p, s, b, idx, *a: draws.append(idx.tolist()) or
                        real(w, p, s, b, idx, *a))
    return draws


KINDS = ["fpi", "tps", "fpi", "shift", "tps", "compound"]


def test_one_draw_per_kind_of_map(make_gl_warper, rng, monkeypatch):
    from fpiwarp.backends.gl import batch

    stack = rng.integers(0, 256, size=(6, 11, 13, 3), dtype=np.uint8)
    maps = [make_map(kind, k, 13, 11) for k, kind in enumerate(KINDS)]
    draws = recorded_draws(batch, monkeypatch)
    got, expected = run(make_gl_warper(), stack, maps, (9, 15), order=1, mode="edge", cval=np.zeros(3))
    np.testing.assert_array_equal(got, expected)
    assert sorted(draws) == [[0, 2, 3], [1, 4], [5]]  # an R-linear map is an FPI's kind of program here
    draws.clear()
    got, expected = run(make_gl_warper(), stack, maps[:1], (9, 15), order=3, mode="reflect", cval=np.zeros(3))
    np.testing.assert_array_equal(got, expected)
    assert draws == [list(range(6))]  # one shared map: one draw
    draws.clear()
    got, expected = run(make_gl_warper(specialize=False), stack, maps, (9, 15), order=0, mode="wrap", cval=np.zeros(3))
    np.testing.assert_array_equal(got, expected)
    # a program that reads the kind at run time: one draw for the maps with a
    # Newton core (the coarse pass's program), one for the others
    assert sorted(draws) == [[0, 2, 3, 5], [1, 4]]


@pytest.mark.parametrize("shape", [(3, 20), (5, 20), (8, 8)])
def test_bounded_draws_and_column_tiles(make_gl_warper, rng, shape):
    """A size limit of 8 pixels: draws of 8 // rows images, outputs wider
    than 8 in column tiles, still the loop's result."""
    stack = rng.uniform(-1, 2, size=(5, 6, 7, 2)).astype(np.float32)
    maps = [make_map(kind, k, 8, 8) for k, kind in enumerate(KINDS[:5])]
    got, expected = run(make_gl_warper(max_texture_size=8), stack, maps, shape, order=1, mode="constant",
                        cval=np.full(2, 0.5))
    np.testing.assert_array_equal(got, expected)


def test_antialiased_batches_equal_the_loop(make_gl_warper, rng):
    """Antialiased batches go image by image (each source's pyramid once);
    chunked draws are test_draws_of_one_image's."""
    stack = rng.integers(0, 65536, size=(4, 7, 9, 4), dtype=np.uint16)
    maps = [make_map(kind, k, 9, 7) for k, kind in enumerate(["tps", "fpi", "tps", "tps"])]
    got, expected = run(make_gl_warper(), stack, maps, (7, 9), order=1, mode="wrap", cval=np.zeros(4), antialias=True)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("single_texture", [True, False])
def test_draws_of_one_image(make_gl_warper, rng, monkeypatch, single_texture):
    """Chunks of one byte: every draw holds one image, its source a 2D
    texture (FPW_BATCH_SINGLE, where SINGLE_SOURCE_TEXTURE) or a layer of a
    texture array; the loop's result either way, for gathered and packed
    RGB, a Newton map's coarse pass, cubic sampling, one shared map and
    float32 gray."""
    from fpiwarp.backends.gl import batch

    for name in ("CHUNK_BYTES", "SOFTWARE_CHUNK_BYTES"):
        monkeypatch.setattr(batch, name, 1)
    monkeypatch.setattr(batch, "SINGLE_SOURCE_TEXTURE", single_texture)
    sizes = []
    real = batch.draw_group
    monkeypatch.setattr(batch, "draw_group", lambda w, p, s, b, idx, *a: sizes.append(len(idx)) or
                        real(w, p, s, b, idx, *a))
    w = make_gl_warper()
    rgb = rng.integers(0, 256, size=(3, 11, 13, 3), dtype=np.uint8)
    maps = [make_map(kind, k, 13, 11) for k, kind in enumerate(["fpi", "tps", "fpi"])]
    for options in ({"order": 1, "mode": "constant", "cval": np.array([7.0, 0.0, 255.0])},
                    {"order": 1, "mode": "wrap", "cval": np.zeros(3)},
                    {"order": 3, "mode": "reflect", "cval": np.zeros(3)}):
        got, expected = run(w, rgb, maps, (9, 15), **options)
        np.testing.assert_array_equal(got, expected)
    got, expected = run(w, rgb, maps[:1], (12, 10), order=1, mode="edge", cval=np.zeros(3))
    np.testing.assert_array_equal(got, expected)
    gray = rng.uniform(-1, 2, size=(2, 9, 8, 1)).astype(np.float32)
    got, expected = run(w, gray, maps[1:], (7, 9), order=0, mode="edge", cval=np.zeros(1))
    np.testing.assert_array_equal(got, expected)
    assert sizes and set(sizes) == {1}
    assert any("FPW_BATCH_SINGLE" in key.flags for key in w.programs.programs) == single_texture


@pytest.mark.parametrize("software", [True, False])
def test_images_drawn_alone_from_a_size_on(make_gl_warper, monkeypatch, software):
    """A software rasterizer draws each image alone from SOFTWARE_ALONE_BYTES
    of source and output on, below in chunks of SOFTWARE_CHUNK_BYTES; other
    drivers fill CHUNK_BYTES."""
    from fpiwarp.backends.gl import batch

    monkeypatch.setattr(batch, "software_rasterizer", lambda ctx: software)
    w = make_gl_warper()
    side = 64
    while (2 * side * side) * 4 < batch.SOFTWARE_ALONE_BYTES:
        side += 1
    alone, below = batch.images_per_draw(w, (side, side, 3), (side, side), 1), batch.images_per_draw(
        w, (side - 1, side - 1, 3), (side - 1, side - 1), 1)
    chunk = batch.SOFTWARE_CHUNK_BYTES if software else batch.CHUNK_BYTES
    assert 1 < below <= chunk // (2 * (side - 1) ** 2 * 4)
    assert (alone == 1) == software


@pytest.mark.parametrize("case", ["tiled source", "no storage buffers"])
def test_image_by_image_fallbacks(make_gl_warper, rng, monkeypatch, case):
    from fpiwarp.backends.gl import batch

    w = make_gl_warper(max_texture_size=8)
    if case == "no storage buffers":
        monkeypatch.setattr(batch, "supports_batches", lambda ctx: False)
    size = (11, 10) if case == "tiled source" else (6, 7)
    stack = rng.integers(0, 256, size=(3, *size, 1), dtype=np.uint8)
    maps = [make_map(kind, k, 8, 8) for k, kind in enumerate(["fpi", "shift", "tps"])]
    monkeypatch.setattr(batch, "draw_group", None)  # never drawn as a batch
    got, expected = run(w, stack, maps, (5, 6), order=1, mode="edge", cval=np.zeros(1))
    np.testing.assert_array_equal(got, expected)


def test_the_callers_framebuffer_stays_bound(make_gl_warper, rng):
    from fpiwarp.backends.gl import batch
    from fpiwarp.backends.gl.context import bound_framebuffer

    w = make_gl_warper()
    fbo = w.ctx.simple_framebuffer((4, 4))
    try:
        fbo.use()
        stack = rng.integers(0, 256, size=(2, 5, 6, 3), dtype=np.uint8)
        run(w, stack, [make_map("fpi", 0, 8, 8)], (5, 6), order=1, mode="edge", cval=np.zeros(3))
        assert bound_framebuffer(w.ctx).glo == fbo.glo
        w.targets.dummy.use()  # one of the warper's own: never a cached target after the batch
        batch.warp_batch(w, stack, [make_map("fpi", 0, 8, 8).inverse.params()], (5, 6), order=1, mode="edge",
                         cval=np.zeros(3))
        assert bound_framebuffer(w.ctx) is w.targets.dummy
    finally:
        w.ctx.detect_framebuffer(0).use()
        fbo.release()


def test_maps_whose_single_warp_splits_its_band_are_drawn_image_by_image(make_gl_warper, rng, monkeypatch):
    """A seeded map whose first stage has a Newton core and regions draws its
    band apart when warped alone (fpiwarp/backends/gl/band.py); the instanced
    draw cannot, so a batch warps those maps image by image (the loop's
    result) and the others in instanced draws."""
    from support.batch_cases import local_map

    from fpiwarp.backends.gl import batch
    from fpiwarp.block.many import BlockStack

    stack = rng.integers(0, 256, size=(4, 60, 90, 3), dtype=np.uint8)
    maps = [local_map(0, 90, 60), make_map("fpi", 1, 90, 60), local_map(2, 90, 60), make_map("fpi", 3, 90, 60)]
    blocks = BlockStack.of([t.inverse for t in maps])
    assert [batch.splits(b) for b in blocks.blocks()] == [True, False, True, False]
    monkeypatch.setattr(batch.coarse, "picks", lambda *a, **k: True)  # the pass taken: the band split applies
    draws = recorded_draws(batch, monkeypatch)
    got, expected = run(make_gl_warper(), stack, maps, (60, 90), order=1, mode="constant", cval=np.zeros(3))
    np.testing.assert_array_equal(got, expected)
    assert sorted(draws) == [[1, 3]]
