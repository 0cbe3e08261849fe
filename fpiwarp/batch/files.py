"""One file of a batch: read, warp, write, and the one-line reason it failed.

Shared by the folder runs in threads (:mod:`fpiwarp.batch.folders`) and
on a Dask cluster (:mod:`fpiwarp.batch.dask`).
"""

from dataclasses import dataclass

from ..errors import FpiwarpError, OutputExistsError
from ..io.images import check_writable, read_image, write_image

__all__ = ["FILE_ERRORS", "FileOptions", "process_file", "reason_of"]


@dataclass(frozen=True)
class FileOptions:
    """How a batch reads and writes each file: ``overwrite`` outputs that
    exist, and the EXIF ``orientation`` rule of :func:`fpiwarp.read_image`
    ("apply" or "stored")."""

    overwrite: bool = False
    orientation: str = "apply"
    damaged: str = "refuse"


def reason_of(exc):
    """The one-line reason a file failed."""
    text = str(exc)
    if isinstance(exc, OSError) and exc.strerror:
        text = exc.strerror
    return text if isinstance(exc, (FpiwarpError, OSError, ValueError)) else f"{type(exc).__name__}: {text}"


#: What makes one file fail without stopping the batch: fpiwarp's own
#: errors and the operating system's (anything else is a bug, and stops it).
FILE_ERRORS = (FpiwarpError, OSError)


def process_file(src, dst, warper, options):
    """Read, warp and write one file; return (status, input path, reason,
    (width, height) of the input when it was warped)."""
    try:
        if not options.overwrite and dst.is_file():
            return "skipped", str(src), None
        image, info = read_image(src, orientation=options.orientation, with_info=True, damaged=options.damaged)
        dtype, channels = image.dtype, (1 if image.ndim == 2 else image.shape[2])
        check_writable(dst, dtype, channels, info)
        out = warper(image)
        dst.parent.mkdir(parents=True, exist_ok=True)
        write_image(dst, out, info, overwrite=options.overwrite)
        return "done", str(src), None, (image.shape[1], image.shape[0])
    except OutputExistsError:
        return "skipped", str(src), None
    except FILE_ERRORS as exc:
        return "failed", str(src), reason_of(exc)
