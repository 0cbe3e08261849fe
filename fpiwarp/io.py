"""Reading and writing image files without losing pixels, metadata or files.

``read_image(path)`` returns an array in one of the layouts
:func:`fpiwarp.warp_image` takes (uint8, uint16 or float32; (H, W) gray or
(H, W, C) with C = 2 gray+alpha, 3 RGB, 4 RGBA or CMYK) and an
:class:`ImageInfo` with what is needed to write the result back the same
way: format, color mode and metadata (ICC profile, EXIF, resolution, PNG
text and color chunks, JPEG quantization tables, TIFF compression).
``write_image(path, array, info)`` writes atomically: into a temporary file
in the output folder, then renamed over the final name, so that a crash or
Ctrl-C leaves either no file or the complete one, never a partial file or
a temporary one. An existing file is kept unless ``overwrite=True``.

Pillow (the ``io`` extra) handles JPEG, TIFF, BMP, WebP, ... A small
built-in PNG codec (zlib only) handles 8- and 16-bit gray, gray+alpha, RGB
and RGBA, so a numpy-only install can read and write PNG; it is also used
where Pillow would lose data (Pillow reduces 16-bit color PNGs to 8 bits).
Every PNG is written by the built-in codec, which copies the input's color
and text chunks. A file that cannot be read without loss (16-bit color
TIFF, animations, multi-page files) is refused with a message saying why.
"""

import errno
import os
import struct
import tempfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "ImageError",
    "ImageInfo",
    "OutputExistsError",
    "check_writable",
    "format_for_path",
    "have_pillow",
    "read_image",
    "write_image",
]


class ImageError(ValueError):
    """A file that is not an image fpiwarp can read, or an array that the
    chosen format cannot store; the message names the file and the problem."""


class OutputExistsError(FileExistsError):
    """The output file exists and overwriting was not asked for."""

    def __init__(self, path):
        super().__init__(errno.EEXIST, "file exists", str(path))

    def __str__(self):
        return f"{self.filename} already exists (pass overwrite=True to replace it)"


@dataclass
class ImageInfo:
    """How an image was stored, so that its warped copy is stored alike.

    ``mode`` is the Pillow mode name ("L", "LA", "RGB", "RGBA", "CMYK",
    "I;16", "F", ...). ``png_chunks`` holds the input's ancillary PNG chunks
    (type, data) that stay valid for a warped copy; ``ihdr`` the input's PNG
    (bit depth, color type), which decides whether tRNS and sBIT may be kept.
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


def have_pillow():
    """True when Pillow can be imported."""
    try:
        import PIL.Image  # noqa: F401
    except ImportError:
        return False
    return True


def _pillow(purpose):
    try:
        from PIL import Image
    except ImportError:
        raise ImageError(
            f"{purpose} needs Pillow: pip install 'fpiwarp[io]' (without it fpiwarp reads and writes PNG only)"
        ) from None
    return Image


# --------------------------------------------------------------------------
# Formats

_EXTENSIONS = {
    ".png": "PNG",
    ".jpg": "JPEG",
    ".jpeg": "JPEG",
    ".jpe": "JPEG",
    ".tif": "TIFF",
    ".tiff": "TIFF",
}


def format_for_path(path):
    """The format name ("PNG", "JPEG", "TIFF", ...) that ``path``'s
    extension asks for; ImageError if it names none."""
    ext = Path(path).suffix.lower()
    if ext in _EXTENSIONS:
        return _EXTENSIONS[ext]
    if have_pillow():
        from PIL import Image

        fmt = Image.registered_extensions().get(ext)
        if fmt is not None and fmt in Image.SAVE:
            return fmt
    raise ImageError(f"{path}: cannot tell the image format from the extension {ext or '(none)'!r}")


def _layout(array):
    arr = np.asarray(array)
    if arr.ndim == 2:
        return arr.dtype, 1
    if arr.ndim == 3 and 1 <= arr.shape[2] <= 4:
        return arr.dtype, arr.shape[2]
    raise ImageError(f"an image array must be (H, W) or (H, W, C) with C in 1..4, got shape {arr.shape}")


_DTYPE_NAMES = {np.dtype(np.uint8): "8-bit", np.dtype(np.uint16): "16-bit", np.dtype(np.float32): "float32"}


def _pil_mode(dtype, channels, info):
    """The Pillow mode that stores (dtype, channels), or None."""
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


_PILLOW_MODES_BY_FORMAT = {
    "JPEG": {"L", "RGB", "CMYK"},
    "TIFF": {"L", "LA", "RGB", "RGBA", "CMYK", "I;16", "F"},
}


def check_writable(path, dtype, channels, info=None):
    """Raise ImageError if the format of ``path`` cannot store an image of
    this dtype and channel count without loss; return the format name."""
    fmt = format_for_path(path)
    dtype = np.dtype(dtype)
    kind = _DTYPE_NAMES.get(dtype, str(dtype))
    what = {1: "gray", 2: "gray+alpha", 3: "RGB", 4: "RGBA"}.get(channels, f"{channels}-channel")
    if fmt == "PNG":
        if dtype not in (np.uint8, np.uint16):
            raise ImageError(f"{path}: PNG cannot store {kind} images; use .tif")
        return fmt
    _pillow(f"writing {fmt} ({path})")
    mode = _pil_mode(dtype, channels, info)
    allowed = _PILLOW_MODES_BY_FORMAT.get(fmt)
    if mode is None or (allowed is not None and mode not in allowed):
        hint = "; use .png" if dtype != np.float32 else "; use .tif"
        raise ImageError(f"{path}: {fmt} cannot store {kind} {what} images{hint}")
    return fmt


# --------------------------------------------------------------------------
# Built-in PNG codec

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_COLOR_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}
_CHANNEL_COLOR = {1: 0, 3: 2, 2: 4, 4: 6}
#: Ancillary chunks that stay true for a warped copy of the same pixel format.
_KEEP_CHUNKS = {b"iCCP", b"sRGB", b"gAMA", b"cHRM", b"pHYs", b"tEXt", b"zTXt", b"iTXt", b"eXIf"}
#: Chunks that describe the sample encoding: kept only if it is unchanged.
_KEEP_SAME_ENCODING = {b"tRNS", b"sBIT"}


def _png_chunks(data, name):
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


#: Largest image the built-in PNG reader inflates (2**28 px, 1.5 GiB as
#: 16-bit RGB): beyond it a file is refused rather than exhausting memory.
MAX_PNG_PIXELS = 2**28


def _ihdr(chunks):
    w, h, depth, color, comp, filt, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    return w, h, depth, color, comp, filt, interlace


def _builtin_can_decode(ihdr):
    _, _, depth, color, comp, filt, interlace = ihdr
    return depth in (8, 16) and color in _COLOR_CHANNELS and comp == 0 and filt == 0 and interlace == 0


def _unfilter(raw, height, stride, bpp, name):
    """Undo PNG row filters; raw holds height rows of 1 + stride bytes."""
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(height, stride + 1)
    out = np.empty((height, stride), dtype=np.uint8)
    prior = np.zeros(stride, dtype=np.uint8)
    for r in range(height):
        ftype, cur = rows[r, 0], rows[r, 1:]
        if ftype == 0:
            rec = cur.copy()
        elif ftype == 1:  # Sub: running sum along the row, per byte position
            rec = np.cumsum(cur.reshape(-1, bpp), axis=0, dtype=np.uint8).reshape(-1)
        elif ftype == 2:  # Up
            rec = cur + prior
        elif ftype in (3, 4):  # Average, Paeth: sequential along the row
            rec = _unfilter_slow(ftype, bytes(cur), bytes(prior), bpp)
        else:
            raise ImageError(f"{name}: corrupt PNG (unknown row filter {ftype})")
        out[r] = rec
        prior = out[r]
    return out


def _unfilter_slow(ftype, cur, prior, bpp):
    rec = bytearray(len(cur))
    for i in range(len(cur)):
        left = rec[i - bpp] if i >= bpp else 0
        up = prior[i]
        if ftype == 3:
            pred = (left + up) >> 1
        else:
            upleft = prior[i - bpp] if i >= bpp else 0
            p = left + up - upleft
            pa, pb, pc = abs(p - left), abs(p - up), abs(p - upleft)
            pred = left if pa <= pb and pa <= pc else (up if pb <= pc else upleft)
        rec[i] = (cur[i] + pred) & 255
    return np.frombuffer(bytes(rec), dtype=np.uint8)


def _png_decode(chunks, name):
    """Pixels of a PNG in the built-in subset: (H, W) or (H, W, C)."""
    w, h, depth, color, *_ = ihdr = _ihdr(chunks)
    if not _builtin_can_decode(ihdr):
        raise ImageError(
            f"{name}: this PNG (bit depth {depth}, color type {color}, interlace {ihdr[6]}) "
            "needs Pillow: pip install 'fpiwarp[io]'"
        )
    if w == 0 or h == 0:
        raise ImageError(f"{name}: PNG has no pixels ({w}×{h})")
    if w * h > MAX_PNG_PIXELS:
        raise ImageError(
            f"{name}: PNG of {w}×{h} pixels exceeds the built-in reader's limit of {MAX_PNG_PIXELS} "
            "(a decompression bomb, or an image too large to warp in memory)"
        )
    channels = _COLOR_CHANNELS[color]
    nbytes = depth // 8
    bpp = channels * nbytes
    expected = h * (w * bpp + 1)
    try:  # never inflate more than the header promises
        raw = zlib.decompressobj().decompress(b"".join(p for t, p in chunks if t == b"IDAT"), expected + 1)
    except zlib.error as exc:
        raise ImageError(f"{name}: corrupt PNG image data ({exc})") from None
    if len(raw) != expected:
        raise ImageError(f"{name}: corrupt PNG (image data has {len(raw)} bytes, expected {expected})")
    pixels = _unfilter(raw, h, w * bpp, bpp, name)
    if depth == 16:
        arr = pixels.view(">u2").astype(np.uint16)
    else:
        arr = pixels
    arr = arr.reshape(h, w, channels)
    return arr[:, :, 0] if channels == 1 else arr


def _png_chunk(ctype, payload):
    return struct.pack(">I", len(payload)) + ctype + payload + struct.pack(">I", zlib.crc32(ctype + payload))


def _filter_rows(raw, bpp):
    """Filter each row with None, Sub or Up, whichever has the smallest sum
    of absolute signed bytes (the PNG spec's heuristic). Paeth and Average
    are left out so that the built-in reader decodes these files quickly."""
    up = raw - np.vstack([np.zeros((1, raw.shape[1]), np.uint8), raw[:-1]])
    sub = raw.copy()
    sub[:, bpp:] -= raw[:, :-bpp]
    candidates = (raw, sub, up)  # filter types 0, 1, 2
    cost = np.stack([np.abs(c.view(np.int8).astype(np.int16)).sum(axis=1, dtype=np.int64) for c in candidates])
    best = np.argmin(cost, axis=0)
    out = np.empty((raw.shape[0], raw.shape[1] + 1), dtype=np.uint8)
    out[:, 0] = best
    for ftype, c in enumerate(candidates):
        rows = best == ftype
        out[rows, 1:] = c[rows]
    return out


def _png_encode(arr, info):
    """PNG file bytes of an (H, W[, C]) uint8/uint16 array."""
    dtype, channels = _layout(arr)
    h, w = arr.shape[:2]
    depth = 16 if dtype == np.uint16 else 8
    color = _CHANNEL_COLOR[channels]
    data = np.ascontiguousarray(arr.reshape(h, w * channels).astype(">u2" if depth == 16 else np.uint8))
    raw = data.view(np.uint8).reshape(h, -1)
    filtered = _filter_rows(raw, channels * depth // 8)
    out = [PNG_SIGNATURE, _png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, color, 0, 0, 0))]
    for ctype, payload in _png_metadata(info, (depth, color)):
        out.append(_png_chunk(ctype, payload))
    out.append(_png_chunk(b"IDAT", zlib.compress(filtered.tobytes(), 6)))
    out.append(_png_chunk(b"IEND", b""))
    return b"".join(out)


def _png_metadata(info, encoding):
    """Ancillary chunks for a PNG written from an image described by info."""
    if info is None:
        return []
    if info.png_chunks:
        return [
            (t, p)
            for t, p in info.png_chunks
            if t in _KEEP_CHUNKS or (t in _KEEP_SAME_ENCODING and info.ihdr == encoding)
        ]
    chunks = []
    if info.icc_profile:
        chunks.append((b"iCCP", b"ICC Profile\0\0" + zlib.compress(info.icc_profile)))
    if info.dpi:
        ppm = [max(1, round(d / 0.0254)) for d in info.dpi[:2]]
        chunks.append((b"pHYs", struct.pack(">IIB", ppm[0], ppm[1], 1)))
    if info.exif:
        exif = info.exif[6:] if info.exif.startswith(b"Exif\0\0") else info.exif
        chunks.append((b"eXIf", exif))
    return chunks


def _png_info(chunks):
    """ImageInfo of a PNG read by the built-in codec."""
    _, _, depth, color, *_ = _ihdr(chunks)
    mode = {0: "L", 2: "RGB", 4: "LA", 6: "RGBA", 3: "P"}.get(color)
    if depth == 16:
        mode = {"L": "I;16"}.get(mode, mode + ";16" if mode else None)
    info = ImageInfo(format="PNG", mode=mode, ihdr=(depth, color))
    info.png_chunks = [(t, p) for t, p in chunks if t in _KEEP_CHUNKS | _KEEP_SAME_ENCODING]
    for t, p in chunks:
        if t == b"iCCP":
            try:
                info.icc_profile = zlib.decompress(p[p.index(b"\0") + 2 :])
            except (ValueError, zlib.error):
                pass
    return info


# --------------------------------------------------------------------------
# Reading


def read_image(path):
    """Read an image file; return (array, ImageInfo).

    Raises FileNotFoundError for a missing file and ImageError for a file
    that is not an image, is corrupt, or cannot be read without loss.
    """
    path = Path(path)
    if path.is_dir():
        raise ImageError(f"{path}: is a folder, not an image file")
    with open(path, "rb") as f:
        head = f.read(8)
    if head == PNG_SIGNATURE:
        return _read_png(path)
    Image = _pillow(f"reading {path.suffix or 'this file'} ({path})")
    return _read_pillow(path, Image)


def _read_png(path):
    data = path.read_bytes()
    chunks = _png_chunks(data, path)
    ihdr = _ihdr(chunks)
    info = _png_info(chunks)
    depth, color = ihdr[2], ihdr[3]
    if not have_pillow() or (_builtin_can_decode(ihdr) and depth == 16):
        return _png_decode(chunks, path), info  # raises if outside the subset
    if depth == 16 and color != 0:
        raise ImageError(f"{path}: interlaced 16-bit color PNG is not supported (Pillow would reduce it to 8 bits)")
    from PIL import Image

    arr, pil_info = _read_pillow(path, Image)
    pil_info.png_chunks, pil_info.ihdr = info.png_chunks, info.ihdr
    return arr, pil_info


def _read_pillow(path, Image):
    from PIL import UnidentifiedImageError

    try:
        with Image.open(path) as im:
            if getattr(im, "n_frames", 1) > 1:
                raise ImageError(f"{path}: has {im.n_frames} frames or pages; fpiwarp reads single images only")
            im.load()
            return _from_pillow(im, path)
    except UnidentifiedImageError:
        raise ImageError(f"{path}: not an image file (or a format Pillow cannot read)") from None
    except (OSError, SyntaxError, ValueError, struct.error, Image.DecompressionBombError) as exc:
        if isinstance(exc, (ImageError, FileNotFoundError, PermissionError)):
            raise
        raise ImageError(f"{path}: cannot read image: {exc}") from None


def _from_pillow(im, path):
    info = ImageInfo(format=im.format, mode=im.mode)
    info.icc_profile = im.info.get("icc_profile") or None
    exif = im.info.get("exif")
    info.exif = exif if isinstance(exif, bytes) and exif else None
    dpi = im.info.get("dpi")
    info.dpi = tuple(float(d) for d in dpi[:2]) if dpi else None
    if im.format == "JPEG":
        from PIL import JpegImagePlugin

        info.jpeg_qtables = getattr(im, "quantization", None)
        sampling = JpegImagePlugin.get_sampling(im)
        info.jpeg_subsampling = sampling if sampling >= 0 else None
    if im.format == "TIFF":
        info.tiff_compression = im.info.get("compression")
        bits = im.tag_v2.get(258) if hasattr(im, "tag_v2") else None
        bits = (bits,) if isinstance(bits, int) else tuple(bits or ())
        if any(b > 8 for b in bits) and im.mode not in ("I;16", "I;16B", "I;16L", "I", "F"):
            raise ImageError(
                f"{path}: {max(bits)}-bit {im.mode} TIFF would be reduced to 8 bits by Pillow; "
                "convert it to 16-bit PNG to warp it without loss"
            )
    mode = im.mode
    if mode in ("L", "LA", "RGB", "RGBA", "CMYK"):
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


# --------------------------------------------------------------------------
# Writing

_UMASK = os.umask(0o022)
os.umask(_UMASK)
TEMP_SUFFIX = ".fpiwarp-tmp"


def is_temp_file(path):
    """True for the temporary files write_image creates (and removes)."""
    name = Path(path).name
    return name.startswith(".") and name.endswith(TEMP_SUFFIX)


def atomic_write(path, write, *, overwrite=False):
    """Call ``write(file)`` on a temporary file next to ``path``, then move
    it to ``path`` in one rename. Without ``overwrite`` an existing
    ``path`` is never replaced (OutputExistsError), even if it appears
    while writing. The temporary file is removed on every error, including
    KeyboardInterrupt."""
    path = Path(path)
    if not overwrite and path.exists():
        raise OutputExistsError(path)
    parent = path.parent
    if not parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {parent}")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=TEMP_SUFFIX, dir=parent)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)
        if overwrite:
            os.replace(tmp, path)
        else:
            _rename_no_clobber(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _rename_no_clobber(tmp, path):
    try:
        os.link(tmp, path)  # fails if path exists: no window to clobber it
    except FileExistsError:
        raise OutputExistsError(path) from None
    except OSError:  # file systems without hard links
        if path.exists():
            raise OutputExistsError(path) from None
        os.replace(tmp, path)
        return
    os.unlink(tmp)


def write_image(path, array, info=None, *, overwrite=False):
    """Write ``array`` to ``path`` atomically, in the format its extension
    names, with the metadata of ``info`` (from :func:`read_image`) where the
    format allows. Raises ImageError when the format cannot store the
    array, OutputExistsError when ``path`` exists and not ``overwrite``."""
    array = np.asarray(array)
    dtype, channels = _layout(array)
    fmt = check_writable(path, dtype, channels, info)
    if fmt == "PNG":
        data = _png_encode(array, info)
        atomic_write(path, lambda f: f.write(data), overwrite=overwrite)
        return
    Image = _pillow(f"writing {fmt}")
    im = _to_pillow(array, _pil_mode(dtype, channels, info), Image)
    params = _save_params(fmt, info, im.mode)
    atomic_write(path, lambda f: im.save(f, format=fmt, **params), overwrite=overwrite)


def _to_pillow(array, mode, Image):
    h, w = array.shape[:2]
    if mode == "I;16":
        data = np.ascontiguousarray(array, dtype="<u2")
    elif mode == "F":
        data = np.ascontiguousarray(array, dtype="=f4")
    else:
        data = np.ascontiguousarray(array, dtype=np.uint8)
    return Image.frombytes(mode, (w, h), data.tobytes())


def _save_params(fmt, info, mode):
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
    lossless = ("tiff_lzw", "tiff_adobe_deflate", "tiff_deflate", "packbits")
    if fmt == "TIFF" and info.format == "TIFF" and info.tiff_compression in lossless:
        params["compression"] = info.tiff_compression  # the input's (lossless) compression
    return params
