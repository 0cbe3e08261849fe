"""PNG: pixels through Pillow or libpng (``imagecodecs``), metadata kept.

Pillow decodes and encodes every PNG except 16-bit colour (gray+alpha, RGB,
RGBA), which it would reduce to 8 bits; those go through ``imagecodecs``
(the ``io`` extra). Neither codec copies the ancillary chunks that a warped
copy should keep (colour space, gamma, resolution, text, EXIF), so this
module reads the file's chunk list (checking CRCs and the header before any
pixel is decoded) and writes the kept chunks right after the new IHDR.
"""

import struct
import zlib
from collections import namedtuple
from io import BytesIO

import numpy as np

from ..errors import ImageError
from .formats import ImageInfo, check_pixel_count, is_16_bit_colour, optional_codec, quiet_stderr
from .orientation import orientation_of
from .pillow import open_checked, read_pillow, to_pillow

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Ancillary chunks that stay true for a warped copy of the same pixel format.
KEEP_CHUNKS = {b"iCCP", b"sRGB", b"gAMA", b"cHRM", b"pHYs", b"tEXt", b"zTXt", b"iTXt", b"eXIf"}
#: Chunks that describe the sample encoding: kept only if it is unchanged.
KEEP_SAME_ENCODING = {b"tRNS", b"sBIT"}

PngHeader = namedtuple("PngHeader", "width height depth color interlace")
_COLOR_NAMES = {0: "gray", 2: "RGB", 3: "palette", 4: "gray+alpha", 6: "RGBA"}
_COLOR_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}
_CHANNEL_COLOR = {1: 0, 3: 2, 2: 4, 4: 6}
#: Bit depths the PNG specification allows for each color type.
_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}


def png_chunks(data, name):
    """[(type, payload)] of a PNG file's bytes, CRCs checked."""
    if not data.startswith(PNG_SIGNATURE):
        raise ImageError(f"{name}: not a PNG file")
    chunks, pos = [], len(PNG_SIGNATURE)
    while pos < len(data):
        if pos + 8 > len(data):
            raise ImageError(f"{name}: truncated PNG (chunk header cut off)")
        length, ctype = struct.unpack(">I4s", data[pos : pos + 8])
        end = pos + 8 + length
        if end + 4 > len(data):
            raise ImageError(f"{name}: truncated PNG (chunk {ctype.decode('latin-1')!r} cut off)")
        payload = data[pos + 8 : end]
        (crc,) = struct.unpack(">I", data[end : end + 4])
        if zlib.crc32(ctype + payload) != crc:
            raise ImageError(f"{name}: corrupt PNG (bad CRC in chunk {ctype.decode('latin-1')!r})")
        chunks.append((ctype, payload))
        pos = end + 4
        if ctype == b"IEND":
            break
    if not chunks or chunks[0][0] != b"IHDR" or len(chunks[0][1]) != 13:
        raise ImageError(f"{name}: corrupt PNG (no IHDR chunk)")
    if chunks[-1][0] != b"IEND":
        raise ImageError(f"{name}: truncated PNG (no IEND chunk)")
    return chunks


def png_header(chunks, name):
    """The checked IHDR of a chunk list: a valid combination of bit depth
    and color type, a known compression, filter and interlace method."""
    w, h, depth, color, comp, filt, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    if color not in _DEPTHS:
        raise ImageError(f"{name}: invalid PNG (unknown color type {color})")
    if depth not in _DEPTHS[color]:
        allowed = ", ".join(map(str, _DEPTHS[color]))
        raise ImageError(
            f"{name}: invalid PNG: a {depth}-bit {_COLOR_NAMES[color]} image does not exist "
            f"(the PNG standard allows {allowed} bits for {_COLOR_NAMES[color]})"
        )
    if comp != 0 or filt != 0 or interlace not in (0, 1):
        raise ImageError(f"{name}: invalid PNG (compression {comp}, filter {filt}, interlace {interlace})")
    if w == 0 or h == 0:
        raise ImageError(f"{name}: PNG has no pixels ({w}×{h})")
    return PngHeader(w, h, depth, color, interlace)


def read_png(path, data, max_pixels, damaged="refuse"):
    """(array, info, orientation) of the PNG file ``path`` whose bytes are
    ``data``; the size is checked against ``max_pixels`` before decoding.
    ``damaged="refuse"`` refuses pixel data shorter or longer than the
    header's size needs (checked by inflating it, before decoding)."""
    chunks = png_chunks(data, path)
    header = png_header(chunks, path)
    check_pixel_count(path, header.width, header.height, max_pixels)
    if damaged == "refuse":
        _check_pixel_data(path, chunks, header)
    if header.depth == 16 and header.color in (2, 4, 6):
        arr, info = _read_16_bit_colour(path, data, chunks, header)
        orientation = orientation_of(next((p for t, p in chunks if t == b"eXIf"), None))
    else:
        with open_checked(path, max_pixels) as im:
            arr, info, orientation = read_pillow(path, im, damaged)
    info.png_chunks = [(t, p) for t, p in chunks if t in KEEP_CHUNKS | KEEP_SAME_ENCODING]
    info.ihdr = (header.depth, header.color)
    return arr, info, orientation


_CHANNELS_ALL = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))


def raw_size(header):
    """Bytes of the inflated pixel data (filter bytes included) that a PNG
    of this header holds: one scan line per row, per Adam7 pass if interlaced."""
    bits = header.depth * _CHANNELS_ALL[header.color]

    def lines(w, h):
        return 0 if w == 0 or h == 0 else h * (1 + (w * bits + 7) // 8)

    if not header.interlace:
        return lines(header.width, header.height)
    return sum(lines(-(-(header.width - x0) // dx), -(-(header.height - y0) // dy)) for x0, y0, dx, dy in _ADAM7)


def _check_pixel_data(path, chunks, header):
    """Refuse IDAT data that does not inflate to what the header needs (a
    forgiving decoder would fill the rest with zeros and only print a
    warning). Inflated in pieces, never beyond the expected size + 1."""
    need = raw_size(header)
    inflater = zlib.decompressobj()
    got = 0
    try:
        for ctype, payload in chunks:
            if ctype == b"IDAT":
                got += len(inflater.decompress(payload, need + 1 - got))
                if got > need or inflater.unconsumed_tail:
                    break
        complete = inflater.eof
    except zlib.error as exc:
        raise ImageError(f"{path}: damaged PNG: its pixel data cannot be inflated ({exc})") from None
    if got != need or not complete:
        what = "more" if got > need else f"{got:,}"
        raise ImageError(
            f"{path}: damaged PNG: its pixel data holds {what} of the {need:,} bytes its "
            f"{header.width}x{header.height} header needs{'' if complete else ' (the data stream is cut short)'}; "
            "pass damaged='accept' (--accept-damaged) to decode what is there"
        )


def _read_16_bit_colour(path, data, chunks, header):
    kind = f"16-bit {_COLOR_NAMES[header.color]} PNG"
    codecs = optional_codec("imagecodecs", path, f"reading {kind}")
    try:
        with quiet_stderr():  # libpng prints its warnings there (for every interlaced file, a spurious one)
            arr = codecs.png_decode(data)
    except (codecs.PngError, ValueError, RuntimeError) as exc:
        raise ImageError(f"{path}: corrupt {kind} ({exc})") from None
    channels = _COLOR_CHANNELS[header.color]
    if arr.ndim == 3 and arr.shape[2] == channels + 1:
        arr = arr[..., :channels]  # libpng made tRNS an alpha channel; the chunk is kept instead
    if arr.shape[:2] != (header.height, header.width) or arr.dtype != np.uint16:
        raise ImageError(f"{path}: corrupt {kind} (decoded {arr.shape} {arr.dtype})")
    mode = {2: "RGB;16", 4: "LA;16", 6: "RGBA;16"}[header.color]
    info = ImageInfo(format="PNG", mode=mode, icc_profile=_icc_profile(chunks), dpi=_dpi(chunks))
    exif = next((p for t, p in chunks if t == b"eXIf"), None)
    info.exif = b"Exif\0\0" + exif if exif else None
    return np.ascontiguousarray(arr), info


def _icc_profile(chunks):
    for ctype, payload in chunks:
        if ctype == b"iCCP":
            try:
                return zlib.decompress(payload[payload.index(b"\0") + 2 :])
            except (ValueError, zlib.error):
                return None
    return None


def _dpi(chunks):
    for ctype, payload in chunks:
        if ctype == b"pHYs" and len(payload) == 9:
            x, y, unit = struct.unpack(">IIB", payload)
            return (x * 0.0254, y * 0.0254) if unit == 1 else None
    return None


def encode_png(path, array, mode, info):
    """PNG file bytes of an (H, W[, C]) uint8/uint16 array with the
    metadata of ``info``, for ``path``; ``mode`` is its Pillow mode (None
    for 16-bit colour, which ``imagecodecs`` encodes)."""
    channels = 1 if array.ndim == 2 else array.shape[2]
    if is_16_bit_colour(array.dtype, channels):
        codecs = optional_codec("imagecodecs", path, "writing 16-bit colour PNG")
        pixels = codecs.png_encode(np.ascontiguousarray(array), level=6)
    else:
        buffer = BytesIO()
        to_pillow(array, mode).save(buffer, format="PNG", compress_level=6)
        pixels = buffer.getvalue()
    depth = 16 if array.dtype == np.uint16 else 8
    return _with_chunks(pixels, _metadata_chunks(info, (depth, _CHANNEL_COLOR[channels])))


def _with_chunks(png, extra):
    """``png`` bytes with the ``extra`` chunks inserted after IHDR (a valid
    place for every kept chunk in a PNG without palette)."""
    ihdr_end = len(PNG_SIGNATURE) + 8 + 13 + 4
    inserted = b"".join(_chunk(t, p) for t, p in extra)
    return png[:ihdr_end] + inserted + png[ihdr_end:]


def _chunk(ctype, payload):
    return struct.pack(">I", len(payload)) + ctype + payload + struct.pack(">I", zlib.crc32(ctype + payload))


def _metadata_chunks(info, encoding):
    """Ancillary chunks for a PNG written from an image described by info."""
    if info is None:
        return []
    if info.png_chunks:
        return [
            (t, p)
            for t, p in info.png_chunks
            if t in KEEP_CHUNKS or (t in KEEP_SAME_ENCODING and info.ihdr == encoding)
        ]
    chunks = []
    if info.icc_profile:
        chunks.append((b"iCCP", b"ICC Profile\0\0" + zlib.compress(info.icc_profile)))
    if info.dpi:
        ppm = [max(1, round(d / 0.0254)) for d in info.dpi[:2]]
        chunks.append((b"pHYs", struct.pack(">IIB", ppm[0], ppm[1], 1)))
    if info.exif:
        chunks.append((b"eXIf", info.exif.removeprefix(b"Exif\0\0")))
    return chunks
