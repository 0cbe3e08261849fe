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
