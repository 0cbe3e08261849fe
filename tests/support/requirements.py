"""Backends a test needs: skip with the reason in a developer run, fail in CI.

FPIWARP_REQUIRE_BACKENDS (CI sets "opencl,warp,gl") lists the backends whose
tests must run: for those, a backend that cannot run fails the test.
"""

import os

import pytest

from fpiwarp.backends import backend_status


def required_backends():
    value = os.environ.get("FPIWARP_REQUIRE_BACKENDS", "")
    return {name.strip() for name in value.split(",") if name.strip()}


def use_backend(name):
    """Return the backend name if it can run; else skip (or fail if required)."""
    reason = backend_status()[name]
    if reason is not None:
        message = f"backend {name!r} unavailable: {reason}"
        if name in required_backends():
            pytest.fail(message + " (required by FPIWARP_REQUIRE_BACKENDS)")
        pytest.skip(message)
    return name
