"""The ``fpiwarp`` command.

* :mod:`.commands`: the entry point :func:`main` and each subcommand;
* :mod:`.arguments`: the command line's words turned into the library's
  arguments (points, specs, output paths).

The progress bar of folder batches is :mod:`fpiwarp.batch.progress`.
"""

from .commands import main

__all__ = ["main"]
