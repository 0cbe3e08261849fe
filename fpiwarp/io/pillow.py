"""Reading and writing through Pillow: every format it knows, with 8-bit
samples, and 16-bit or float32 gray where the format has them.

What Pillow would reduce to 8 bits (16-bit colour) is not read here: the
PNG and TIFF modules send it to ``imagecodecs`` and ``tifffile``.
"""

import contextlib
import os
import re
import struct
import threading

import numpy as np
from PIL import Image, ImageFile, JpegImagePlugin, UnidentifiedImageError

from ..errors import ImageError
from .formats import ImageInfo, check_pixel_count
from .orientation import ORIENTATION_TAG, to_stored


def open_checked(path, max_pixels, unreadable="not an image file (or a format Pillow cannot read)"):
    """Open ``path`` with Pillow (header only), refusing images beyond
    ``max_pixels`` and multi-frame files before any pixel is decoded;
    ``unreadable`` says what a file Pillow does not recognise is."""
    try:
        im = Image.open(path)
    except UnidentifiedImageError:
        raise ImageError(f"{path}: {unreadable}") from None
    except Image.DecompressionBombError as exc:  # far beyond Pillow's limit: it refuses before we can
        raise ImageError(_bomb_message(path, exc, max_pixels)) from None
    except (OSError, SyntaxError, ValueError, struct.error) as exc:
        if isinstance(exc, (FileNotFoundError, PermissionError)):
            raise
        raise ImageError(f"{path}: cannot read image: {exc}") from None
    try:
        check_pixel_count(path, *im.size, max_pixels)
        if getattr(im, "n_frames", 1) > 1:
            raise ImageError(f"{path}: has {im.n_frames} frames or pages; fpiwarp reads single images only")
    except BaseException:
        im.close()
        raise
    return im


def _bomb_message(path, exc, max_pixels):
    """One line for Pillow's DecompressionBombError (raised from the header,
    at twice Image.MAX_IMAGE_PIXELS): ours when the image is beyond our
    limit too, else one that says how to lift Pillow's."""
    found = re.search(r"\((\d+) pixels\)", str(exc))
    pixels = int(found.group(1)) if found else None
    if pixels is None or pixels > max_pixels:
        size = f"{pixels:,} pixels" if pixels is not None else "its size"
        return (
            f"{path}: image of {size} exceeds the limit of {max_pixels:,} pixels "
            "(a decompression bomb, or too large to warp in memory)"
        )
    return f"{path}: image of {pixels:,} pixels exceeds Pillow's limit; raise PIL.Image.MAX_IMAGE_PIXELS to read it"


def tiff_bits(im):
    """Bits per sample of an open TIFF (the largest if they differ)."""
    bits = im.tag_v2.get(258) if hasattr(im, "tag_v2") else None
    bits = (bits,) if isinstance(bits, int) else tuple(bits or ())
    return max(bits, default=8)


#: What ``read_image(damaged=...)`` takes.
DAMAGED = ("refuse", "accept")
#: Fewest bits a baseline JPEG spends on one 8x8 block of its first
#: component: a DC difference code and an end-of-block code, at least one
#: bit each with optimal Huffman tables. A file smaller than the header's
#: block count implies is cut short or padded with filler.
MIN_BITS_PER_BLOCK = 2
_TRUNCATED_LOCK = threading.Lock()


def check_damaged(damaged):
    if damaged not in DAMAGED:
        from ..errors import ArgumentError

        raise ArgumentError(f"damaged must be one of {DAMAGED}, got {damaged!r}")
    return damaged


def _check_jpeg_size(path, im):
    """Refuse a baseline JPEG whose file is too small for the size its
    header claims (before decoding it: a 1 KB file claiming 9000x9000 would
    otherwise decode 243 MB of filler gray). Progressive JPEGs can code
    whole runs of empty blocks in a few bits, so they are not bounded."""
    if im.format != "JPEG" or im.info.get("progressive") or im.info.get("progression"):
        return
    w, h = im.size
    blocks = -(-w // 8) * -(-h // 8)
    need = blocks * MIN_BITS_PER_BLOCK // 8
    size = os.path.getsize(path)
    if size < need:
        raise ImageError(
            f"{path}: damaged JPEG: its header claims {w}x{h} pixels, which needs at least {need:,} bytes of "
            f"image data, but the file has {size:,} bytes (cut short, or padded with filler); "
            "pass damaged='accept' (--accept-damaged) to decode what is there"
        )


@contextlib.contextmanager
def _decoding(damaged):
    """Pillow's LOAD_TRUNCATED_IMAGES on while an image with
    ``damaged="accept"`` is decoded (a global of Pillow's: set under a lock
    and restored)."""
    if damaged != "accept" or ImageFile.LOAD_TRUNCATED_IMAGES:
        yield
        return
    with _TRUNCATED_LOCK:
        ImageFile.LOAD_TRUNCATED_IMAGES = True
        try:
            yield
        finally:
            ImageFile.LOAD_TRUNCATED_IMAGES = False


def read_pillow(path, im, damaged="refuse"):
    """(array, info, orientation) of an image opened by
    :func:`open_checked`: the pixels as stored, and the EXIF orientation
    they need for display. ``damaged="refuse"`` (the default) refuses a
    truncated file and a JPEG too small for its header's size; "accept"
    decodes what there is (the rest filled by the decoder)."""
    try:
        tiff = im.format == "TIFF"
        stored_tag = _orientation(im) if tiff else 1  # before loading: Pillow drops it when turning TIFF pixels
        if damaged == "refuse":
            _check_jpeg_size(path, im)
        with _decoding(damaged):
            im.load()  # first for the others: a corrupt file must fail here, not inside getexif
        orientation = stored_tag if tiff else _orientation(im)
        array, info = _from_pillow(im, path)
    except (OSError, SyntaxError, ValueError, struct.error) as exc:
        if isinstance(exc, (ImageError, FileNotFoundError, PermissionError)):
            raise
        hint = "; pass damaged='accept' (--accept-damaged) to decode what is there" if "truncated" in str(exc) else ""
        raise ImageError(f"{path}: cannot read image: {exc}{hint}") from None
    if tiff:
        array = to_stored(array, orientation)  # Pillow (10 and later) turns TIFF pixels while loading
    return array, info, orientation


def _orientation(im):
    """The EXIF orientation of an open image (TIFF: its own tag), 1..8; 1
    when the EXIF is unreadable (the pixels are still good)."""
    try:
        tags = im.tag_v2 if im.format == "TIFF" else im.getexif()
        value = tags.get(ORIENTATION_TAG, 1)
    except (OSError, SyntaxError, ValueError, TypeError, KeyError, IndexError, struct.error):
        return 1
    return value if isinstance(value, int) and 1 <= value <= 8 else 1


def _from_pillow(im, path):
    """(array, info) of a loaded Pillow image."""
    info = ImageInfo(format=im.format, mode=im.mode)
    info.icc_profile = im.info.get("icc_profile") or None
    exif = im.info.get("exif")
    info.exif = exif if isinstance(exif, bytes) and exif else None
    dpi = im.info.get("dpi")
    info.dpi = tuple(float(d) for d in dpi[:2]) if dpi else None
    if im.format == "JPEG":
        info.jpeg_qtables = getattr(im, "quantization", None)
        sampling = JpegImagePlugin.get_sampling(im)
        info.jpeg_subsampling = sampling if sampling >= 0 else None
    if im.format == "TIFF":
        info.tiff_compression = im.info.get("compression")
    mode = im.mode
    if mode == "CMYK":
        arr = np.asarray(_cmyk_to_rgb(im, info))
        info.mode = "RGB"
    elif mode in ("L", "LA", "RGB", "RGBA"):
        arr = np.asarray(im)
    elif mode in ("I;16", "I;16L", "I;16B", "I;16N"):
        arr = np.asarray(im).astype(np.uint16)
        info.mode = "I;16"
    elif mode == "I":
        arr = np.asarray(im)
        if arr.size and (arr.min() < 0 or arr.max() > 65535):
            raise ImageError(f"{path}: 32-bit integer pixels outside 0..65535 are not supported")
        arr = arr.astype(np.uint16)
        info.mode = "I;16"
    elif mode == "F":
        arr = np.asarray(im).astype(np.float32)
    elif mode in ("1", "P", "PA", "La", "RGBa", "RGBX", "YCbCr", "HSV", "LAB"):
        # No lossless 1:1 array layout: widen to the nearest one. A warp
        # interpolates, so bilevel or palette pixels could not stay so anyway.
        has_alpha = mode in ("PA", "La", "RGBa") or (mode == "P" and "transparency" in im.info)
        target = {"1": "L", "La": "LA"}.get(mode, "RGBA" if has_alpha else "RGB")
        arr = np.asarray(im.convert(target))
        info.mode = target
    else:
        raise ImageError(f"{path}: pixel mode {mode!r} is not supported")
    return np.ascontiguousarray(arr), info


def _cmyk_to_rgb(im, info):
    """A CMYK image as RGB: through its embedded ICC profile (a CMYK
    profile) to sRGB with littlecms, or without one (or with a profile of
    another colour space, which cannot describe these pixels) by Pillow's
    plain formula R = 255 - min(255, C + K), ... . Pillow reads CMYK JPEGs
    with Adobe's inverted convention, as Photoshop writes them, so the
    samples are true CMYK either way. The profile is then dropped from
    ``info``: the pixels are sRGB (or, without a profile, device RGB)."""
    profile = info.icc_profile
    info.icc_profile = None
    if profile:
        try:
            from io import BytesIO

            from PIL import ImageCms

            source = ImageCms.ImageCmsProfile(BytesIO(profile))
            if source.profile.xcolor_space.strip() == "CMYK":
                return ImageCms.profileToProfile(im, source, ImageCms.createProfile("sRGB"), outputMode="RGB")
        except (ImportError, OSError, ValueError, TypeError, AttributeError):
            pass  # no littlecms, or a profile it cannot read: the plain formula
        except Exception as exc:  # noqa: BLE001 - ImageCms.PyCMSError is not an OSError
            if type(exc).__name__ != "PyCMSError":
                raise
    return im.convert("RGB")


def to_pillow(array, mode):
    """A Pillow image of ``array`` in ``mode`` (from ``pillow_mode``)."""
    h, w = array.shape[:2]
    if mode == "I;16":
        data = np.ascontiguousarray(array, dtype="<u2")
    elif mode == "F":
        data = np.ascontiguousarray(array, dtype="=f4")
    else:
        data = np.ascontiguousarray(array, dtype=np.uint8)
    return Image.frombytes(mode, (w, h), data.tobytes())


#: TIFF compressions that are lossless, by Pillow's names: kept on output.
LOSSLESS_TIFF = ("tiff_lzw", "tiff_adobe_deflate", "tiff_deflate", "packbits")


def save_params(fmt, info, mode):
    """Pillow save options that keep ``info``'s metadata and quality."""
    if info is None:
        return {"quality": 95} if fmt == "JPEG" else {}
    params = {}
    if info.icc_profile:
        params["icc_profile"] = info.icc_profile
    if info.exif:
        params["exif"] = info.exif
    if info.dpi:
        params["dpi"] = info.dpi
    if fmt == "JPEG":
        same = info.format == "JPEG" and info.mode == mode
        if same and info.jpeg_qtables:
            params["qtables"] = info.jpeg_qtables  # the input's quality
        else:
            params["quality"] = 95
        if same and info.jpeg_subsampling is not None:
            params["subsampling"] = info.jpeg_subsampling
    if fmt == "TIFF" and info.format == "TIFF" and info.tiff_compression in LOSSLESS_TIFF:
        params["compression"] = info.tiff_compression  # the input's (lossless) compression
    return params


def write_pillow(path, file, array, fmt, mode, info):
    """Write ``array`` to the open binary ``file`` (the output ``path``) in
    ``fmt`` through Pillow; a refusal of Pillow's encoder names ``path``."""
    try:
        to_pillow(array, mode).save(file, format=fmt, **save_params(fmt, info, mode))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        if isinstance(exc, OSError) and exc.errno is not None:
            raise  # the file system's: atomic_write names the output
        raise ImageError(f"{path}: Pillow cannot write this {mode} image as {fmt}: {exc}") from None
