"""What each image format can store, and which codec reads and writes it.

Pillow (a core dependency) reads and writes every format it knows with 8-bit
samples, and 16-bit gray and float32 gray where the format has them. Pillow
reduces 16-bit colour (gray+alpha, RGB, RGBA) to 8 bits, so those go through
the ``io`` extra instead: ``imagecodecs`` (libpng) for PNG and ``tifffile``
for TIFF. Anything that cannot be stored without loss is refused up front,
before any warping, with a message naming the file.
"""

import contextlib
import importlib
import os
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import DTypeLike
from PIL import Image

from ..errors import ImageError, OutputIsFolderError

#: Default largest image read, in pixels: where Pillow itself refuses an
#: image (twice its warning size, 178,956,970 px, e.g. 16384×10922).
#: Checked from the file's header before any pixel is decoded, for every
#: format and codec, so that a small file declaring a huge size (a
#: decompression bomb) is refused at once; ``read_image(max_pixels=...)``
#: raises or lowers it for one call.
MAX_PIXELS = 2 * (1024 * 1024 * 1024 // 4 // 3)

#: The ``io`` extra: what 16-bit colour PNG and TIFF need.
INSTALL_IO = "pip install 'fpiwarp[io]'"


@dataclass
class ImageInfo:
    """How an image was stored, so that its warped copy is stored alike.

    ``mode`` is the Pillow mode name ("L", "LA", "RGB", "RGBA", "CMYK",
    "I;16", "F") or "LA;16", "RGB;16", "RGBA;16" for 16-bit colour.
    ``png_chunks`` holds the input's ancillary PNG chunks (type, data) that
    stay valid for a warped copy; ``ihdr`` the input's PNG (bit depth,
    color type), which decides whether tRNS and sBIT may be kept.
    ``orientation`` is the EXIF orientation the returned pixels still need
    for display: 1 once :func:`read_image` applied it.
    """

    format: str | None = None
    mode: str | None = None
    icc_profile: bytes | None = None
    exif: bytes | None = None
    dpi: tuple | None = None
    png_chunks: list = field(default_factory=list)
    ihdr: tuple | None = None
    jpeg_qtables: object = None
    jpeg_subsampling: int | None = None
    tiff_compression: str | None = None
    orientation: int = 1


def have_pillow() -> bool:
    """True when Pillow can be imported (always, in a complete install:
    Pillow is a core dependency); kept for code written when it was optional."""
    try:
        import PIL.Image  # noqa: F401
    except ImportError:
        return False
    return True


def check_pixel_count(path, width, height, max_pixels):
    """Raise ImageError if a ``width``×``height`` image exceeds
    ``max_pixels``; called with the header's size before decoding."""
    if width * height > max_pixels:
        raise ImageError(
            f"{path}: image of {width}×{height} = {width * height:,} pixels exceeds the limit of "
            f"{max_pixels:,} pixels (a decompression bomb, or too large to warp in memory)"
        )


_STDERR_LOCK = threading.Lock()


@contextlib.contextmanager
def quiet_stderr():
    """File descriptor 2 sent to a temporary file (and dropped) while a C
    codec runs: libpng writes its warnings there, where no Python code can
    catch them. The damage they report is detected before decoding."""
    with _STDERR_LOCK:
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError, AttributeError):
            yield
            return
        try:
            with tempfile.TemporaryFile() as sink:
                os.dup2(sink.fileno(), 2)
                try:
                    yield
                finally:
                    os.dup2(saved, 2)
        finally:
            os.close(saved)


def optional_codec(module, path, what):
    """Import ``module`` ("imagecodecs" or "tifffile"), or raise ImageError
    naming ``path``, what needs it, and the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImageError(f"{path}: {what} needs the {module} package: {INSTALL_IO}") from None


_EXTENSIONS = {
    ".png": "PNG",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".jpe": "JPEG",
    ".tif": "TIFF",
    ".tiff": "TIFF",
}


def format_for_path(path: str | os.PathLike) -> str:
    """The format name ("PNG", "JPEG", "TIFF", ...) that ``path``'s
    extension asks for; ImageError if it names none."""
    ext = Path(path).suffix.lower()
    if ext in _EXTENSIONS:
        return _EXTENSIONS[ext]
    fmt = Image.registered_extensions().get(ext)
    if fmt is not None and fmt in Image.SAVE:
        return fmt
    raise ImageError(f"{path}: cannot tell the image format from the extension {ext or '(none)'!r}")


def layout(array, path=None):
    """(dtype, channels) of an image array; ImageError for other shapes,
    naming the output ``path`` when given."""
    arr = np.asarray(array)
    if arr.ndim == 2:
        return arr.dtype, 1
    if arr.ndim == 3 and 1 <= arr.shape[2] <= 4:
        return arr.dtype, arr.shape[2]
    where = f"{path}: " if path is not None else ""
    raise ImageError(f"{where}an image array must be (H, W) or (H, W, C) with C in 1..4, got shape {arr.shape}")


def is_16_bit_colour(dtype, channels):
    """True for the layouts Pillow cannot store: 16-bit with 2-4 channels."""
    return np.dtype(dtype) == np.uint16 and channels > 1


def pillow_mode(dtype, channels, info):
    """The Pillow mode that stores (dtype, channels) without loss, or None."""
    dtype = np.dtype(dtype)
    if dtype == np.uint8:
        if channels == 4 and info is not None and info.mode == "CMYK":
            return "CMYK"
        return {1: "L", 2: "LA", 3: "RGB", 4: "RGBA"}[channels]
    if dtype == np.uint16 and channels == 1:
        return "I;16"
    if dtype == np.float32 and channels == 1:
        return "F"
    return None


_DTYPE_NAMES = {np.dtype(np.uint8): "8-bit", np.dtype(np.uint16): "16-bit", np.dtype(np.float32): "float32"}
_CHANNEL_NAMES = {1: "gray", 2: "gray+alpha", 3: "RGB", 4: "RGBA"}
_PILLOW_MODES_BY_FORMAT = {
    "PNG": {"L", "LA", "RGB", "RGBA", "I;16"},
    "JPEG": {"L", "RGB", "CMYK"},
    "TIFF": {"L", "LA", "RGB", "RGBA", "CMYK", "I;16", "F"},
}
#: Formats that store 16-bit colour through the ``io`` extra, and its codec.
COLOUR_16_CODECS = {"PNG": "imagecodecs", "TIFF": "tifffile"}


def describe(dtype, channels):
    """ "16-bit RGB", "8-bit gray+alpha", ... for messages."""
    dtype = np.dtype(dtype)
    return f"{_DTYPE_NAMES.get(dtype, str(dtype))} {_CHANNEL_NAMES.get(channels, f'{channels}-channel')}"


def check_writable(path: str | os.PathLike, dtype: DTypeLike, channels: int, info: ImageInfo | None = None) -> str:
    """Raise ImageError if the format of ``path`` cannot store an image of
    this dtype and channel count without loss (or needs a codec that is not
    installed), OutputIsFolderError if ``path`` is a folder; return the
    format name."""
    if Path(path).is_dir():
        raise OutputIsFolderError(path)
    fmt = format_for_path(path)
    dtype = np.dtype(dtype)
    if is_16_bit_colour(dtype, channels) and fmt in COLOUR_16_CODECS:
        optional_codec(COLOUR_16_CODECS[fmt], path, f"writing 16-bit colour {fmt}")
        return fmt
    mode = pillow_mode(dtype, channels, info)
    allowed = _PILLOW_MODES_BY_FORMAT.get(fmt)
    if mode == "CMYK" and allowed is not None and mode not in allowed:
        raise ImageError(f"{path}: {fmt} cannot store CMYK images (the info says CMYK); pass info=None to write "
                         "the 4 channels as RGBA, or convert the pixels to RGB first")
    if mode is None or (allowed is not None and mode not in allowed):
        hint = "; use .tif" if dtype == np.float32 and fmt != "TIFF" else "; use .png" if fmt != "PNG" else ""
        raise ImageError(f"{path}: {fmt} cannot store {describe(dtype, channels)} images{hint}")
    return fmt
