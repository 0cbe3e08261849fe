"""Issue 25 items 5-8: special files as outputs, colour modes, damaged files, swapped and masked arguments."""

import io
import os
import socket
import stat
import struct
import zlib

import numpy as np
import pytest
from PIL import Image, ImageCms

import fpiwarp
from fpiwarp.errors import ArgumentTypeError, ImageError, OutputExistsError, OutputIsSpecialFileError

IMG = (np.arange(12 * 16 * 3) % 251).astype(np.uint8).reshape(12, 16, 3)


# --- item 5: outputs that are not regular files -------------------------------------------------------------------


def _special(tmp_path, kind):
    path = tmp_path / f"{kind}.png"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(path))
        return path, s
    elif kind == "device":
        try:
            os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
        except PermissionError:
            os.symlink("/dev/null", path)  # a link to the system's /dev/null: refused like its target
    return path, None


@pytest.mark.parametrize("kind", ["fifo", "socket", "device"])
@pytest.mark.parametrize("overwrite", [False, True])
def test_write_image_never_replaces_a_special_file(tmp_path, kind, overwrite):
    path, sock = _special(tmp_path, kind)
    before = os.lstat(path)
    with pytest.raises(OutputIsSpecialFileError) as info:
        fpiwarp.write_image(path, IMG, overwrite=overwrite)
    assert str(path) in str(info.value) and "\n" not in str(info.value) and "not a regular file" in str(info.value)
    after = os.lstat(path)
    assert (after.st_mode, after.st_ino) == (before.st_mode, before.st_ino)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left
    if sock is not None:
        sock.close()


def test_dev_null_itself_is_refused():
    with pytest.raises(OutputIsSpecialFileError, match="/dev/null is a character device"):
        fpiwarp.write_image("/dev/null", IMG, overwrite=True)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_a_symlink_to_a_fifo_or_nothing_is_refused(tmp_path):
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "to-fifo.png").symlink_to(tmp_path / "fifo")
    (tmp_path / "dangling.png").symlink_to(tmp_path / "missing.png")
    with pytest.raises(OutputIsSpecialFileError, match="symbolic link to a FIFO"):
        fpiwarp.write_image(tmp_path / "to-fifo.png", IMG, overwrite=True)
    with pytest.raises(OutputIsSpecialFileError, match="symbolic link to nothing"):
        fpiwarp.write_image(tmp_path / "dangling.png", IMG, overwrite=True)
    assert stat.S_ISFIFO(os.stat(tmp_path / "fifo").st_mode)


def test_a_symlink_to_a_regular_file_is_followed_and_kept(tmp_path):
    fpiwarp.write_image(tmp_path / "real.png", np.zeros((4, 4), np.uint8))
    link = tmp_path / "link.png"
    link.symlink_to("real.png")
    with pytest.raises(OutputExistsError):
        fpiwarp.write_image(link, IMG)
    fpiwarp.write_image(link, IMG, overwrite=True)
    assert link.is_symlink() and np.array_equal(fpiwarp.read_image(tmp_path / "real.png"), IMG)


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_reading_a_special_file_is_refused_not_waited_on(tmp_path, kind):
    path, _ = _special(tmp_path, kind)
    with pytest.raises(ImageError, match="not an image file"):
        fpiwarp.read_image(path)


# --- item 6: colour modes -----------------------------------------------------------------------------------------

RED = (255, 0, 0)


def _srgb_profile():
    return ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()


@pytest.mark.parametrize("icc", [None, "srgb"])
@pytest.mark.parametrize("ext", ["jpg", "tif"])
def test_cmyk_is_read_as_rgb(tmp_path, icc, ext):
    """Red in CMYK (0, 255, 255, 0) reads as RGB red. An embedded profile of another colour space (sRGB) cannot
    describe CMYK pixels: the plain formula is used, as without a profile."""
    path = tmp_path / f"cmyk.{ext}"
    kw = {"icc_profile": _srgb_profile()} if icc else {}
    Image.new("CMYK", (16, 12), (0, 255, 255, 0)).save(path, **kw)
    pixels, info = fpiwarp.read_image(path, with_info=True)
    assert pixels.shape == (12, 16, 3) and info.mode == "RGB" and info.icc_profile is None
    assert np.abs(pixels.astype(int) - RED).max() <= 2
    fpiwarp.write_image(tmp_path / "out.png", pixels, info)  # the reported case: CMYK JPEG to PNG
    assert np.array_equal(fpiwarp.read_image(tmp_path / "out.png"), pixels)


def test_cmyk_conversion_uses_a_cmyk_profile(tmp_path, monkeypatch):
    """With a CMYK ICC profile, littlecms converts to sRGB (no CMYK profile can be made here: the call is checked)."""
    from fpiwarp.io import pillow

    calls = []

    class FakeProfile:
        class profile:
            xcolor_space = "CMYK"

    def fake_profile_to_profile(im, source, target, outputMode):
        calls.append(outputMode)
        return Image.new("RGB", im.size, (1, 2, 3))

    monkeypatch.setattr(ImageCms, "ImageCmsProfile", lambda f: FakeProfile())
    monkeypatch.setattr(ImageCms, "profileToProfile", fake_profile_to_profile)
    info = pillow.ImageInfo(icc_profile=b"cmyk profile")
    out = pillow._cmyk_to_rgb(Image.new("CMYK", (3, 2)), info)
    assert calls == ["RGB"] and np.asarray(out)[0, 0].tolist() == [1, 2, 3] and info.icc_profile is None


def test_a_cmyk_info_names_cmyk_when_png_cannot_store_it(tmp_path):
    info = fpiwarp.io.ImageInfo(mode="CMYK")
    with pytest.raises(ImageError, match="PNG cannot store CMYK images"):
        fpiwarp.write_image(tmp_path / "x.png", np.zeros((2, 2, 4), np.uint8), info)


@pytest.mark.parametrize(
    "mode, value, expect",
    [
        ("YCbCr", None, (200, 30, 40)),
        ("LAB", (128, 128, 128), (119, 119, 119)),
        ("HSV", (0, 255, 255), RED),
    ],
)
def test_other_colour_spaces_are_read_as_rgb(tmp_path, mode, value, expect):
    im = Image.new("RGB", (8, 6), (200, 30, 40)).convert(mode) if value is None else Image.new(mode, (8, 6), value)
    path = tmp_path / "x.tif"
    if mode == "HSV":  # no format stores HSV: read_pillow's conversion is checked on the image itself
        from fpiwarp.io.pillow import _from_pillow

        im.format = "TIFF"
        arr, info = _from_pillow(im, path)
    else:
        im.save(path)
        arr, info = fpiwarp.read_image(path, with_info=True)
    assert arr.shape == (6, 8, 3) and info.mode == "RGB"
    assert np.abs(arr[0, 0].astype(int) - expect).max() <= 3


@pytest.mark.parametrize(
    "make, shape, dtype",
    [
        (lambda: Image.new("P", (8, 6), 3), (6, 8, 3), np.uint8),
        (lambda: _palette_with_transparency(), (6, 8, 4), np.uint8),
        (lambda: Image.new("PA", (8, 6), (3, 128)), (6, 8, 4), np.uint8),
        (lambda: Image.new("LA", (8, 6), (3, 128)), (6, 8, 2), np.uint8),
        (lambda: Image.new("1", (8, 6), 1), (6, 8), np.uint8),
        (lambda: Image.new("I;16", (8, 6), 300), (6, 8), np.uint16),
        (lambda: Image.new("F", (8, 6), 0.25), (6, 8), np.float32),
    ],
)
def test_palette_bilevel_and_deep_modes(tmp_path, make, shape, dtype):
    im = make()
    path = tmp_path / ("x.png" if im.mode in ("P", "LA", "1", "I;16") else "x.tif")
    if im.mode == "PA":  # no format Pillow writes stores PA: the conversion is checked on the image itself
        from fpiwarp.io.pillow import _from_pillow

        im.format = "PNG"
        arr = _from_pillow(im, path)[0]
    else:
        im.save(path)
        arr = fpiwarp.read_image(path)
    assert arr.shape == shape and arr.dtype == dtype
    if im.mode == "1":
        assert set(np.unique(arr)) == {255}


def _palette_with_transparency():
    im = Image.new("P", (8, 6), 3)
    im.info["transparency"] = 3
    return im


def test_big_endian_16_bit_gray(tmp_path):
    from fpiwarp.io.pillow import _from_pillow

    im = Image.frombytes("I;16B", (4, 2), np.arange(8, dtype=">u2").tobytes())
    im.format = "TIFF"
    arr, _ = _from_pillow(im, tmp_path / "x.tif")
    assert arr.dtype == np.uint16 and arr.ravel().tolist() == list(range(8))


# --- item 7: damaged files ----------------------------------------------------------------------------------------


def _jpeg(size=(64, 48)):
    b = io.BytesIO()
    Image.fromarray(np.resize(IMG, (size[1], size[0], 3))).save(b, format="JPEG", quality=90)
    return b.getvalue()


def _claims(w, h, progressive=False):
    """A small JPEG whose header claims w x h, padded with zeros to 1 KB."""
    b = io.BytesIO()
    Image.new("L", (16, 16), 128).save(b, format="JPEG", progressive=progressive)
    raw = bytearray(b.getvalue())
    sof = raw.find(b"\xff\xc2" if progressive else b"\xff\xc0")
    raw[sof + 5 : sof + 9] = struct.pack(">HH", h, w)
    return bytes(raw[:-2]) + b"\0" * max(0, 1024 - len(raw)) + b"\xff\xd9"


@pytest.mark.parametrize("w, h", [(9000, 9000), (4000, 300), (1000, 1000)])
def test_a_jpeg_too_small_for_its_header_is_refused_before_decoding(tmp_path, capfd, w, h):
    path = tmp_path / "claims.jpg"
    path.write_bytes(_claims(w, h))
    with pytest.raises(ImageError, match=rf"damaged JPEG: its header claims {w}x{h}") as info:
        fpiwarp.read_image(path)
    assert str(path) in str(info.value) and "damaged='accept'" in str(info.value)
    assert capfd.readouterr().err == ""


def test_accepting_a_damaged_jpeg_decodes_it(tmp_path, capfd):
    path = tmp_path / "claims.jpg"
    path.write_bytes(_claims(640, 480))
    assert fpiwarp.read_image(path, damaged="accept").shape == (480, 640)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("keep", [0.3, 0.5, 0.9])
def test_a_truncated_jpeg_is_refused_or_accepted_on_request(tmp_path, capfd, keep):
    data = _jpeg((256, 192))
    path = tmp_path / "cut.jpg"
    path.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(ImageError, match="truncated|damaged") as info:
        fpiwarp.read_image(path)
    assert str(path) in str(info.value)
    assert fpiwarp.read_image(path, damaged="accept").shape == (192, 256, 3)
    from PIL import ImageFile

    assert ImageFile.LOAD_TRUNCATED_IMAGES is False  # restored
    assert capfd.readouterr().err == ""


def test_a_good_jpeg_and_a_progressive_one_pass_the_size_check(tmp_path):
    (tmp_path / "a.jpg").write_bytes(_jpeg((640, 480)))
    Image.new("RGB", (2000, 2000), (9, 9, 9)).save(tmp_path / "p.jpg", progressive=True)
    Image.new("RGB", (2000, 2000), (9, 9, 9)).save(tmp_path / "flat.jpg", optimize=True)
    assert fpiwarp.read_image(tmp_path / "a.jpg").shape == (480, 640, 3)
    assert fpiwarp.read_image(tmp_path / "p.jpg").shape == (2000, 2000, 3)
    assert fpiwarp.read_image(tmp_path / "flat.jpg").shape == (2000, 2000, 3)  # a flat picture: the bound holds


def _png_with_idat(header, raw, cut=None):
    def chunk(t, p):
        return struct.pack(">I", len(p)) + t + p + struct.pack(">I", zlib.crc32(t + p))

    data = zlib.compress(raw)
    data = data if cut is None else data[: int(len(data) * cut)]
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data) + chunk(b"IEND", b"")


@pytest.mark.parametrize("color, channels", [(0, 1), (2, 3), (6, 4)])
@pytest.mark.parametrize("interlace", [0, 1])
def test_png_with_too_little_pixel_data_is_refused(tmp_path, capfd, color, channels, interlace):
    w, h = 32, 32
    header = struct.pack(">IIBBBBB", w, h, 16, color, 0, 0, interlace)
    raw = bytes(h * (1 + w * 2 * channels))  # the right size for a non-interlaced image
    path = tmp_path / "short.png"
    path.write_bytes(_png_with_idat(header, raw[: len(raw) // 3]))
    with pytest.raises(ImageError, match="damaged PNG") as info:
        fpiwarp.read_image(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("w, h", [(16, 16), (13, 11), (1, 9)])
def test_complete_interlaced_16_bit_png_reads_with_nothing_on_stderr(tmp_path, capfd, w, h):
    """libpng warns on stderr about every interlaced file it decodes (imagecodecs): silenced."""
    pytest.importorskip("imagecodecs")
    from fpiwarp.io.png import PngHeader, raw_size

    header = struct.pack(">IIBBBBB", w, h, 16, 2, 0, 0, 1)
    path = tmp_path / "adam7.png"
    path.write_bytes(_png_with_idat(header, bytes(raw_size(PngHeader(w, h, 16, 2, 1)))))
    arr = fpiwarp.read_image(path)
    assert arr.shape == (h, w, 3) and arr.dtype == np.uint16 and not arr.any()
    assert capfd.readouterr().err == ""


def test_accepting_a_short_16_bit_png_gives_nothing_on_stderr(tmp_path, capfd):
    pytest.importorskip("imagecodecs")
    header = struct.pack(">IIBBBBB", 32, 32, 16, 2, 0, 0, 1)
    path = tmp_path / "short.png"
    path.write_bytes(_png_with_idat(header, bytes(32 * (1 + 32 * 6))[:2000]))
    try:
        fpiwarp.read_image(path, damaged="accept")
    except ImageError as exc:  # libpng may still give up: then a one-line refusal
        assert "\n" not in str(exc)
    assert capfd.readouterr().err == ""


def test_png_raw_size_matches_pillow_for_interlaced_8_bit(tmp_path):
    from fpiwarp.io.png import png_chunks, png_header, raw_size

    for w, h in [(1, 1), (7, 5), (33, 17)]:
        b = io.BytesIO()
        Image.new("RGB", (w, h)).save(b, format="PNG")  # Pillow writes no interlaced PNG: check the plain case
        chunks = png_chunks(b.getvalue(), "x")
        raw = zlib.decompress(b"".join(p for t, p in chunks if t == b"IDAT"))
        assert raw_size(png_header(chunks, "x")) == len(raw)


def test_bad_damaged_value():
    with pytest.raises(fpiwarp.ArgumentError, match="damaged must be one of"):
        fpiwarp.read_image("x.png", damaged="yes")


# --- item 8: swapped arguments, short reprs, masked arrays --------------------------------------------------------


@pytest.mark.parametrize("array", [IMG, np.zeros((1080, 1920, 3), np.uint8), np.zeros((2, 2), np.float32)])
def test_write_image_with_swapped_arguments(tmp_path, array):
    with pytest.raises(ArgumentTypeError, match="arguments are swapped") as info:
        fpiwarp.write_image(array, tmp_path / "out.png")
    text = str(info.value)
    assert "\n" not in text and len(text) < 300 and f"shape {array.shape}" in text
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("bad", [IMG, 3, None, [1, 2]])
def test_read_image_and_write_image_refuse_a_non_path(bad, tmp_path):
    with pytest.raises(ArgumentTypeError) as info:
        fpiwarp.read_image(bad)
    assert "\n" not in str(info.value) and len(str(info.value)) < 200
    with pytest.raises(ArgumentTypeError):
        fpiwarp.write_image(bad, IMG)


@pytest.mark.parametrize("kw", [{"cval": np.zeros(10000)}, {"order": np.zeros(500)}, {"output_shape": np.zeros(900)},
                                {"mode": "x" * 5000}])
def test_messages_never_print_a_whole_user_value(kw):
    f = fpiwarp.FPI([[0, 0], [15, 0], [15, 11], [0, 11]], [[1, 0], [15, 1], [14, 11], [0, 10]])
    with pytest.raises(fpiwarp.FpiwarpError) as info:
        fpiwarp.warp_image(IMG, f, **kw)
    assert "\n" not in str(info.value) and len(str(info.value)) < 200


def _masked():
    m = np.ma.masked_array(IMG, mask=np.zeros(IMG.shape, bool))
    m.mask[:3] = True
    return m


F = fpiwarp.FPI([[0, 0], [15, 0], [15, 11], [0, 11]], [[1, 0], [15, 1], [14, 11], [0, 10]])


@pytest.mark.parametrize(
    "call",
    [
        lambda m, tmp: fpiwarp.warp_image(m, F),
        lambda m, tmp: fpiwarp.warp_image(m[..., 0], F, backend="numpy"),
        lambda m, tmp: __import__("fpiwarp.warping").warping.Warper(F)(m),
        lambda m, tmp: fpiwarp.warp_batch(np.ma.stack([m, m]), F),
        lambda m, tmp: fpiwarp.warp_images([m], F),
        lambda m, tmp: fpiwarp.write_image(tmp / "m.png", m),
    ],
    ids=["warp_image", "warp_image gray", "Warper", "warp_batch", "warp_images", "write_image"],
)
def test_masked_arrays_are_refused_with_the_way_out(tmp_path, call):
    with pytest.raises(ArgumentTypeError, match=r"MaskedArray.*\.filled\(value\).*\.data") as info:
        call(_masked(), tmp_path)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "m.png").exists()


def test_masked_array_filled_warps():
    assert fpiwarp.warp_image(_masked().filled(0), F).shape == IMG.shape
