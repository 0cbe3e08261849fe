"""Reading and writing image files without losing pixels, metadata or files.

``read_image(path)`` returns an array in one of the layouts
:func:`fpiwarp.warp_image` takes (uint8, uint16 or float32; (H, W) gray or
(H, W, C) with C = 2 gray+alpha, 3 RGB, 4 RGBA or CMYK), as imageio,
scikit-image, OpenCV and ``np.asarray(PIL.Image.open(path))`` do;
``read_image(path, with_info=True)`` returns ``(array, info)``, an
:class:`~fpiwarp.io.ImageInfo` with what is needed to write the result back the same
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
parts live in the modules of :mod:`fpiwarp.io`: ``formats`` (what each
format stores), ``png``, ``pillow``, ``tiff`` (codecs), ``orientation``
(EXIF orientation) and ``atomic`` (atomic writes);
their errors are fpiwarp's own (``ImageError``, ``OutputExistsError``,
``OutputIsFolderError``).
"""

import os
from pathlib import Path

import numpy as np

from ..errors import ArgumentTypeError, ImageError, OutputExistsError, OutputIsFolderError
from ..validation import refuse_masked, short_repr
from .atomic import TEMP_SUFFIX, atomic_write, check_output, is_temp_file, special_kind
from .formats import (
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
from .orientation import ORIENTATIONS, apply_orientation, check_choice
from .pillow import DAMAGED, check_damaged, open_checked, read_pillow, write_pillow
from .png import PNG_SIGNATURE, encode_png, png_chunks, read_png
from .tiff import is_tiff, read_tiff, write_tiff16

__all__ = [
    "DAMAGED",
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
    path: str | os.PathLike,
    *,
    orientation: str = "apply",
    max_pixels: int = MAX_PIXELS,
    with_info: bool = False,
    damaged: str = "refuse",
) -> np.ndarray | tuple[np.ndarray, ImageInfo]:
    """Read an image file; return its pixels (with ``with_info=True``:
    ``(pixels, info)``, the metadata to write a warped copy alike).

    Pillow (a dependency) decodes every format it knows; 16-bit colour
    (gray+alpha, RGB, RGBA), which Pillow would reduce to 8 bits, goes
    through imagecodecs (PNG) or tifffile (TIFF): ``pip install
    'fpiwarp[io]'``. fpiwarp itself reads a PNG's chunk list (header and
    CRCs checked before any pixel is decoded) to keep its metadata.

    Parameters
    ----------
    path : str or path-like
        The file. Its content, not its extension, says the format.
    orientation : {"apply", "stored"}, optional
        "apply" (the default) turns the pixels as the EXIF Orientation tag
        says, as viewers and OpenCV show them, and removes the tag from the
        returned metadata; "stored" returns the pixels as stored and keeps
        the tag (``info.orientation`` then says what a viewer would do).
    max_pixels : int, optional
        An image of more pixels is refused from its header, before
        decoding; default ``fpiwarp.io.MAX_PIXELS``, Pillow's limit.
    with_info : bool, optional
        Also return the file's :class:`~fpiwarp.io.ImageInfo` (default False: the
        pixels only, like every other image reader).
    damaged : {"refuse", "accept"}, optional
        "refuse" (the default): a file that a forgiving decoder would
        complete with filler is an ImageError naming the file and the
        damage: truncated data, a baseline JPEG smaller than its header's
        size needs (checked before decoding), PNG pixel data shorter or
        longer than its header says. "accept" decodes what is there
        (Pillow's ``LOAD_TRUNCATED_IMAGES`` while it decodes; the rest of
        the picture is the decoder's filler). Either way no codec warning
        reaches stderr.

    Returns
    -------
    array : ndarray
        (H, W) or (H, W, C), uint8, uint16 or float32, row 0 at the top:
        gray, gray+alpha, RGB or RGBA in that order. Other colour modes are
        converted: CMYK to RGB through its embedded CMYK ICC profile (to
        sRGB, with littlecms) or, without one, by Pillow's plain formula
        (CMYK JPEGs are read with Adobe's inverted convention, as Photoshop
        writes them); YCbCr, LAB and HSV to RGB; palette to RGB, or RGBA
        where it has transparency; bilevel ("1") to 8-bit gray 0/255;
        16-bit gray in any byte order to uint16; 32-bit float to float32.
        ``info.mode`` then names the returned layout ("RGB", ...).
    info : ImageInfo
        Only with ``with_info=True``: how the file stored it (mode,
        metadata), for :func:`write_image` to store the warped copy alike.

    Raises
    ------
    FileNotFoundError
        A missing file.
    ImageError
        A folder, a FIFO, device or socket, a file that is not an image, is
        corrupt or damaged, is too large, or cannot be read without loss.
    ArgumentTypeError
        ``path`` is not a file name (an array passed by mistake).

    Examples
    --------
    >>> from importlib import resources
    >>> import fpiwarp
    >>> with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    ...     image = fpiwarp.read_image(path)
    ...     _, info = fpiwarp.read_image(path, with_info=True)
    >>> image.shape, image.dtype.name, info.mode
    ((480, 640, 3), 'uint8', 'RGB')
    """
    array, info = _read(path, orientation, max_pixels, damaged)
    return (array, info) if with_info else array


def _read(path, orientation, max_pixels, damaged="refuse"):
    check_choice(orientation)
    check_damaged(damaged)
    path = _input_path(path)
    if path.is_dir():
        raise ImageError(f"{path}: is a folder, not an image file")
    kind = special_kind(os.stat(path).st_mode)  # FileNotFoundError for a missing file
    if kind is not None:  # reading a FIFO would wait forever, a device never end
        raise ImageError(f"{path}: is {kind}, not an image file")
    with open(path, "rb") as f:
        head = f.read(len(PNG_SIGNATURE))
    if head == PNG_SIGNATURE:
        array, info, tag = read_png(path, path.read_bytes(), max_pixels, damaged)
    elif is_tiff(head):
        array, info, tag = read_tiff(path, max_pixels, damaged)
    else:
        with open_checked(path, max_pixels) as im:
            array, info, tag = read_pillow(path, im, damaged)
    return apply_orientation(array, info, tag, orientation)


def _input_path(path):
    """``path`` as a Path; a one-line ArgumentTypeError for anything else
    (an array passed where the file name goes)."""
    if isinstance(path, (str, os.PathLike)):
        return Path(path)
    raise ArgumentTypeError(f"read_image takes a file name (str or path-like), got {short_repr(path)}")


def _check_write_arguments(path, array):
    """One line for write_image(array, path) (the arguments swapped), a
    path of another type, and a masked array."""
    if not isinstance(path, (str, os.PathLike)):
        if isinstance(array, (str, os.PathLike)):
            raise ArgumentTypeError(
                f"write_image(path, array): the arguments are swapped, got {short_repr(path)} as the path "
                f"and {short_repr(array)} as the array; call write_image({short_repr(array)}, array)"
            )
        raise ArgumentTypeError(f"write_image's path must be a file name (str or path-like), got {short_repr(path)}")
    refuse_masked(array, "array")


def write_image(
    path: str | os.PathLike, array: np.ndarray, info: ImageInfo | None = None, *, overwrite: bool = False
) -> None:
    """Write ``array`` to ``path`` atomically, in the format its extension names.

    The file is written to a temporary name in the same folder and renamed,
    so a crash never leaves a partial file under ``path``.

    Parameters
    ----------
    path : str or path-like
        The output file; its extension (.png, .jpg, .tif, ...) chooses the
        format.
    array : array_like
        (H, W) or (H, W, C), uint8, uint16 or float32, RGB(A) order.
    info : ImageInfo, optional
        From :func:`~fpiwarp.read_image`: the metadata (ICC profile, EXIF, PNG
        chunks) and mode to keep where the format allows.
    overwrite : bool, optional
        Replace an existing file; default False.

    Raises
    ------
    ImageError
        The format cannot store the array (e.g. 16-bit colour as JPEG).
    OutputExistsError
        ``path`` exists and not ``overwrite``.
    OutputIsFolderError
        ``path`` is a folder.
    OutputIsSpecialFileError
        ``path`` is a FIFO, a character or block device (/dev/null), a
        socket, a symbolic link to one or a dangling link: never replaced,
        even with ``overwrite`` (a link to a regular file is followed: the
        new content goes to its target, and the link stays).
    ArgumentTypeError
        The arguments swapped (``write_image(array, path)``), or a masked
        array (pass ``array.filled(value)`` or ``array.data``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import fpiwarp
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ramp.png"
    >>> fpiwarp.write_image(path, np.arange(6, dtype=np.uint16).reshape(2, 3))
    >>> fpiwarp.read_image(path).tolist()
    [[0, 1, 2], [3, 4, 5]]
    """
    _check_write_arguments(path, array)
    check_output(path, overwrite=overwrite)  # a folder, a special file: said before anything else
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
