"""Batches in one launch (opencl, warp; gl: one draw): warp_batch and map_points_batch
equal the per-image loop of warp_image / map_points on the same backend,
bit for bit, for any number of images, shapes, dtypes, channels, orders,
modes, antialiasing and any mix of kinds of map; large batches are split
into bounded launches, never refused."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.batch_cases import KINDS, batches, coarse_switch, local_map, loop, make_map

import fpiwarp
from fpiwarp.backends import get_backend

BATCHING = ["numpy", "opencl", "warp", "gl"]




@pytest.mark.parametrize("backend", BATCHING)
@settings(max_examples=25, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=batches())
def test_batch_equals_the_loop_bit_for_bit(backend, case):
    from support.requirements import use_backend

    use_backend(backend)
    stack, transforms, options = case
    got = fpiwarp.warp_batch(stack, transforms, backend=backend, **options)
    expected = loop(stack, transforms, backend, options)
    assert got.dtype == stack.dtype and got.shape == expected.shape
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("backend", ["opencl", "gl"])
def test_newton_batches_take_the_coarse_pass(backend, rng, monkeypatch, coarse_always):
    """Local deformations (one per image, one shared, mixed with an FPI)
    batched on the backends with a coarse pass (forced: the rule leaves
    maps this small to per-pixel Newton): the loop's result bit for bit,
    which here differs from a per-pixel Newton's (the pass switched off),
    so the batch took the pass for each image's own map."""
    from support.requirements import use_backend

    use_backend(backend)
    stack = rng.integers(0, 256, size=(4, 60, 90, 3), dtype=np.uint8)
    mixed = [local_map(0, 90, 60), make_map("fpi", 1, 90, 60), local_map(2, 90, 60), make_map("tps_inverse", 0, 90, 60)]
    cases = [[local_map(k, 90 + 3 * k, 60) for k in range(4)], local_map(1, 90, 60), mixed]
    for maps in cases:
        expected = loop(stack, maps, backend, {})
        np.testing.assert_array_equal(fpiwarp.warp_batch(stack, maps, backend=backend), expected)
        with monkeypatch.context() as patch:
            patch.setattr(coarse_switch(backend), "COARSE_PASS", False)
            per_pixel = fpiwarp.warp_batch(stack, maps, backend=backend)
        assert (per_pixel != expected).any()


@pytest.mark.parametrize("transfer", ["zero_copy", "zero_copy, copied", "serial", "pipelined"])
def test_opencl_transfers_and_bounded_chunks_equal_the_loop(opencl_backend, transfer, rng, monkeypatch):
    """Chunks of one image and launches of two blocks (tiny bounds forced)
    still give the loop's result, in every way of transferring (zero copy:
    the sources read in place, or copied chunk by chunk as antialiased
    batches' are)."""
    from fpiwarp.backends.opencl import batch as opencl_batch

    if transfer == "zero_copy, copied":
        transfer = "zero_copy"
        monkeypatch.setattr(opencl_batch, "reads_in_place", lambda stack, antialias: False)
    stack = rng.integers(0, 256, size=(5, 13, 17, 3), dtype=np.uint8)
    maps = [make_map(kind, k, 17, 13) for k, kind in enumerate(["fpi", "tps", "fpi", "shift", "tps"])]
    maps[2] = local_map(0, 17, 13)  # a Newton map: its coarse pass per chunk and launch
    backend = get_backend("opencl")
    calls = []
    real = opencl_batch.chunk_ranges
    monkeypatch.setattr(opencl_batch, "chunk_ranges", lambda n, item, limit: calls.append(1) or real(n, item, 1))
    monkeypatch.setattr(opencl_batch, "constant_bytes", lambda be: 2 * 77 * 16)
    got = backend.warp_batch(stack, maps, (11, 19), order=1, mode="edge", cval=np.zeros(3), transfer=transfer)
    assert calls
    np.testing.assert_array_equal(got, loop(stack, maps, "opencl", {"output_shape": (11, 19), "mode": "edge"}))


def test_opencl_batches_read_in_place_only_what_the_kernel_reads_within(opencl_backend, rng):
    """A zero-copy batch reads the caller's stack in place where the kernel
    stays inside each image (C-contiguous, images of 4 bytes or more, not
    antialiased); stacks of 1 x 1 RGB images, read by 32-bit words, are
    copied with slack. Both equal the loop."""
    from fpiwarp.backends.opencl import batch as opencl_batch

    assert opencl_batch.reads_in_place(np.zeros((3, 2, 2, 1), np.uint8), False)
    assert not opencl_batch.reads_in_place(np.zeros((3, 2, 2, 1), np.uint8), True)
    assert not opencl_batch.reads_in_place(np.zeros((3, 1, 1, 3), np.uint8), False)
    assert not opencl_batch.reads_in_place(np.zeros((3, 4, 6, 3), np.uint8)[:, :, ::2], False)
    be = get_backend("opencl")
    stack = np.zeros((64, 64, 64, 3), np.uint8)  # 12 KiB an image
    chunks, in_place = opencl_batch.chunk_plan(be, stack, stack[0].nbytes, "zero_copy")
    assert in_place and [tuple(c) for c in chunks] == [(0, 64)]  # one launch
    per_unit = opencl_batch.ZERO_COPY_CHUNK_BYTES_PER_UNIT * max(1, be.device.max_compute_units)
    for transfer, antialias in [("zero_copy", True), ("pipelined", False)]:
        chunks, in_place = opencl_batch.chunk_plan(be, stack, stack[0].nbytes, transfer, antialias)
        assert not in_place and chunks[0][0] == 0 and chunks[-1][1] == 64
        assert all(a < b == c for (a, b), (c, _) in zip(chunks, chunks[1:]))
        if transfer == "zero_copy":  # copied chunks: the per-unit bound (at least one image)
            assert (chunks[0][1] - chunks[0][0]) * 2 * stack[0].nbytes <= max(per_unit, 2 * stack[0].nbytes)
    for shape in [(3, 1, 1, 3), (4, 1, 2, 1), (2, 7, 5, 4)]:
        stack = rng.integers(0, 256, size=shape, dtype=np.uint8)
        maps = [make_map(kind, k, 9, 9) for k, kind in zip(range(shape[0]), ["fpi", "shift", "fpi", "tps"])]
        np.testing.assert_array_equal(fpiwarp.warp_batch(stack, maps, backend="opencl"),
                                      loop(stack, maps, "opencl", {}))


def test_opencl_groups_maps_by_kind():
    from fpiwarp.backends.opencl import batch as opencl_batch

    maps = [make_map(kind, k, 9, 9) for k, kind in enumerate(["fpi", "tps", "shift", "compound", "tps"])]
    from fpiwarp.backends.opencl.backend import kind_options

    groups = opencl_batch.block_groups(maps, len(maps), kind_options)
    assert sorted(sorted(g[3].tolist()) for g in groups) == [[0, 2], [1, 4], [3]]
    one = opencl_batch.block_groups(maps[:1], 6, kind_options)
    assert len(one) == 1 and one[0][1] == 0 and one[0][3].tolist() == list(range(6))


def test_warp_batch_splits_large_batches(warp_backend, rng, monkeypatch):
    from fpiwarp.backends.nvwarp import batch as warp_batches

    monkeypatch.setattr(warp_batches, "CHUNK_BYTES", 1)  # one image per launch
    stack = rng.uniform(0, 1, size=(3, 9, 11, 2)).astype(np.float32)
    maps = [make_map(kind, k, 11, 9) for k, kind in enumerate(["compound", "tps_inverse", "fpi"])]
    np.testing.assert_array_equal(fpiwarp.warp_batch(stack, maps, backend="warp", order=3),
                                  loop(stack, maps, "warp", {"order": 3}))


@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", ["constant", "edge", "reflect", "wrap"])
def test_warp_batch_of_several_kinds_equals_the_loop(warp_backend, rng, monkeypatch, order, mode):
    """Maps of three kinds in one batch (fpi and shift of one kind, not adjacent):
    one launch per kind of the per-kind kernels, the loop's result bit for
    bit in every order and mode."""
    stack = rng.integers(0, 256, size=(4, 12, 15, 3), dtype=np.uint8)
    maps = [make_map(kind, k, 15, 12) for k, kind in enumerate(["fpi", "tps_inverse", "compound", "shift"])]
    runner = get_backend("warp").batches()
    launches = []
    real = runner.launch
    monkeypatch.setattr(runner, "launch", lambda kernel, *args: launches.append(kernel) or real(kernel, *args))
    options = {"order": order, "mode": mode, "cval": 9, "output_shape": (13, 14)}
    got = fpiwarp.warp_batch(stack, maps, backend="warp", **options)
    assert len(launches) == len(set(launches)) == 3
    np.testing.assert_array_equal(got, loop(stack, maps, "warp", options))


def test_warp_groups_maps_by_kind():
    from fpiwarp.backends.nvwarp.batch import kind_groups
    from fpiwarp.block import describe

    maps = [make_map(kind, k, 9, 9) for k, kind in enumerate(["fpi", "tps", "shift", "compound", "tps"])]
    groups = kind_groups(maps, len(maps))
    assert sorted(g[2].tolist() for g in groups) == [[0, 2], [1, 4], [3]]
    for key, blocks, images in groups:
        assert key == tuple((s.core, s.n_regions) for s in describe(maps[images[0]].params()).stages)
        assert blocks.dtype == np.float32 and len(blocks) == len(images)
        for block, i in zip(blocks, images):
            params = np.asarray(maps[i].params(), dtype=np.float32)
            np.testing.assert_array_equal(block[: len(params)], params)
            assert not block[len(params):].any()
    ((_, blocks, images),) = kind_groups(maps[1:2], 6)
    assert len(blocks) == 1 and images.tolist() == list(range(6))


@pytest.mark.parametrize("backend", BATCHING)
@settings(max_examples=15, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(n=st.integers(1, 4), shape=st.sampled_from([(0,), (1,), (7,), (3, 5)]), one=st.booleans(),
       kinds=st.lists(st.sampled_from(KINDS), min_size=4, max_size=4), seed=st.integers(0, 2**32 - 1))
def test_map_points_batch_equals_the_loop(backend, n, shape, one, kinds, seed):
    from support.requirements import use_backend

    use_backend(backend)
    pts = np.random.default_rng(seed).uniform(-20, 40, size=(n, *shape, 2))
    maps = [make_map(kind, k, 20, 15) for k, kind in enumerate(kinds[:n])]
    transforms = maps[0] if one else maps
    try:
        expected = np.stack([fpiwarp.map_points(maps[0] if one else t, p, backend=backend) for t, p in zip(maps, pts)])
    except fpiwarp.FpiwarpError as exc:  # the host inverse of a TPS that does not converge: so must the batch
        with pytest.raises(type(exc)):
            fpiwarp.map_points_batch(transforms, pts, backend=backend)
        return
    got = fpiwarp.map_points_batch(transforms, pts, backend=backend)
    assert got.shape == pts.shape and got.dtype == np.float64
    np.testing.assert_array_equal(got, expected)


def test_map_points_batch_refuses_bad_batches():
    shift = fpiwarp.RLinear(1, 0, 1)
    with pytest.raises(fpiwarp.ArgumentError, match="2 maps for 3 point sets"):
        fpiwarp.map_points_batch([shift, shift], np.zeros((3, 4, 2)))
    with pytest.raises(fpiwarp.ArgumentError, match=r"\(N, \.\.\., 2\)"):
        fpiwarp.map_points_batch(shift, np.zeros(2))
    with pytest.raises(fpiwarp.ArgumentTypeError):
        fpiwarp.map_points_batch([shift, "not a map"], np.zeros((2, 1, 2)))


def test_batch_keeps_the_per_image_limits(opencl_backend):
    """SizeLimitError as warp_image gives it, for the one map of the batch
    that exceeds the backend's stages."""
    from fpiwarp.block import MAX_STAGES

    fpi = make_map("fpi", 0, 10, 10)
    deep = fpi
    for _ in range(MAX_STAGES):
        deep = deep @ fpi
    with pytest.raises(fpiwarp.SizeLimitError, match="stages"):
        fpiwarp.warp_image(np.zeros((4, 4), np.uint8), deep, backend="opencl")
    with pytest.raises(fpiwarp.SizeLimitError, match="stages"):
        fpiwarp.warp_batch(np.zeros((2, 4, 4), np.uint8), [fpi, deep], backend="opencl")
    with pytest.raises(fpiwarp.ArgumentTypeError, match="transforms must be an fpiwarp map .* got str"):
        fpiwarp.warp_batch(np.zeros((2, 4, 4), np.uint8), [fpi, "shift"], backend="opencl")


def test_opencl_refuses_an_unknown_transfer(opencl_backend):
    backend = get_backend("opencl")
    with pytest.raises(ValueError, match="transfer"):
        backend.warp_batch(np.zeros((1, 2, 2, 1), np.uint8), [make_map("fpi", 0, 8, 8)], (2, 2), order=1,
                           mode="edge", cval=np.zeros(1), transfer="teleport")
