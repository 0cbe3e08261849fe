"""EXIF orientation: give pixels as a viewer shows them, and keep the tag true.

Cameras store a portrait photo as landscape pixels plus an EXIF Orientation
tag (6: turn 90° clockwise to view). Users pick corners on what they see,
so :func:`fpiwarp.read_image` applies the tag by default (as viewers and
OpenCV do) and removes it from the EXIF it passes on, so that the warped
copy is not turned a second time. ``orientation="stored"`` keeps the pixels
as stored and the tag as it is, which is consistent too.
"""

import re
import struct

import numpy as np
from PIL import Image

from ..errors import ArgumentError

#: The EXIF Orientation tag.
ORIENTATION_TAG = 0x0112
#: The choices of read_image's ``orientation`` keyword.
ORIENTATIONS = ("apply", "stored")

# Orientation value -> how to turn the stored pixels into the displayed ones
# (the transposes Pillow's ImageOps.exif_transpose uses, on numpy arrays).
_TO_DISPLAY = {
    2: lambda a: a[:, ::-1],  # mirrored left-right
    3: lambda a: a[::-1, ::-1],  # turned 180°
    4: lambda a: a[::-1],  # mirrored top-bottom
    5: lambda a: a.swapaxes(0, 1),  # transposed
    6: lambda a: np.rot90(a, -1),  # turn 90° clockwise to view
    7: lambda a: a[::-1, ::-1].swapaxes(0, 1),  # transversed
    8: lambda a: np.rot90(a, 1),  # turn 90° counter-clockwise to view
}


#: The inverse turns: most are their own inverse, the quarter turns swap.
_INVERSE = {2: 2, 3: 3, 4: 4, 5: 5, 6: 8, 7: 7, 8: 6}


def to_stored(array, orientation):
    """Undo an orientation a codec applied on its own (Pillow does for
    TIFF), so that every reader hands over the pixels as stored."""
    if orientation == 1:
        return array
    return np.ascontiguousarray(_TO_DISPLAY[_INVERSE[orientation]](array))


def check_choice(orientation):
    """Raise ArgumentError (a ValueError) unless ``orientation`` is one of ORIENTATIONS."""
    if orientation not in ORIENTATIONS:
        raise ArgumentError(f"orientation must be one of {', '.join(map(repr, ORIENTATIONS))}, got {orientation!r}")


def orientation_of(exif):
    """The Orientation value (1..8) in EXIF bytes (with or without the
    "Exif\\0\\0" header); 1 when absent, out of range or unreadable."""
    if not exif:
        return 1
    try:
        value = _load(exif).get(ORIENTATION_TAG, 1)
    except (ValueError, TypeError, KeyError, IndexError, struct.error, SyntaxError, OSError):
        return 1
    return value if isinstance(value, int) and 1 <= value <= 8 else 1


def apply_orientation(array, info, orientation, choice):
    """(array, info) as ``choice`` asks: "apply" turns the pixels to the
    displayed orientation and removes the tag from ``info``'s EXIF and PNG
    chunks; "stored" leaves the pixels and makes sure the tag travels with
    them (an EXIF block holding it alone when the input kept it outside
    EXIF, as TIFF does). ``info.orientation`` says what the returned pixels
    still need for display."""
    check_choice(choice)
    info.orientation = orientation
    if orientation == 1:
        return array, info
    if choice == "stored":
        if not info.exif:
            tags = Image.Exif()
            tags[ORIENTATION_TAG] = orientation
            info.exif = tags.tobytes()
        return array, info
    array = np.ascontiguousarray(_TO_DISPLAY[orientation](array))
    info.orientation = 1
    info.exif = _without_orientation(info.exif)
    info.png_chunks = [chunk for chunk in map(_chunk_without_orientation, info.png_chunks) if chunk is not None]
    return array, info


#: XMP's copy of the tag, as Pillow's ImageOps.exif_transpose removes it.
_XMP_ORIENTATION = (rb'tiff:Orientation="[0-9]"', rb"<tiff:Orientation>[0-9]</tiff:Orientation>")


def _chunk_without_orientation(chunk):
    """A PNG chunk with the orientation taken out, or None to drop it."""
    ctype, payload = chunk
    if ctype == b"eXIf":
        exif = _without_orientation(payload)
        return None if exif is None else (ctype, exif.removeprefix(b"Exif\0\0"))
    keyword = payload.split(b"\0", 1)[0]
    if ctype in (b"tEXt", b"zTXt", b"iTXt") and keyword == b"Raw profile type exif":
        return None  # ImageMagick's hex copy of EXIF, orientation included
    if ctype == b"iTXt" and keyword == b"XML:com.adobe.xmp":
        for pattern in _XMP_ORIENTATION:
            payload = re.sub(pattern, b"", payload)
    return ctype, payload


def _load(exif):
    tags = Image.Exif()
    tags.load(exif if exif.startswith(b"Exif\0\0") else b"Exif\0\0" + exif)
    return tags


def _without_orientation(exif):
    """EXIF bytes without the Orientation tag ("Exif\\0\\0" first), or None
    when there was none or it cannot be rewritten (then it is dropped rather
    than copied with a tag that would turn the pixels again)."""
    if not exif:
        return None
    try:
        tags = _load(exif)
        tags.pop(ORIENTATION_TAG, None)
        return tags.tobytes()
    except (ValueError, TypeError, KeyError, IndexError, struct.error, SyntaxError, OSError):
        return None
