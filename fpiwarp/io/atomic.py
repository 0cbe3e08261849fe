"""Atomic writes: a crash or Ctrl-C leaves either no file or the complete one.

The data goes into a hidden temporary file in the output folder, which is
then renamed over the final name in one step. An existing file is never
replaced unless asked for, even one that appears while writing. Errors name
the user's path and the real problem, never the temporary file.
"""

import errno
import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from ..errors import OutputExistsError, OutputIsFolderError

#: Suffix of the temporary files; batches skip files that end in it.
TEMP_SUFFIX = ".fpiwarp-tmp"


def is_temp_file(path: str | os.PathLike) -> bool:
    """True for the temporary files write_image creates (and removes)."""
    name = Path(path).name
    return name.startswith(".") and name.endswith(TEMP_SUFFIX)


def check_output(path: str | os.PathLike, *, overwrite: bool = False) -> None:
    """Raise if ``path`` cannot become an output file: OutputIsFolderError
    for a folder, OutputExistsError for an existing file without
    ``overwrite``, FileNotFoundError when its folder does not exist."""
    path = Path(path)
    if path.is_dir():
        raise OutputIsFolderError(path)
    if not overwrite and (path.exists() or path.is_symlink()):
        raise OutputExistsError(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(errno.ENOENT, "output folder does not exist", str(path.parent))


def atomic_write(path: str | os.PathLike, write: Callable[[BinaryIO], object], *, overwrite: bool = False) -> None:
    """Call ``write(file)`` on a temporary file next to ``path``, then move
    it to ``path`` in one rename. Without ``overwrite`` an existing
    ``path`` is never replaced (OutputExistsError), even if it appears
    while writing. The temporary file is removed on every error, including
    KeyboardInterrupt; an error of the file system names ``path``."""
    path = Path(path)
    check_output(path, overwrite=overwrite)
    try:
        fd, tmp = _create_temp_file(path)
    except OSError as exc:
        raise _about_output(path, exc) from None
    try:
        try:
            with os.fdopen(fd, "wb") as f:
                write(f)
                f.flush()
                os.fsync(f.fileno())
            if overwrite:
                _replace(tmp, path)
            else:
                _rename_no_clobber(tmp, path)
        except OSError as exc:
            raise _about_output(path, exc) from None
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _create_temp_file(path):
    """Open a new hidden file next to ``path``. Created with mode 0o666 like
    any new file, so the process umask alone decides its permissions (what
    ``tempfile.mkstemp``'s 0o600 would not give), without reading or
    changing the process-wide umask."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}{TEMP_SUFFIX}"
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(errno.EEXIST, "no unused temporary file name", str(path))


def _replace(tmp, path):
    if path.is_dir():  # became a folder while writing
        raise OutputIsFolderError(path)
    os.replace(tmp, path)


def _rename_no_clobber(tmp, path):
    try:
        os.link(tmp, path)  # fails if path exists: no window to clobber it
    except FileExistsError:
        raise (OutputIsFolderError(path) if path.is_dir() else OutputExistsError(path)) from None
    except OSError:  # file systems without hard links
        if path.exists():
            raise OutputExistsError(path) from None
        os.replace(tmp, path)
        return
    os.unlink(tmp)


def _about_output(path, exc):
    """``exc`` reworded to name ``path`` when it names the temporary file,
    the output folder or no file (a full disk, a read-only file system,
    missing permissions); other errors are returned as they are."""
    if isinstance(exc, (OutputExistsError, OutputIsFolderError)) or exc.errno is None:
        return exc
    named = exc.filename
    if named is not None and not is_temp_file(named) and str(named) != str(path.parent):
        return exc
    return OSError(exc.errno, f"cannot write the output: {exc.strerror}", str(path))
