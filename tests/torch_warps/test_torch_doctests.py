"""The examples in fpiwarp.torch's docstrings run and say what they show."""

import doctest
import importlib

import pytest
from support.torch_cases import require_torch

require_torch()


@pytest.mark.parametrize("name", ["warp", "points", "module"])
def test_docstring_examples(name):
    module = importlib.import_module(f"fpiwarp.torch.{name}")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
