"""TIFF: Pillow for what it reads without loss, ``tifffile`` for the rest.

Pillow reads and writes 8-bit, 16-bit gray and float32 gray TIFF. It
reduces 16-bit colour (gray+alpha, RGB, RGBA) to 8 bits or cannot open it,
so that goes through ``tifffile`` (the ``io`` extra), with its ICC profile,
resolution, lossless compression and orientation.
"""

from io import BytesIO

import numpy as np

from ..errors import ImageError
from .formats import INSTALL_IO, ImageInfo, check_pixel_count, optional_codec
from .pillow import open_checked, read_pillow, tiff_bits

TIFF_SIGNATURES = (b"II*\0", b"MM\0*", b"II+\0", b"MM\0+")

# tifffile's compression names <-> Pillow's, so either codec keeps the input's.
_TO_PILLOW = {
    "LZW": "tiff_lzw",
    "ADOBE_DEFLATE": "tiff_adobe_deflate",
    "DEFLATE": "tiff_deflate",
    "PACKBITS": "packbits",
    "NONE": "raw",
}
_FROM_PILLOW = {
    "tiff_lzw": "lzw",
    "tiff_adobe_deflate": "adobe_deflate",
    "tiff_deflate": "deflate",
    "packbits": "packbits",
}
_ICC, _ORIENTATION, _XRES, _YRES, _RESUNIT = 34675, 274, 282, 283, 296
_UNASSOCIATED_ALPHA = 2
_UNDEFINED = 7  # TIFF field type of opaque bytes


def is_tiff(head):
    """True when the first bytes of a file are a (Big)TIFF signature."""
    return head[:4] in TIFF_SIGNATURES


#: Pillow modes that hold TIFF samples of more than 8 bits without loss.
_DEEP_PILLOW_MODES = ("I;16", "I;16B", "I;16L", "I", "F")


def read_tiff(path, max_pixels, damaged="refuse"):
    """(array, info, orientation) of a TIFF file, through tifffile when it
    is 16-bit colour, else through Pillow."""
    if have_tifffile():
        if is_16_bit_colour_tiff(path):
            return read_tiff16(path, max_pixels)
        unreadable = "not a TIFF that Pillow can read"
    else:
        unreadable = UNREADABLE_WITHOUT_TIFFFILE
    with open_checked(path, max_pixels, unreadable) as im:
        if tiff_bits(im) > 8 and im.mode not in _DEEP_PILLOW_MODES:
            raise needs_tifffile(path, tiff_bits(im), im.mode)
        return read_pillow(path, im, damaged)


def have_tifffile():
    """True when tifffile (the ``io`` extra) can be imported."""
    try:
        import tifffile  # noqa: F401
    except ImportError:
        return False
    return True


def is_16_bit_colour_tiff(path):
    """True when ``path`` is a TIFF that Pillow cannot read without loss:
    16-bit samples, 2 or more of them (needs tifffile)."""
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            return page.bitspersample == 16 and page.samplesperpixel > 1
    except (tifffile.TiffFileError, ValueError, OSError):
        return False  # Pillow's reader gives the message


#: What a TIFF is that Pillow does not recognise, when tifffile is missing.
UNREADABLE_WITHOUT_TIFFFILE = f"a TIFF that Pillow cannot read (16-bit gray+alpha TIFF needs tifffile: {INSTALL_IO})"


def needs_tifffile(path, bits, mode):
    """The error for a TIFF that Pillow would reduce to 8 bits."""
    if have_tifffile():
        return ImageError(f"{path}: {bits}-bit {mode} TIFF is not supported")
    return ImageError(f"{path}: {bits}-bit {mode} TIFF needs the tifffile package: {INSTALL_IO}")


def read_tiff16(path, max_pixels):
    """(array, info, orientation) of a 16-bit colour TIFF; the size is
    checked against ``max_pixels`` before decoding."""
    tifffile = optional_codec("tifffile", path, "reading 16-bit colour TIFF")
    try:
        with tifffile.TiffFile(path) as tif:
            if len(tif.pages) > 1:
                raise ImageError(f"{path}: has {len(tif.pages)} frames or pages; fpiwarp reads single images only")
            page = tif.pages[0]
            check_pixel_count(path, page.imagewidth, page.imagelength, max_pixels)
            if page.samplesperpixel > 4 or page.dtype != np.uint16:
                raise ImageError(f"{path}: {page.samplesperpixel}-sample {page.dtype} TIFF is not supported")
            arr = page.asarray()
            if page.axes.startswith("S"):  # planar: one plane per sample
                arr = np.moveaxis(arr, 0, -1)
            info = _info(page)
            orientation = _tag(page, _ORIENTATION, 1)
    except (tifffile.TiffFileError, ValueError, KeyError, IndexError) as exc:
        if isinstance(exc, ImageError):
            raise
        raise ImageError(f"{path}: cannot read 16-bit TIFF: {exc}") from None
    if arr.ndim != 3 or arr.shape[:2] != (page.imagelength, page.imagewidth):
        raise ImageError(f"{path}: 16-bit TIFF of shape {arr.shape} is not supported")
    return np.ascontiguousarray(arr), info, orientation if orientation in range(1, 9) else 1


def _tag(page, code, default):
    tag = page.tags.get(code)
    return default if tag is None else tag.value


def _info(page):
    channels = page.samplesperpixel
    info = ImageInfo(format="TIFF", mode={2: "LA;16", 3: "RGB;16", 4: "RGBA;16"}[channels])
    info.icc_profile = _tag(page, _ICC, None) or None
    info.tiff_compression = _TO_PILLOW.get(page.compression.name)
    unit = int(_tag(page, _RESUNIT, 1))
    xres, yres = _tag(page, _XRES, None), _tag(page, _YRES, None)
    if unit in (2, 3) and xres and yres and xres[1] and yres[1]:
        per_inch = 1.0 if unit == 2 else 2.54
        info.dpi = (xres[0] / xres[1] * per_inch, yres[0] / yres[1] * per_inch)
    return info


def write_tiff16(file, array, info):
    """Write a 16-bit (H, W, 2..4) array as TIFF to the open binary
    ``file``, with ``info``'s ICC profile, resolution and lossless
    compression (when the input was a TIFF)."""
    import tifffile

    channels = array.shape[2]
    options = {
        "photometric": "minisblack" if channels == 2 else "rgb",
        "extrasamples": [_UNASSOCIATED_ALPHA] if channels in (2, 4) else None,
        "metadata": None,
        "software": False,
    }
    if info is not None:
        extratags = []
        if info.icc_profile:  # as a plain tag: tifffile's iccprofile option is recent
            extratags.append((_ICC, _UNDEFINED, len(info.icc_profile), info.icc_profile, True))
        if info.dpi:
            options["resolution"] = tuple(float(d) for d in info.dpi[:2])
            options["resolutionunit"] = "INCH"
        if info.format == "TIFF" and info.tiff_compression in _FROM_PILLOW:
            options["compression"] = _FROM_PILLOW[info.tiff_compression]
        if info.orientation != 1:  # pixels kept as stored: so is their tag
            extratags.append((_ORIENTATION, "H", 1, info.orientation, True))
        options["extratags"] = extratags
    buffer = BytesIO()  # tifffile wants a named file or a buffer, not a file descriptor
    tifffile.imwrite(buffer, np.ascontiguousarray(array, dtype=np.uint16), **options)
    file.write(buffer.getvalue())
