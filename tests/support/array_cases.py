"""Shared pieces of the device-array tests (tests/test_arrays*.py).

FPIWARP_REQUIRE_LIBRARIES (comma-separated, CI sets "jax") turns the skip
of a missing optional array library into a failure, as
FPIWARP_REQUIRE_BACKENDS does for backends.
"""

import importlib
import os

import numpy as np
import pytest

import fpiwarp

#: A generic FPI whose pole is far from the test images (up to 48x64).
FPI = fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 3], [60, -2], [66, 50], [-3, 44]])
DTYPES = (np.uint8, np.uint16, np.float32)


def require_library(name):
    """The imported module ``name``; skip (or fail when required) without it."""
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        required = {s.strip() for s in os.environ.get("FPIWARP_REQUIRE_LIBRARIES", "").split(",")}
        if name in required:
            pytest.fail(f"{name} is required by FPIWARP_REQUIRE_LIBRARIES but cannot be imported: {exc}")
        pytest.skip(f"{name} is not installed")


def make_image(rng, shape, dtype):
    """Random pixels over the dtype's range (float32 in [0, 1])."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return rng.random(shape, dtype=np.float32)
    return rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)


class FakeCudaArray:
    """An object that says it lives on CUDA device 0 through DLPack (no data)."""

    def __dlpack_device__(self):
        return (2, 0)

    def __dlpack__(self, stream=None):  # pragma: no cover - never read: refused first
        raise AssertionError("a refused array must not be read")


def fails(*args, **kwargs):
    """Stands in for a host copy or readback that must not happen."""
    raise AssertionError("a host copy was made on a device path")


def forbid_host_copies(monkeypatch, cla, limit):
    """From here on, readbacks fail, and so does any host array of ``limit``
    bytes or more given to enqueue_copy, other than a map's parameter block."""
    import pyopencl as cl

    from fpiwarp.backends.opencl import backend as opencl_backend
    from fpiwarp.block import STAGE_ROWS

    copy = cl.enqueue_copy

    def is_block(a):  # a map's parameter block: float32 rows of vec4, a header row and whole stages
        return a.dtype == np.float32 and a.ndim == 2 and a.shape[1] == 4 and (a.shape[0] - 1) % STAGE_ROWS == 0

    def checked(queue, dest, src, **kw):
        for a in (dest, src):
            assert not (isinstance(a, np.ndarray) and a.nbytes >= limit and not is_block(a)), "a host copy of the image"
        return copy(queue, dest, src, **kw)

    monkeypatch.setattr(opencl_backend.Backend, "_read_back", fails)
    monkeypatch.setattr(cla.Array, "get", fails)
    monkeypatch.setattr(cl, "enqueue_copy", checked)
