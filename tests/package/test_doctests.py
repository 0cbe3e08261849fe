"""The examples in the docstrings run and say what they show.

Modules whose examples draw with OpenGL run where the "gl" backend can
(skipped otherwise, failed when FPIWARP_REQUIRE_BACKENDS lists it).
"""

import doctest
import importlib

import pytest
from support.requirements import use_backend

MODULES = [
    "maps.fpi", "maps.rlinear", "maps.mobius", "maps.thin_plate_spline", "maps.constrained", "maps.local",
    "warping", "maps.transform", "errors", "batch.images", "batch.folders", "batch.points", "sampling.positions",
    "io.images", "backends", "curves", "metrics", "spec", "backends.lru", "testing",
]
GL_MODULES = ["viewer.offscreen", "viewer.renderer"]


def run_examples(name):
    module = importlib.import_module(f"fpiwarp.{name}")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    run_examples(name)


@pytest.mark.parametrize("name", GL_MODULES)
def test_docstring_examples_that_draw(name):
    use_backend("gl")
    run_examples(name)
