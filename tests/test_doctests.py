"""The examples in the docstrings run and say what they show."""

import doctest
import importlib

import pytest

MODULES = ["_fpi", "_linear", "_mobius", "_tps", "_constrained", "_local", "curves", "metrics", "spec"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"fpiwarp.{name}")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
