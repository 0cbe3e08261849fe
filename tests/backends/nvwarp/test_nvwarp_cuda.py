"""Device-array batches on CUDA (benchmarks/gpu_batches.py's checks): Warp
stacks on cuda:0 in one launch per kind with out= in place and no
readback, numpy stacks through the CUDA chunks, point batches, torch
(B, C, H, W) and CuPy stacks. Skipped without a GPU (and torch / CuPy);
on Warp's CPU device the same checks run to test their own logic."""

import pytest

from benchmarks import gpu_batches


@pytest.mark.parametrize("name", list(gpu_batches.CHECKS))
def test_on_cuda(warp_backend, name):
    try:
        gpu_batches.CHECKS[name]()
    except gpu_batches.Skip as skip:
        pytest.skip(str(skip))


@pytest.mark.parametrize("name", [n for n in gpu_batches.CHECKS if "torch" not in n and "CuPy" not in n])
def test_the_checks_on_the_cpu_device(warp_backend, monkeypatch, name):
    """Where the warp backend runs on the CPU, the checks' logic (references,
    launch counts, pointers, no readback) against the CPU device."""
    from fpiwarp.backends import get_backend

    if not get_backend("warp").device.is_cpu:
        pytest.skip("the warp backend runs on a GPU: test_on_cuda covers it")
    monkeypatch.setenv(gpu_batches.ON_CPU_ENV, "1")
    gpu_batches.CHECKS[name]()


@pytest.mark.parametrize("transfer", ["serial", "pipelined"])
def test_the_cuda_host_paths_logic_on_the_cpu_device(warp_backend, rng, monkeypatch, transfer):
    """The CUDA branch of a numpy batch (chunks copied in and out; pipelined:
    two slots of pinned staging and streams, drained before reuse) run by a
    runner that treats Warp's CPU device as a device with copies, streams
    stood in for: the loop's result bit for bit, at chunks of one image."""
    import contextlib

    import numpy as np
    from support.batch_cases import loop, make_map

    from fpiwarp.backends import get_backend
    from fpiwarp.backends.nvwarp import batch as warp_batches

    be = get_backend("warp")
    if not be.device.is_cpu:
        pytest.skip("the warp backend runs on a GPU: test_on_cuda covers it")
    wp = be.batches().wp

    class FakeStream:
        def __init__(self, device):
            pass

        def record_event(self):
            return None

    copy = wp.copy
    monkeypatch.setattr(wp, "Stream", FakeStream)
    monkeypatch.setattr(wp, "ScopedStream", lambda stream: contextlib.nullcontext())
    monkeypatch.setattr(wp, "synchronize_event", lambda event: None)
    monkeypatch.setattr(wp, "copy", lambda dst, src, stream=None, **kw: copy(dst, src, **kw))
    real_empty = wp.empty
    monkeypatch.setattr(wp, "empty", lambda *a, pinned=False, **kw: real_empty(*a, **kw))
    monkeypatch.setattr(warp_batches, "CHUNK_BYTES", 1)
    monkeypatch.setattr(warp_batches, "PIPELINE_CHUNK_BYTES", 1)
    runner = warp_batches.BatchRunner(be, on_cpu=False)
    stack = rng.integers(0, 256, size=(5, 9, 11, 3), dtype=np.uint8)
    maps = [make_map(kind, k, 11, 9) for k, kind in enumerate(["fpi", "tps", "shift", "fpi", "compound"])]
    for transforms in (maps, maps[:1]):
        got = runner.warp_batch(stack, list(transforms), (8, 12), order=1, mode="edge", cval=np.zeros(3),
                                transfer=transfer)
        np.testing.assert_array_equal(got, loop(stack, transforms if len(transforms) > 1 else transforms[0], "warp",
                                                {"output_shape": (8, 12), "mode": "edge"}))
    with pytest.raises(ValueError, match="transfer must be one of"):
        runner.warp_batch(stack, maps, (8, 12), order=1, mode="edge", cval=np.zeros(3), transfer="teleport")
