"""Atomic writes: a crash or Ctrl-C leaves either no file or the complete one.

The data goes into a hidden temporary file in the output folder, which is
then renamed over the final name in one step. An existing file is never
replaced unless asked for, even one that appears while writing. Errors name
the user's path and the real problem, never the temporary file.

Something that is not a regular file is never replaced, even with
``overwrite``: a FIFO, a character or block device (``/dev/null``), a
socket (:class:`~fpiwarp.OutputIsSpecialFileError`), a folder
(:class:`~fpiwarp.OutputIsFolderError`). A symbolic link is followed: one
to a regular file gets the new content written to its target, atomically,
and stays a link (with ``overwrite``); one to a special file or a folder is
refused like its target; a dangling one is refused.
"""

import errno
import os
import secrets
import stat
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from ..errors import OutputExistsError, OutputIsFolderError, OutputIsSpecialFileError

#: Suffix of the temporary files; batches skip files that end in it.
TEMP_SUFFIX = ".fpiwarp-tmp"


def is_temp_file(path: str | os.PathLike) -> bool:
    """True for the temporary files write_image creates (and removes)."""
    name = Path(path).name
    return name.startswith(".") and name.endswith(TEMP_SUFFIX)


_SPECIAL_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def special_kind(mode: int) -> str | None:
    """ "a FIFO (named pipe)", "a character device", ... for the ``st_mode``
    of something that is neither a regular file nor a folder; else None."""
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return next((kind for test, kind in _SPECIAL_KINDS if test(mode)), "not a regular file")


def _existing_kind(path):
    """How ``path`` exists: None (it does not), "file", "folder", or the
    special kind of what it is or (a symbolic link) points to; a dangling
    link is "a symbolic link to nothing"."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "a symbolic link to nothing" if os.path.islink(path) else None
    except OSError:
        return None  # unreadable: the write itself reports it
    if stat.S_ISDIR(st.st_mode):
        return "folder"
    kind = special_kind(st.st_mode)
    if kind is not None and os.path.islink(path):
        return f"a symbolic link to {kind}"
    return kind or "file"


def check_output(path: str | os.PathLike, *, overwrite: bool = False) -> None:
    """Raise if ``path`` cannot become an output file: OutputIsFolderError
    for a folder, OutputIsSpecialFileError for a FIFO, device, socket (or a
    link to one, or a dangling link), even with ``overwrite``;
    OutputExistsError for an existing file without ``overwrite``;
    FileNotFoundError when its folder does not exist."""
    path = Path(path)
    kind = _existing_kind(path)
    if kind == "folder":
        raise OutputIsFolderError(path)
    if kind not in (None, "file"):
        raise OutputIsSpecialFileError(path, kind)
    if not overwrite and kind is not None:
        raise OutputExistsError(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(errno.ENOENT, "output folder does not exist", str(path.parent))


def _target(path):
    """Where the new file goes: ``path``, or the regular file a symbolic
    link at ``path`` points to (the link stays)."""
    return Path(os.path.realpath(path)) if os.path.islink(path) else path


def atomic_write(path: str | os.PathLike, write: Callable[[BinaryIO], object], *, overwrite: bool = False) -> None:
    """Call ``write(file)`` on a temporary file next to ``path``, then move
    it to ``path`` in one rename. Without ``overwrite`` an existing
    ``path`` is never replaced (OutputExistsError), even if it appears
    while writing. The temporary file is removed on every error, including
    KeyboardInterrupt; an error of the file system names ``path``."""
    given = Path(path)
    check_output(given, overwrite=overwrite)
    path = _target(given)
    try:
        fd, tmp = _create_temp_file(path)
    except OSError as exc:
        raise _about_output(given, exc) from None
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
            raise _about_output(given, exc) from None
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
    kind = _existing_kind(path)  # again: it may have changed while writing
    if kind == "folder":
        raise OutputIsFolderError(path)
    if kind not in (None, "file"):
        raise OutputIsSpecialFileError(path, kind)
    os.replace(tmp, path)


def _rename_no_clobber(tmp, path):
    try:
        os.link(tmp, path)  # fails if path exists: no window to clobber it
    except FileExistsError:
        kind = _existing_kind(path)
        if kind == "folder":
            raise OutputIsFolderError(path) from None
        if kind not in (None, "file"):
            raise OutputIsSpecialFileError(path, kind) from None
        raise OutputExistsError(path) from None
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
    if isinstance(exc, (OutputExistsError, OutputIsFolderError, OutputIsSpecialFileError)) or exc.errno is None:
        return exc
    named = exc.filename
    if named is not None and not is_temp_file(named) and str(named) != str(path.parent):
        return exc
    return OSError(exc.errno, f"cannot write the output: {exc.strerror}", str(path))
