"""Shared fixtures: backend selection that skips with a reason in a
developer run but fails in CI for the backends CI must test.

Set FPIWARP_REQUIRE_BACKENDS to a comma-separated list (CI sets
"opencl,warp,gl"): a listed backend that cannot run fails the tests
that use it instead of skipping them.

Hypothesis runs under the profile named by HYPOTHESIS_PROFILE: "dev" (the
default) draws new random examples on every run, to keep searching; "ci"
(set by .ci/run) is derandomized, so a landing never fails by the luck of
the draw. Falsifying examples that were found are pinned with @example.
"""

import importlib.util
import os
import tempfile

import numpy as np
import pytest
from hypothesis import settings
from support.requirements import use_backend

# What fpiwarp measures and builds (the fast default's ranking, OpenCL binaries) goes to a folder of this run,
# never to the developer's cache; the fast default is measured once per run, by the first test that needs it.
os.environ.setdefault("FPIWARP_CACHE_DIR", tempfile.mkdtemp(prefix="fpiwarp-test-cache-"))

import fpiwarp  # noqa: E402

# Triton (installed with PyPI's torch) bundles an LLVM whose static
# initialisers crash the process when Mesa's LLVM (llvmpipe, the gl backend
# here) was loaded first; loaded in the other order both work. torch imports
# Triton lazily (e.g. torch.optim), after GL tests ran, so load it first.
# See docs/guides/autodiff.rst, "Known conflicts".
if importlib.util.find_spec("triton") is not None:
    import triton  # noqa: F401

settings.register_profile("dev", deadline=None)
settings.register_profile("ci", deadline=None, derandomize=True, database=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))


@pytest.fixture(params=["numpy", "opencl", "warp", "gl"])
def any_backend(request):
    """Every backend in turn: the numpy reference and each kernel backend."""
    return use_backend(request.param)


@pytest.fixture
def opencl_backend():
    """The name "opencl" if that backend can run (skip, or fail when required)."""
    return use_backend("opencl")


@pytest.fixture
def warp_backend():
    """The name "warp" if that backend can run (skip, or fail when required)."""
    return use_backend("warp")


@pytest.fixture
def gl_backend():
    """The name "gl" if that backend can run (skip, or fail when required)."""
    return use_backend("gl")


@pytest.fixture
def make_gl_warper(gl_backend):
    """Makes GLWarpers (options as GLWarper's) in the shared GL context; all are released afterwards."""
    from fpiwarp.backends.gl.context import shared_context
    from fpiwarp.backends.gl.warper import GLWarper

    made = []

    def make(**options):
        made.append(GLWarper(shared_context(), **options))
        return made[-1]

    yield make
    for w in made:
        w.release()


@pytest.fixture
def coarse_always(monkeypatch):
    """Every Newton map's warp takes the coarse pass (fpiwarp.block.coarse_choice.ALWAYS):
    tests of the pass itself on maps the rule leaves to per-pixel Newton."""
    from fpiwarp.block import coarse_choice

    monkeypatch.setattr(coarse_choice, "ALWAYS", True)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def sample_fpi():
    """A generic FPI with a pole well away from a 64×48 image."""
    return fpiwarp.FPI(
        [[0, 0], [63, 0], [63, 47], [0, 47]],
        [[4, 3], [60, -2], [66, 50], [-3, 44]],
    )
