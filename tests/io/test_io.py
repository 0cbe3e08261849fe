"""Image files: lossless round trips, metadata kept, atomic writes that never
clobber or leave temporary files, clear errors for what cannot be read."""

import errno
import os
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image, ImageCms, ImageOps

import fpiwarp
from fpiwarp.io import images as io
from fpiwarp.io.images import ImageError, OutputExistsError, OutputIsFolderError, read_image, write_image

LAYOUTS = [
    ((13, 17), np.uint8),
    ((13, 17, 2), np.uint8),
    ((13, 17, 3), np.uint8),
    ((13, 17, 4), np.uint8),
    ((13, 17), np.uint16),
    ((13, 17, 2), np.uint16),
    ((13, 17, 3), np.uint16),
    ((13, 17, 4), np.uint16),
]


def _random(shape, dtype, rng):
    if np.dtype(dtype).kind == "f":
        return rng.standard_normal(shape).astype(dtype)
    return rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)


def _leftovers(folder):
    return [p.name for p in folder.iterdir() if p.name.endswith(io.TEMP_SUFFIX)]


def _needs_extra(shape, dtype, fmt):
    """Skip a 16-bit colour case when the io extra's codec is missing."""
    if np.dtype(dtype) == np.uint16 and len(shape) == 3:
        pytest.importorskip({"PNG": "imagecodecs", "TIFF": "tifffile"}[fmt])


@pytest.fixture
def without(monkeypatch):
    """Make ``import NAME`` fail, as when the io extra is not installed."""

    def block(name):
        monkeypatch.setitem(sys.modules, name, None)

    return block


def _chunk(ctype, payload):
    return struct.pack(">I", len(payload)) + ctype + payload + struct.pack(">I", zlib.crc32(ctype + payload))


def _png(width, height, depth, color, idat, extra=()):
    """PNG bytes from parts, written here independently of fpiwarp."""
    ihdr = struct.pack(">IIBBBBB", width, height, depth, color, 0, 0, 0)
    middle = b"".join(_chunk(t, p) for t, p in extra)
    return io.PNG_SIGNATURE + _chunk(b"IHDR", ihdr) + middle + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


def _png_with_every_filter(image, extra=()):
    """A PNG whose rows use filter types 0-4 in turn (encoded from the PNG
    specification), 8- or 16-bit."""
    h, w, c = image.shape
    nbytes = image.dtype.itemsize
    raw = image.astype(f">u{nbytes}").view(np.uint8).reshape(h, w * c * nbytes).astype(np.int64)
    bpp = c * nbytes
    rows = []
    for r in range(h):
        cur = raw[r]
        prev = raw[r - 1] if r else np.zeros_like(cur)
        left = np.concatenate([np.zeros(bpp, np.int64), cur[:-bpp]])
        upleft = np.concatenate([np.zeros(bpp, np.int64), prev[:-bpp]])
        ftype = r % 5
        if ftype == 0:
            pred = 0
        elif ftype == 1:
            pred = left
        elif ftype == 2:
            pred = prev
        elif ftype == 3:
            pred = (left + prev) // 2
        else:
            p = left + prev - upleft
            pa, pb, pc = abs(p - left), abs(p - prev), abs(p - upleft)
            pred = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, prev, upleft))
        rows.append(bytes([ftype]) + ((cur - pred) % 256).astype(np.uint8).tobytes())
    color = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    return _png(w, h, nbytes * 8, color, zlib.compress(b"".join(rows)), extra)


# --------------------------------------------------------------------------
# Pixels: every layout, every codec path, exact


@pytest.mark.parametrize("shape, dtype", LAYOUTS)
def test_png_round_trip_is_exact(tmp_path, rng, shape, dtype):
    _needs_extra(shape, dtype, "PNG")
    image = _random(shape, dtype, rng)
    write_image(tmp_path / "a.png", image)
    back, info = read_image(tmp_path / "a.png", with_info=True)
    assert back.dtype == image.dtype and back.shape == image.shape
    np.testing.assert_array_equal(back, image)
    assert info.format == "PNG"


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_png_reader_handles_every_row_filter(tmp_path, rng, channels, dtype):
    _needs_extra((1, 1, channels) if channels > 1 else (1, 1), dtype, "PNG")
    image = _random((11, 9, channels), dtype, rng)
    (tmp_path / "f.png").write_bytes(_png_with_every_filter(image, [(b"tEXt", b"Comment\0kept")]))
    back, info = read_image(tmp_path / "f.png", with_info=True)
    assert back.dtype == image.dtype
    np.testing.assert_array_equal(back.reshape(image.shape), image)
    write_image(tmp_path / "g.png", back, info)
    chunks = io.png_chunks((tmp_path / "g.png").read_bytes(), "g.png")
    assert (b"tEXt", b"Comment\0kept") in chunks  # metadata copied


def _adam7_png(image):
    """An interlaced (Adam7) PNG of an (H, W, C) array, rows unfiltered."""
    h, w, c = image.shape
    nbytes = image.dtype.itemsize
    passes = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]
    raw = b""
    for x0, y0, dx, dy in passes:
        sub = image[y0::dy, x0::dx].astype(f">u{nbytes}")
        if sub.size:
            raw += b"".join(b"\0" + row.tobytes() for row in sub)
    png = _png(w, h, nbytes * 8, {1: 0, 2: 4, 3: 2, 4: 6}[c], zlib.compress(raw))
    ihdr = bytearray(png[16:29])
    ihdr[12] = 1  # interlace method: Adam7
    return png[:8] + _chunk(b"IHDR", bytes(ihdr)) + png[33:]


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_interlaced_png_is_read(tmp_path, rng, dtype):
    _needs_extra((1, 1, 3), dtype, "PNG")
    image = _random((11, 13, 3), dtype, rng)
    (tmp_path / "i.png").write_bytes(_adam7_png(image))
    np.testing.assert_array_equal(read_image(tmp_path / "i.png"), image)


def test_other_readers_decode_our_png_alike(tmp_path, rng):
    cv2 = pytest.importorskip("cv2")
    rgb8 = _random((9, 12, 3), np.uint8, rng)
    write_image(tmp_path / "a.png", rgb8)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), rgb8)
    pytest.importorskip("imagecodecs")
    rgba16 = _random((9, 12, 4), np.uint16, rng)
    write_image(tmp_path / "b.png", rgba16)
    from_cv2 = cv2.imread(str(tmp_path / "b.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(from_cv2[..., [2, 1, 0, 3]], rgba16)
    np.testing.assert_array_equal(read_image(tmp_path / "b.png"), rgba16)


def test_16_bit_rgb_png_with_trns_stays_rgb_and_keeps_the_chunk(tmp_path, rng):
    """libpng would turn tRNS into a fourth channel: the reader keeps the
    file's three channels and the chunk, as for 8-bit RGB."""
    pytest.importorskip("imagecodecs")
    image = _random((5, 6, 3), np.uint16, rng)
    image[0, 0] = (1, 2, 3)
    trns = (b"tRNS", struct.pack(">HHH", 1, 2, 3))
    (tmp_path / "t.png").write_bytes(_png_with_every_filter(image, [trns]))
    back, info = read_image(tmp_path / "t.png", with_info=True)
    np.testing.assert_array_equal(back, image)
    write_image(tmp_path / "u.png", back, info)
    assert trns in io.png_chunks((tmp_path / "u.png").read_bytes(), "u.png")


@pytest.mark.parametrize(
    "shape, dtype",
    [
        ((10, 14), np.uint8),
        ((10, 14, 3), np.uint8),
        ((10, 14, 4), np.uint8),
        ((10, 14), np.uint16),
        ((10, 14, 2), np.uint16),
        ((10, 14, 3), np.uint16),
        ((10, 14, 4), np.uint16),
        ((10, 14), np.float32),
    ],
)
def test_tiff_round_trip_is_exact(tmp_path, rng, shape, dtype):
    _needs_extra(shape, dtype, "TIFF")
    image = _random(shape, dtype, rng)
    write_image(tmp_path / "a.tif", image)
    back, info = read_image(tmp_path / "a.tif", with_info=True)
    assert info.format == "TIFF" and back.dtype == image.dtype
    np.testing.assert_array_equal(back, image)


def test_16_bit_color_tiff_from_another_writer_is_read_exactly(tmp_path, rng):
    pytest.importorskip("tifffile")
    cv2 = pytest.importorskip("cv2")
    image = _random((6, 7, 3), np.uint16, rng)
    cv2.imwrite(str(tmp_path / "deep.tif"), image[..., ::-1])
    back, info = read_image(tmp_path / "deep.tif", with_info=True)
    np.testing.assert_array_equal(back, image)
    assert info.mode == "RGB;16"


def test_16_bit_color_tiff_keeps_lzw_compression_icc_and_dpi(tmp_path, rng):
    tifffile = pytest.importorskip("tifffile")
    pytest.importorskip("imagecodecs")  # tifffile's LZW codec
    icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    image = _random((6, 7, 4), np.uint16, rng)
    tifffile.imwrite(
        tmp_path / "in.tif",
        image,
        photometric="rgb",
        extrasamples=["unassalpha"],
        compression="lzw",
        extratags=[(34675, 7, len(icc), icc, True)],
        resolution=(300, 300),
        resolutionunit="INCH",
    )
    back, info = read_image(tmp_path / "in.tif", with_info=True)
    write_image(tmp_path / "out.tif", back, info)
    again, info2 = read_image(tmp_path / "out.tif", with_info=True)
    np.testing.assert_array_equal(again, image)
    assert info2.tiff_compression == "tiff_lzw" and info2.icc_profile == icc
    assert tuple(round(d) for d in info2.dpi) == (300, 300)


# --------------------------------------------------------------------------
# Metadata


def test_jpeg_round_trip_keeps_layout_quality_and_icc_profile(tmp_path):
    icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    y, x = np.mgrid[0:32, 0:48]
    smooth = np.stack([x * 5, y * 7, (x + y) * 3], axis=-1).astype(np.uint8)
    Image.fromarray(smooth).save(tmp_path / "in.jpg", quality=80, icc_profile=icc, dpi=(300, 300))
    image, info = read_image(tmp_path / "in.jpg", with_info=True)
    assert image.shape == (32, 48, 3) and image.dtype == np.uint8 and info.icc_profile == icc
    write_image(tmp_path / "out.jpg", image, info)
    again, info2 = read_image(tmp_path / "out.jpg", with_info=True)
    assert info2.icc_profile == icc
    assert info2.jpeg_qtables == info.jpeg_qtables  # the input's quality, not a default
    assert np.abs(again.astype(int) - image.astype(int)).max() <= 8
    assert tuple(round(d) for d in info2.dpi) == (300, 300)


@pytest.mark.parametrize(
    "name, dtype", [("out.png", np.uint8), ("out.tif", np.uint8), ("out.png", np.uint16), ("out.tif", np.uint16)]
)
def test_icc_profile_and_dpi_are_kept_in_png_and_tiff(tmp_path, rng, name, dtype):
    _needs_extra((6, 5, 3), dtype, "PNG" if name.endswith(".png") else "TIFF")
    icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    info = io.ImageInfo(format="JPEG", mode="RGB", icc_profile=icc, dpi=(300.0, 300.0))
    write_image(tmp_path / name, _random((6, 5, 3), dtype, rng), info)
    back = read_image(tmp_path / name, with_info=True)[1]
    assert back.icc_profile == icc and tuple(round(d) for d in back.dpi) == (300, 300)


@pytest.mark.parametrize("name", ["out.jpg", "out.png", "out.tif"])
def test_exif_is_kept(tmp_path, rng, name):
    exif = Image.Exif()
    exif[0x010F] = "fpiwarp test camera"  # Make
    Image.fromarray(_random((8, 10, 3), np.uint8, rng)).save(tmp_path / "in.jpg", exif=exif.tobytes())
    image, info = read_image(tmp_path / "in.jpg", with_info=True)
    write_image(tmp_path / name, image, info)
    with Image.open(tmp_path / name) as im:
        assert im.getexif().get(0x010F) == "fpiwarp test camera"


def test_png_color_and_text_chunks_are_kept_only_where_still_true(tmp_path, rng):
    image = _random((6, 8, 3), np.uint8, rng)
    kept = [(b"gAMA", struct.pack(">I", 45455)), (b"sRGB", b"\0"), (b"zTXt", b"Note\0\0" + zlib.compress(b"hi"))]
    sbit = (b"sBIT", b"\x08\x08\x08")
    (tmp_path / "in.png").write_bytes(_png_with_every_filter(image, [*kept, sbit]))
    back, info = read_image(tmp_path / "in.png", with_info=True)
    write_image(tmp_path / "same.png", back, info)
    chunks = io.png_chunks((tmp_path / "same.png").read_bytes(), "same.png")
    assert all(c in chunks for c in [*kept, sbit])
    write_image(tmp_path / "gray.png", back[..., 0], info)  # another encoding: sBIT no longer true
    chunks = io.png_chunks((tmp_path / "gray.png").read_bytes(), "gray.png")
    assert all(c in chunks for c in kept) and sbit not in chunks


def test_palette_and_bilevel_images_widen_to_rgb_and_gray(tmp_path, rng):
    rgb = _random((8, 8, 3), np.uint8, rng)
    Image.fromarray(rgb).convert("P").save(tmp_path / "p.png")
    image, info = read_image(tmp_path / "p.png", with_info=True)
    assert image.shape == (8, 8, 3) and info.mode == "RGB"
    Image.fromarray(rgb[..., 0] > 128).save(tmp_path / "b.png")
    image = read_image(tmp_path / "b.png")
    assert image.dtype == np.uint8 and set(np.unique(image)) <= {0, 255}


# --------------------------------------------------------------------------
# What cannot be read or written: one line naming the file


@pytest.mark.parametrize(
    "name, shape, dtype, problem",
    [
        ("a.jpg", (4, 4, 4), np.uint8, "JPEG cannot store 8-bit RGBA"),
        ("a.jpg", (4, 4), np.uint16, "JPEG cannot store 16-bit gray"),
        ("a.jpg", (4, 4, 3), np.uint16, "JPEG cannot store 16-bit RGB"),
        ("a.tif", (4, 4, 3), np.float32, "TIFF cannot store float32 RGB"),
        ("a.png", (4, 4), np.float32, "PNG cannot store float32"),
        ("a.xyz", (4, 4), np.uint8, "cannot tell the image format"),
    ],
)
def test_formats_refuse_what_they_cannot_store(tmp_path, name, shape, dtype, problem):
    with pytest.raises(ImageError, match=problem) as caught:
        write_image(tmp_path / name, np.zeros(shape, dtype))
    assert str(tmp_path / name) in str(caught.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "name, array, problem",
    [
        ("a.bmp", np.zeros((4, 4, 2), np.uint8), "Pillow cannot write this LA image as BMP"),
        ("a.png", np.zeros((4, 4, 5), np.uint8), "an image array must be"),
    ],
)
def test_what_pillow_refuses_is_one_line_naming_the_file(tmp_path, name, array, problem):
    with pytest.raises(ImageError, match=problem) as caught:
        write_image(tmp_path / name, array)
    assert str(caught.value).startswith(f"{tmp_path / name}: ") and "\n" not in str(caught.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name, module", [("a.png", "imagecodecs"), ("a.tif", "tifffile")])
def test_16_bit_color_without_the_io_extra_says_what_to_install(tmp_path, rng, without, name, module):
    pytest.importorskip(module)
    image = _random((4, 5, 3), np.uint16, rng)
    write_image(tmp_path / name, image)
    without(module)
    for action in (lambda: read_image(tmp_path / name), lambda: write_image(tmp_path / ("b" + name), image)):
        with pytest.raises(ImageError) as caught:
            action()
        message = str(caught.value)
        assert "\n" not in message and "pip install 'fpiwarp[io]'" in message and "16-bit" in message
        assert str(tmp_path) in message
    # 8-bit and 16-bit gray need only Pillow
    write_image(tmp_path / ("gray" + name), image[..., 0])
    np.testing.assert_array_equal(read_image(tmp_path / ("gray" + name)), image[..., 0])


def test_16_bit_gray_alpha_tiff_without_tifffile_says_what_to_install(tmp_path, rng, without):
    """Pillow does not even recognise this one: the message still helps."""
    pytest.importorskip("tifffile")
    write_image(tmp_path / "la.tif", _random((4, 5, 2), np.uint16, rng))
    without("tifffile")
    with pytest.raises(ImageError, match=r"la.tif: a TIFF that Pillow cannot read .*pip install 'fpiwarp\[io\]'"):
        read_image(tmp_path / "la.tif")


def test_16_bit_palette_png_is_called_invalid_not_interlaced(tmp_path):
    (tmp_path / "p16.png").write_bytes(_png(4, 4, 16, 3, zlib.compress(b"\0" * 40)))
    with pytest.raises(ImageError) as caught:
        read_image(tmp_path / "p16.png")
    message = str(caught.value)
    assert "p16.png" in message and "16-bit palette" in message and "interlace" not in message


def test_unreadable_files_give_clear_errors(tmp_path, rng):
    write_image(tmp_path / "good.png", _random((8, 8, 3), np.uint8, rng))
    data = (tmp_path / "good.png").read_bytes()
    (tmp_path / "truncated.png").write_bytes(data[: len(data) // 2])
    flipped = bytearray(data)
    flipped[60] ^= 0xFF
    (tmp_path / "crc.png").write_bytes(bytes(flipped))
    (tmp_path / "notes.png").write_text("not an image")
    (tmp_path / "bad-idat.png").write_bytes(_png(8, 8, 8, 0, b"not zlib"))
    with pytest.raises(ImageError, match="truncated"):
        read_image(tmp_path / "truncated.png")
    with pytest.raises(ImageError, match="corrupt PNG"):
        read_image(tmp_path / "crc.png")
    with pytest.raises(ImageError, match="notes.png"):
        read_image(tmp_path / "notes.png")
    with pytest.raises(ImageError, match="bad-idat.png"):
        read_image(tmp_path / "bad-idat.png")
    with pytest.raises(FileNotFoundError):
        read_image(tmp_path / "missing.png")
    with pytest.raises(ImageError, match="folder"):
        read_image(tmp_path)


def test_animations_are_refused(tmp_path):
    frames = [Image.new("L", (4, 4), v) for v in (0, 255)]
    frames[0].save(tmp_path / "anim.gif", save_all=True, append_images=frames[1:])
    with pytest.raises(ImageError, match="2 frames"):
        read_image(tmp_path / "anim.gif")


# --------------------------------------------------------------------------
# Decompression bombs: refused from the header, before decoding


def _tiff_header_only(width, height, samples, bits):
    """A little-endian TIFF whose IFD declares a size but holds 16 bytes of
    pixel data (written here from the TIFF 6.0 specification)."""
    entries = [
        (256, 4, 1, width),
        (257, 4, 1, height),
        (258, 3, 1, bits),  # same bits for every sample: one value suffices for readers
        (259, 3, 1, 1),
        (262, 3, 1, 2 if samples >= 3 else 1),
        (273, 4, 1, 8),
        (277, 3, 1, samples),
        (278, 4, 1, height),
        (279, 4, 1, 16),
        (284, 3, 1, 1),
    ]
    ifd_at = 8 + 16
    ifd = struct.pack("<H", len(entries))
    for tag, kind, count, value in entries:
        packed = struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value)
        ifd += struct.pack("<HHI", tag, kind, count) + packed
    return b"II*\0" + struct.pack("<I", ifd_at) + bytes(16) + ifd + struct.pack("<I", 0)


def _jpeg_declaring(path, width, height):
    """A tiny real JPEG whose frame header (SOF0) is patched to a huge size."""
    Image.new("L", (8, 8)).save(path, format="JPEG", quality=90)
    data = bytearray(path.read_bytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = struct.pack(">HH", height, width)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("kind", ["png8", "png16rgb", "jpeg", "tiff8", "tiff16rgb"])
def test_a_small_file_declaring_a_huge_size_is_refused_before_decoding(tmp_path, kind):
    width, height = 100_000, 100_000  # 10 Gpx: 60 GB as 16-bit RGB, were it decoded
    path = tmp_path / f"bomb-{kind}"
    if kind == "png8":
        path.write_bytes(_png(width, height, 8, 0, zlib.compress(b"\0" * 1000)))
    elif kind == "png16rgb":
        path.write_bytes(_png(width, height, 16, 2, zlib.compress(b"\0" * 1000)))
    elif kind == "jpeg":
        _jpeg_declaring(path, 60_000, 60_000)
        width = height = 60_000
    elif kind == "tiff8":
        path.write_bytes(_tiff_header_only(width, height, 1, 8))
    else:
        pytest.importorskip("tifffile")
        path.write_bytes(_tiff_header_only(width, height, 3, 16))
    assert path.stat().st_size < 2000
    with pytest.raises(ImageError, match="exceeds the limit of 178,956,970 pixels") as caught:
        read_image(path)
    message = str(caught.value)
    assert str(path) in message and "\n" not in message
    assert f"{width * height:,}" in message


@pytest.mark.parametrize(
    "name, shape, dtype",
    [
        ("a.png", (30, 40, 3), np.uint8),
        ("a.png", (30, 40, 3), np.uint16),
        ("a.jpg", (30, 40, 3), np.uint8),
        ("a.tif", (30, 40, 3), np.uint16),
        ("a.tif", (30, 40), np.float32),
    ],
)
def test_the_pixel_limit_holds_for_every_codec(tmp_path, rng, name, shape, dtype):
    _needs_extra(shape, dtype, "PNG" if name.endswith(".png") else "TIFF")
    write_image(tmp_path / name, _random(shape, dtype, rng))
    assert read_image(tmp_path / name, max_pixels=1200).shape == shape
    with pytest.raises(ImageError, match=r"40×30 = 1,200 pixels exceeds the limit of 1,199 pixels"):
        read_image(tmp_path / name, max_pixels=1199)


@settings(max_examples=60, deadline=None)
# Pillow warns while parsing a header of 89-179 Mpx (its warning limit is
# half its error limit); these headers are made to be refused.
@pytest.mark.filterwarnings("ignore::PIL.Image.DecompressionBombWarning")
@given(
    width=st.integers(1, 2**31 - 1),
    height=st.integers(1, 2**31 - 1),
    kind=st.sampled_from(["png8", "png16rgb", "tiff8", "tiff16rgb"]),
    data=st.data(),
)
def test_any_declared_size_over_the_limit_is_refused_from_the_header(tmp_path_factory, width, height, kind, data):
    """Sizes up to PNG's 2**31-1 per side, limits below the pixel count:
    refused with the header's size, whatever the codec, never decoded."""
    if kind.startswith("tiff16"):
        pytest.importorskip("tifffile")
    max_pixels = data.draw(st.integers(0, width * height - 1), label="max_pixels")
    path = tmp_path_factory.mktemp("declared") / kind
    if kind == "png8":
        path.write_bytes(_png(width, height, 8, 0, zlib.compress(b"\0" * 64)))
    elif kind == "png16rgb":
        path.write_bytes(_png(width, height, 16, 2, zlib.compress(b"\0" * 64)))
    else:
        path.write_bytes(_tiff_header_only(width, height, 1 if kind == "tiff8" else 3, 8 if kind == "tiff8" else 16))
    with pytest.raises(ImageError, match=f"exceeds the limit of {max_pixels:,} pixels") as caught:
        read_image(path, max_pixels=max_pixels)
    assert str(path) in str(caught.value) and f"{width * height:,}" in str(caught.value)


@settings(max_examples=40, deadline=None)
@given(
    height=st.integers(1, 20),
    width=st.integers(1, 20),
    channels=st.integers(1, 4),
    dtype=st.sampled_from([np.uint8, np.uint16]),
    ext=st.sampled_from([".png", ".tif"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_every_small_layout_round_trips_exactly(tmp_path_factory, height, width, channels, dtype, ext, seed):
    shape = (height, width) if channels == 1 else (height, width, channels)
    _needs_extra(shape, dtype, "PNG" if ext == ".png" else "TIFF")
    image = _random(shape, dtype, np.random.default_rng(seed))
    path = tmp_path_factory.mktemp("layout") / f"a{ext}"
    write_image(path, image)
    back = read_image(path)
    assert back.dtype == image.dtype
    np.testing.assert_array_equal(back, image)


def test_an_ordinary_16_bit_rgb_png_reads_in_well_under_a_second(tmp_path):
    """2000×1500 16-bit RGB with Paeth rows took 6.5 s in the former
    pure-Python decoder; libpng takes about a tenth of a second."""
    import time

    imagecodecs = pytest.importorskip("imagecodecs")
    y, x = np.mgrid[0:1500, 0:2000]
    image = np.stack([x * 30, y * 40, (x + y) * 13], axis=-1).astype(np.uint16)
    path = tmp_path / "photo16.png"
    path.write_bytes(imagecodecs.png_encode(image, filter=imagecodecs.PNG.FILTER.PAETH))
    seconds = []
    for _ in range(3):  # the best of three: a shared machine's load is not the reader's
        start = time.perf_counter()
        back = read_image(path)
        seconds.append(time.perf_counter() - start)
    np.testing.assert_array_equal(back, image)
    assert min(seconds) < 1.0, seconds


# --------------------------------------------------------------------------
# EXIF orientation


def _exif_with_orientation(value):
    exif = Image.Exif()
    exif[0x0112] = value
    exif[0x010F] = "fpiwarp test camera"
    return exif.tobytes()


@pytest.mark.parametrize("orientation", range(1, 9))
def test_orientation_is_applied_as_pillow_and_viewers_do(tmp_path, rng, orientation):
    stored = _random((5, 8, 3), np.uint8, rng)
    Image.fromarray(stored).save(tmp_path / "o.png", exif=_exif_with_orientation(orientation))
    with Image.open(tmp_path / "o.png") as im:
        expected = np.asarray(ImageOps.exif_transpose(im))
    image, info = read_image(tmp_path / "o.png", with_info=True)
    np.testing.assert_array_equal(image, expected)
    assert info.orientation == 1
    raw, raw_info = read_image(tmp_path / "o.png", orientation="stored", with_info=True)
    np.testing.assert_array_equal(raw, stored)
    assert raw_info.orientation == orientation


def test_16_bit_png_orientation_is_applied_too(tmp_path, rng):
    pytest.importorskip("imagecodecs")
    stored = _random((5, 8, 3), np.uint16, rng)
    exif = (b"eXIf", _exif_with_orientation(6).removeprefix(b"Exif\0\0"))
    (tmp_path / "o.png").write_bytes(_png_with_every_filter(stored, [exif]))
    image, info = read_image(tmp_path / "o.png", with_info=True)
    np.testing.assert_array_equal(image, np.rot90(stored, -1))
    write_image(tmp_path / "out.png", image, info)
    with Image.open(tmp_path / "out.png") as im:
        assert 0x0112 not in im.getexif() and im.getexif()[0x010F] == "fpiwarp test camera"


def test_a_portrait_jpeg_is_read_as_shown_and_written_with_a_consistent_tag(tmp_path, rng):
    """Orientation 6: stored 45 wide and 30 high, shown 30 wide and 45 high."""
    stored = np.repeat(np.repeat(_random((3, 5, 3), np.uint8, rng), 10, axis=0), 9, axis=1)
    Image.fromarray(stored).save(tmp_path / "in.jpg", quality=95, exif=_exif_with_orientation(6))
    image, info = read_image(tmp_path / "in.jpg", with_info=True)
    raw, raw_info = read_image(tmp_path / "in.jpg", orientation="stored", with_info=True)
    assert image.shape == (45, 30, 3) and raw.shape == (30, 45, 3) and raw_info.orientation == 6
    np.testing.assert_array_equal(image, np.rot90(raw, -1))  # turned 90° clockwise
    assert np.median(np.abs(raw.astype(int) - stored)) < 3
    write_image(tmp_path / "applied.jpg", image, info)
    with Image.open(tmp_path / "applied.jpg") as im:  # no tag: viewers show it as written
        assert im.size == (30, 45) and im.getexif().get(0x0112, 1) == 1
        assert im.getexif()[0x010F] == "fpiwarp test camera"  # the rest of the EXIF is kept

    write_image(tmp_path / "stored.jpg", raw, raw_info)
    with Image.open(tmp_path / "stored.jpg") as im:  # stored pixels keep their tag
        assert im.size == (45, 30) and im.getexif()[0x0112] == 6


def _tiff_orientation(path):
    tifffile = pytest.importorskip("tifffile")
    with tifffile.TiffFile(path) as tif:
        tag = tif.pages[0].tags.get(0x0112)
        return 1 if tag is None else tag.value


@pytest.mark.parametrize("orientation, turn", [(3, lambda a: a[::-1, ::-1]), (6, lambda a: np.rot90(a, -1))])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_tiff_orientation_is_applied_or_kept_with_its_pixels(tmp_path, rng, dtype, orientation, turn):
    """TIFF keeps the tag in its own header (Pillow for 8 bits, tifffile
    for 16-bit colour): applied, the output has none; stored, it has it."""
    tifffile = pytest.importorskip("tifffile")
    stored = _random((5, 8, 3), dtype, rng)
    tifffile.imwrite(tmp_path / "in.tif", stored, photometric="rgb", extratags=[(0x0112, "H", 1, orientation, True)])
    image, info = read_image(tmp_path / "in.tif", with_info=True)
    np.testing.assert_array_equal(image, turn(stored))
    write_image(tmp_path / "applied.tif", image, info)
    assert _tiff_orientation(tmp_path / "applied.tif") == 1
    raw, raw_info = read_image(tmp_path / "in.tif", orientation="stored", with_info=True)
    np.testing.assert_array_equal(raw, stored)
    write_image(tmp_path / "stored.tif", raw, raw_info)
    assert _tiff_orientation(tmp_path / "stored.tif") == orientation
    write_image(tmp_path / "stored.png", raw, raw_info)  # into another format, the tag goes along
    assert read_image(tmp_path / "stored.png", orientation="stored", with_info=True)[1].orientation == orientation


def test_xmp_and_raw_profile_copies_of_the_tag_go_when_it_is_applied(tmp_path, rng):
    stored = _random((5, 8, 3), np.uint8, rng)
    xmp = b'XML:com.adobe.xmp\0\0\0\0\0<x:xmpmeta><rdf:Description tiff:Orientation="6" tiff:Make="cam"/></x:xmpmeta>'
    exif = _exif_with_orientation(6).removeprefix(b"Exif\0\0")
    raw_profile = b"Raw profile type exif\0\nexif\n" + f"{len(exif):8}\n".encode() + exif.hex().encode() + b"\n"
    chunks = [(b"eXIf", exif), (b"iTXt", xmp), (b"tEXt", raw_profile)]
    (tmp_path / "in.png").write_bytes(_png_with_every_filter(stored, chunks))
    image, info = read_image(tmp_path / "in.png", with_info=True)
    write_image(tmp_path / "out.png", image, info)
    kept = dict(io.png_chunks((tmp_path / "out.png").read_bytes(), "out.png")[1:-2])
    assert b"Orientation" not in kept[b"iTXt"] and b'tiff:Make="cam"' in kept[b"iTXt"]
    assert b"tEXt" not in kept
    with Image.open(tmp_path / "out.png") as im:
        assert im.size == (5, 8) and im.getexif().get(0x0112, 1) == 1


@pytest.mark.filterwarnings("ignore:Corrupt EXIF data")  # Pillow says so, and so it is
def test_unreadable_exif_does_not_stop_reading(tmp_path, rng):
    image = _random((6, 7, 3), np.uint8, rng)
    Image.fromarray(image).save(tmp_path / "a.png", exif=b"Exif\0\0MM\0*garbage")
    back, info = read_image(tmp_path / "a.png", with_info=True)
    np.testing.assert_array_equal(back, image)
    assert info.orientation == 1


def test_an_unknown_orientation_choice_is_refused(tmp_path, rng):
    write_image(tmp_path / "a.png", _random((4, 4), np.uint8, rng))
    with pytest.raises(ValueError, match="'apply', 'stored'"):
        read_image(tmp_path / "a.png", orientation="rotate")


# --------------------------------------------------------------------------
# Atomic writes


def test_existing_output_is_kept_without_overwrite(tmp_path, rng):
    path = tmp_path / "out.png"
    path.write_bytes(b"precious")
    with pytest.raises(OutputExistsError, match="already exists"):
        write_image(path, _random((4, 4), np.uint8, rng))
    assert path.read_bytes() == b"precious" and _leftovers(tmp_path) == []
    image = _random((4, 4), np.uint8, rng)
    write_image(path, image, overwrite=True)
    np.testing.assert_array_equal(read_image(path), image)


@pytest.mark.parametrize("umask", [0o022, 0o027, 0o077])
def test_written_files_get_the_permissions_of_any_new_file(tmp_path, rng, umask):
    previous = os.umask(umask)
    try:
        write_image(tmp_path / "out.png", _random((4, 4), np.uint8, rng))
        (tmp_path / "plain").write_bytes(b"")
    finally:
        os.umask(previous)
    mode = os.stat(tmp_path / "out.png").st_mode & 0o777
    assert mode == 0o666 & ~umask == os.stat(tmp_path / "plain").st_mode & 0o777


def test_importing_and_writing_never_touch_the_umask(tmp_path):
    code = (
        "import os, sys, numpy as np\n"
        "def refuse(*args): raise AssertionError('os.umask called')\n"
        "os.umask = refuse\n"
        "from fpiwarp import io\n"
        "io.write_image(sys.argv[1], np.zeros((4, 4), np.uint8))\n"
    )
    result = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a.png")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "a.png").exists()


@pytest.mark.parametrize("error", [RuntimeError("disk on fire"), KeyboardInterrupt()])
def test_a_failed_write_leaves_nothing_behind(tmp_path, error):
    def write(f):
        f.write(b"half a file")
        raise error

    with pytest.raises(type(error)):
        io.atomic_write(tmp_path / "out.png", write)
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "old.png").write_bytes(b"old")
    with pytest.raises(type(error)):
        io.atomic_write(tmp_path / "old.png", write, overwrite=True)
    assert (tmp_path / "old.png").read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["old.png"]


def test_an_output_appearing_while_writing_is_not_clobbered(tmp_path):
    path = tmp_path / "out.png"

    def write(f):
        path.write_bytes(b"someone else's")
        f.write(b"ours")

    with pytest.raises(OutputExistsError):
        io.atomic_write(path, write)
    assert path.read_bytes() == b"someone else's" and _leftovers(tmp_path) == []


def test_missing_output_folder_is_an_error(tmp_path, rng):
    with pytest.raises(FileNotFoundError, match="output folder does not exist"):
        write_image(tmp_path / "nope" / "out.png", _random((4, 4), np.uint8, rng))


@pytest.mark.parametrize("overwrite", [False, True])
def test_an_output_that_is_a_folder_gets_one_message_naming_it(tmp_path, rng, overwrite):
    folder = tmp_path / "adir.png"
    folder.mkdir()
    image = _random((4, 4, 3), np.uint8, rng)
    with pytest.raises(OutputIsFolderError) as caught:
        write_image(folder, image, overwrite=overwrite)
    error = caught.value
    assert error.filename == str(folder) and "folder" in error.strerror
    assert str(error).startswith(f"{folder} is a folder") and io.TEMP_SUFFIX not in str(error)
    with pytest.raises(OutputIsFolderError):
        io.check_writable(folder, np.uint8, 3)
    assert list(folder.iterdir()) == [] and _leftovers(tmp_path) == []


@pytest.mark.parametrize(
    "where, code, text",
    [
        ("create", errno.EROFS, "Read-only file system"),
        ("create", errno.EACCES, "Permission denied"),
        ("write", errno.ENOSPC, "No space left on device"),
        ("rename", errno.EROFS, "Read-only file system"),
    ],
)
def test_file_system_errors_name_the_output_not_the_temporary_file(tmp_path, monkeypatch, where, code, text):
    """A read-only file system, a folder without write permission or a full
    disk: the message names the user's path and the real problem."""

    def fail(*args, **kwargs):
        name = args[0] if args and where != "write" else None
        raise OSError(code, os.strerror(code), str(name) if name else None)

    if where == "create":
        monkeypatch.setattr(os, "open", fail)
    elif where == "rename":
        monkeypatch.setattr(os, "link", fail)
        monkeypatch.setattr(os, "replace", fail)
    target = tmp_path / "out.png"
    with pytest.raises(OSError) as caught:
        io.atomic_write(target, fail if where == "write" else (lambda f: f.write(b"data")))
    error = caught.value
    assert error.errno == code and error.filename == str(target) and text in error.strerror
    assert io.TEMP_SUFFIX not in str(error)
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []


def test_a_limit_raised_beyond_pillows_says_which_limit_refused(tmp_path):
    path = tmp_path / "huge.jpg"
    _jpeg_declaring(path, 60_000, 60_000)
    with pytest.raises(ImageError, match=r"huge.jpg: image of 3,600,000,000 pixels exceeds Pillow's limit"):
        read_image(path, max_pixels=10**10)


@pytest.mark.parametrize("name", ["a.png", "a.jpg", "a.tif", "a.bmp", "a.webp"])
def test_read_image_returns_the_pixels_like_its_peers_and_the_info_on_request(tmp_path, name):
    """read_image(path) is the array (as imageio, skimage, cv2 and
    np.asarray(Image.open(p)) give): warp_image(read_image(p), f) works;
    with_info=True adds the metadata write_image keeps."""
    from PIL import Image

    image = (np.arange(6 * 5 * 3) % 251).astype(np.uint8).reshape(6, 5, 3)
    write_image(tmp_path / name, image)
    pixels = read_image(tmp_path / name)
    assert isinstance(pixels, np.ndarray) and pixels.shape == (6, 5, 3)
    with Image.open(tmp_path / name) as im:
        np.testing.assert_array_equal(pixels, np.asarray(im.convert("RGB")))
    again, info = read_image(tmp_path / name, with_info=True)
    np.testing.assert_array_equal(again, pixels)
    assert info.format and info.mode == "RGB"
    fpiwarp.warp_image(read_image(tmp_path / name), fpiwarp.FPI([[0, 0], [4, 0], [4, 5], [0, 5]],
                                                               [[0, 0], [4, 1], [4, 5], [0, 5]]))
