"""The errors that reading and writing images raise on purpose.

Each message names the user's file (never a temporary one) and the problem
in one line, so that the command line can print it as it is.
"""

import errno
from pathlib import Path


class ImageError(ValueError):
    """A file that is not an image fpiwarp can read, or an array that the
    chosen format cannot store; the message names the file and the problem."""


class OutputExistsError(FileExistsError):
    """The output file exists and overwriting was not asked for."""

    def __init__(self, path):
        super().__init__(errno.EEXIST, "file exists", str(path))

    def __str__(self):
        return f"{self.filename} already exists (pass overwrite=True to replace it)"


class OutputIsFolderError(IsADirectoryError):
    """The output path names a folder: no image can be written there, with or
    without overwriting."""

    def __init__(self, path):
        super().__init__(errno.EISDIR, "the output is a folder, not a file name", str(path))

    def __str__(self):
        example = Path(self.filename) / "out.png"
        return f"{self.filename} is a folder; give the output a file name (such as {example})"
