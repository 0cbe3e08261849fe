"""Reading and writing image files without losing pixels, metadata or files.

``read_image(path)`` returns an array in one of the layouts
:func:`fpiwarp.warp_image` takes (uint8, uint16 or float32; (H, W) gray or
(H, W, C) with C = 2 gray+alpha, 3 RGB, 4 RGBA or CMYK) and an
:class:`ImageInfo` with what is needed to write the result back the same
way: format, color mode and metadata (ICC profile, EXIF, resolution, PNG
text and color chunks, JPEG quantization tables, TIFF compression).
``write_image(path, array, info)`` writes atomically: into a temporary file
in the output folder, then renamed over the final name, so that a crash or
Ctrl-C leaves either no file or the complete one. An existing file is kept
unless ``overwrite=True``.

Pillow reads and writes every format it knows; 16-bit colour PNG and TIFF
(which Pillow would reduce to 8 bits) need the ``io`` extra
(``imagecodecs`` and ``tifffile``). Images above ``max_pixels`` (default
:data:`MAX_PIXELS`) are refused from their header, before decoding. The
parts live in modules of their own: ``_io_formats`` (what each format
stores), ``_io_png``, ``_io_pillow``, ``_io_tiff`` (codecs),
``_io_orientation`` (EXIF orientation) and ``_io_atomic`` (atomic writes);
their errors are fpiwarp's own (``ImageError``, ``OutputExistsError``,
``OutputIsFolderError``).
"""

import os
from pathlib import Path

import numpy as np

from ._errors import ImageError, OutputExistsError, OutputIsFolderError
from ._io_atomic import TEMP_SUFFIX, atomic_write, check_output, is_temp_file
from ._io_formats import (
    INSTALL_IO,
    MAX_PIXELS,
    ImageInfo,
    check_writable,
    format_for_path,
    have_pillow,
    is_16_bit_colour,
    layout,
    pillow_mode,
)
from ._io_orientation import ORIENTATIONS, apply_orientation, check_choice
from ._io_pillow import open_checked, read_pillow, write_pillow
from ._io_png import PNG_SIGNATURE, encode_png, png_chunks, read_png
from ._io_tiff import is_tiff, read_tiff, write_tiff16

__all__ = [
    "INSTALL_IO",
    "MAX_PIXELS",
    "ORIENTATIONS",
    "PNG_SIGNATURE",
    "TEMP_SUFFIX",
    "ImageError",
    "ImageInfo",
    "OutputExistsError",
    "OutputIsFolderError",
    "atomic_write",
    "check_output",
    "check_writable",
    "format_for_path",
    "have_pillow",
    "is_temp_file",
    "png_chunks",
    "read_image",
    "write_image",
]


def read_image(
    path: str | os.PathLike, *, orientation: str = "apply", max_pixels: int = MAX_PIXELS
) -> tuple[np.ndarray, ImageInfo]:
    """Read an image file; return (array, ImageInfo).

    ``orientation="apply"`` (the default) turns the pixels as the EXIF
    Orientation tag says, as viewers and OpenCV show them, and removes the
    tag from the returned metadata; ``"stored"`` returns the pixels as
    stored and keeps the tag (``info.orientation`` then says what a viewer
    would do). An image of more than ``max_pixels`` pixels (default
    :data:`MAX_PIXELS`, Pillow's limit) is refused from its header, before
    decoding. Raises FileNotFoundError for a missing file and ImageError
    for a file that is not an image, is corrupt, is too large, or cannot
    be read without loss.
    """
    check_choice(orientation)
    path = Path(path)
    if path.is_dir():
        raise ImageError(f"{path}: is a folder, not an image file")
    with open(path, "rb") as f:
        head = f.read(len(PNG_SIGNATURE))
    if head == PNG_SIGNATURE:
        array, info, tag = read_png(path, path.read_bytes(), max_pixels)
    elif is_tiff(head):
        array, info, tag = read_tiff(path, max_pixels)
    else:
        with open_checked(path, max_pixels) as im:
            array, info, tag = read_pillow(path, im)
    return apply_orientation(array, info, tag, orientation)


def write_image(path: str | os.PathLike, array, info: ImageInfo | None = None, *, overwrite: bool = False) -> None:
    """Write ``array`` to ``path`` atomically, in the format its extension
    names, with the metadata of ``info`` (from :func:`read_image`) where the
    format allows. Raises ImageError when the format cannot store the
    array, OutputExistsError when ``path`` exists and not ``overwrite``,
    OutputIsFolderError when it is a folder."""
    array = np.asarray(array)
    dtype, channels = layout(array, path)
    fmt = check_writable(path, dtype, channels, info)
    mode = pillow_mode(dtype, channels, info)
    if fmt == "PNG":
        data = encode_png(path, array, mode, info)
        atomic_write(path, lambda f: f.write(data), overwrite=overwrite)
    elif fmt == "TIFF" and is_16_bit_colour(dtype, channels):
        atomic_write(path, lambda f: write_tiff16(f, array, info), overwrite=overwrite)
    else:
        atomic_write(path, lambda f: write_pillow(path, f, array, fmt, mode, info), overwrite=overwrite)
