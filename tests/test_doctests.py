"""The examples in the core docstrings run and say what they show."""

import doctest

import pytest

from fpiwarp import _fpi, _linear, _mobius


@pytest.mark.parametrize("module", [_fpi, _linear, _mobius])
def test_docstring_examples(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
