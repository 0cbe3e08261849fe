"""Every error fpiwarp raises on purpose, under one base: :class:`FpiwarpError`.

Catch ``fpiwarp.FpiwarpError`` to handle any mistake in what was asked of
fpiwarp (a bad argument, a degenerate quad, an unreadable image, a backend
that cannot run here); anything else that escapes fpiwarp is a bug. Each
class keeps the standard exception it was before as a second base
(``ValueError``, ``TypeError``, ``RuntimeError``, ``FileExistsError``,
``ArithmeticError``, ``ImportError``), so ``except ValueError`` still
catches what it caught. Messages are one line naming the argument, field
or file and the problem.

>>> import fpiwarp
>>> try:
...     fpiwarp.FPI([[0, 0], [1, 0], [2, 0], [0, 1]], [[0, 0], [1, 0], [1, 1], [0, 1]])
... except fpiwarp.FpiwarpError as exc:
...     print(type(exc).__name__, isinstance(exc, ValueError))
DegenerateQuadError True
"""

import errno
from pathlib import Path

__all__ = [
    "ArgumentError",
    "ArgumentTypeError",
    "BackendUnavailableError",
    "ConstraintError",
    "DegenerateQuadError",
    "DeviceMismatchError",
    "FoldOverError",
    "FpiwarpError",
    "IllConditionedPairError",
    "ImageError",
    "InverseNotConvergedError",
    "MissingDependencyError",
    "OutputExistsError",
    "OutputIsFolderError",
    "OutputIsSpecialFileError",
    "SizeLimitError",
    "SpecError",
    "ThreadOwnershipError",
]


class FpiwarpError(Exception):
    """Base of every error fpiwarp raises on purpose: the input or the
    environment, not fpiwarp, is at fault, and the message says how."""


class ArgumentError(FpiwarpError, ValueError):
    """An argument of the right type with a value fpiwarp cannot use (an
    unknown order, mode or backend, a non-positive output size, ...)."""


class ArgumentTypeError(FpiwarpError, TypeError):
    """An argument of a type fpiwarp does not take (a list for an image, a
    float for an order, a string for a map, ...)."""


class DeviceMismatchError(ArgumentError):
    """An array and a backend (or two arrays) that cannot meet without a
    host copy: a CUDA tensor for a CPU-only backend, a pyopencl array of
    another context, a texture for another backend; the message says
    which backend to use or where to copy the data."""


class SizeLimitError(ArgumentError):
    """An image, output or point set beyond a limit of fpiwarp or of the
    chosen backend; the message names the size and the limit."""


class DegenerateQuadError(FpiwarpError, ValueError):
    """Four points that cannot define an orientation-preserving 4-point map.

    Raised for wrong shapes, NaN or inf, coincident points, three collinear
    points, zero area, self-intersecting (bow-tie) quads, and for a source
    and target of opposite orientation. The message names the problem.
    """


class IllConditionedPairError(DegenerateQuadError):
    """A quad pair valid on paper whose map float64 cannot build exactly
    (thin quads, large distortion): the message names the measured error
    and the limit."""


class ConstraintError(FpiwarpError, ValueError):
    """Edge constraints of a :class:`~fpiwarp.ConstrainedFPI` (or a local
    deformation) that no map can satisfy, or options out of range."""


class FoldOverError(ConstraintError):
    """A constrained map that is not one-to-one over its region of interest:
    its Jacobian determinant changes sign there (the message says where)."""


class BackendUnavailableError(FpiwarpError, RuntimeError):
    """A backend was asked for that cannot run here; the message says why
    and which extra to install."""


class ThreadOwnershipError(FpiwarpError, RuntimeError):
    """A thread-bound resource (the gl backend's OpenGL context) used from a
    thread that does not own it; the message says how to hand it over."""


class MissingDependencyError(FpiwarpError, ImportError):
    """An optional Python package a feature needs is not installed; the
    message names the feature and the package to install."""


class InverseNotConvergedError(FpiwarpError, ArithmeticError):
    """A numerical inverse did not reach its tolerance; no silent wrong answer."""


class ImageError(FpiwarpError, ValueError):
    """A file that is not an image fpiwarp can read, or an array that the
    chosen format cannot store; the message names the file and the problem."""


class OutputExistsError(FpiwarpError, FileExistsError):
    """The output file exists and overwriting was not asked for."""

    def __init__(self, path):
        super().__init__(errno.EEXIST, "file exists", str(path))

    def __str__(self):
        return f"{self.filename} already exists (pass overwrite=True to replace it)"


class OutputIsFolderError(FpiwarpError, IsADirectoryError):
    """The output path names a folder: no image can be written there, with or
    without overwriting."""

    def __init__(self, path):
        super().__init__(errno.EISDIR, "the output is a folder, not a file name", str(path))

    def __str__(self):
        example = Path(self.filename) / "out.png"
        return f"{self.filename} is a folder; give the output a file name (such as {example})"


class OutputIsSpecialFileError(FpiwarpError, FileExistsError):
    """The output path names something that is not a regular file (a FIFO,
    a character or block device such as /dev/null, a socket, or a symbolic
    link to one): fpiwarp never replaces it, with or without overwriting."""

    def __init__(self, path, kind):
        super().__init__(errno.EEXIST, f"the output is {kind}, not a regular file", str(path))
        self.kind = kind

    def __str__(self):
        return (f"{self.filename} is {self.kind}, not a regular file; fpiwarp never replaces it "
                "(even with overwrite): give the output another name")


class SpecError(FpiwarpError, ValueError):
    """An invalid spec file; the message names the file, the field and the problem."""


# Reported as fpiwarp.Name (in tracebacks, reprs and docs), where they are
# exported, not as this private module.
for _cls in (globals()[_name] for _name in __all__):
    _cls.__module__ = "fpiwarp"
del _cls
