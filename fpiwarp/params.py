"""The parameter block under its first name: ``fpiwarp.params`` keeps every
name it always had, now defined in the package :mod:`fpiwarp.block`.

The documented block layout (rows, offsets, evaluation steps) is the
docstring of ``fpiwarp/block/layout.py``; the numpy reference every kernel
mirrors is ``fpiwarp/block/reference.py``.
"""

# Every name of the block package, under its first name (a superset of
# what fpiwarp.params had).
from .block import *  # noqa: F403
from .block import __all__  # noqa: F401
