"""Image files: lossless round trips, metadata kept, atomic writes that never
clobber or leave temporary files, clear errors for what cannot be read."""

import os
import struct
import sys
import zlib

import numpy as np
import pytest

from fpiwarp import io
from fpiwarp.io import ImageError, OutputExistsError, read_image, write_image

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


@pytest.fixture
def no_pillow(monkeypatch):
    """Make ``import PIL`` fail, as in a numpy-only install."""
    for name in list(sys.modules):
        if name == "PIL" or name.startswith("PIL."):
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "PIL", None)
    assert not io.have_pillow()


@pytest.mark.parametrize("shape, dtype", LAYOUTS)
def test_png_round_trip_is_exact(tmp_path, rng, shape, dtype):
    image = _random(shape, dtype, rng)
    write_image(tmp_path / "a.png", image)
    back, info = read_image(tmp_path / "a.png")
    assert back.dtype == image.dtype and back.shape == image.shape
    np.testing.assert_array_equal(back, image)
    assert info.format == "PNG"


@pytest.mark.parametrize("shape, dtype", LAYOUTS)
def test_png_round_trip_without_pillow(tmp_path, rng, no_pillow, shape, dtype):
    image = _random(shape, dtype, rng)
    write_image(tmp_path / "a.png", image)
    np.testing.assert_array_equal(read_image(tmp_path / "a.png")[0], image)


def _png_with_every_filter(image):
    """A PNG whose rows use filter types 0-4 in turn (encoded here
    independently of fpiwarp, from the PNG specification)."""
    h, w, c = image.shape
    raw = image.reshape(h, w * c).astype(np.int64)
    rows = []
    for r in range(h):
        cur = raw[r]
        prev = raw[r - 1] if r else np.zeros_like(cur)
        left = np.concatenate([np.zeros(c, np.int64), cur[:-c]])
        upleft = np.concatenate([np.zeros(c, np.int64), prev[:-c]])
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

    def chunk(t, p):
        return struct.pack(">I", len(p)) + t + p + struct.pack(">I", zlib.crc32(t + p))

    return (
        io.PNG_SIGNATURE
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, color, 0, 0, 0))
        + chunk(b"tEXt", b"Comment\0kept")
        + chunk(b"IDAT", zlib.compress(b"".join(rows)))
        + chunk(b"IEND", b"")
    )


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_builtin_png_decoder_handles_every_row_filter(tmp_path, rng, no_pillow, channels):
    image = _random((11, 9, channels), np.uint8, rng)
    (tmp_path / "f.png").write_bytes(_png_with_every_filter(image))
    back, info = read_image(tmp_path / "f.png")
    np.testing.assert_array_equal(back.reshape(image.shape), image)
    write_image(tmp_path / "g.png", back, info)
    chunks = io._png_chunks((tmp_path / "g.png").read_bytes(), "g.png")
    assert (b"tEXt", b"Comment\0kept") in chunks  # metadata copied


def test_pillow_reads_the_builtin_png_and_16_bit_color_stays_16_bit(tmp_path, rng):
    Image = pytest.importorskip("PIL.Image")
    rgb8 = _random((9, 12, 3), np.uint8, rng)
    write_image(tmp_path / "a.png", rgb8)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), rgb8)
    rgb16 = _random((9, 12, 3), np.uint16, rng)
    write_image(tmp_path / "b.png", rgb16)
    back, _ = read_image(tmp_path / "b.png")  # Pillow would give 8 bits here
    assert back.dtype == np.uint16
    np.testing.assert_array_equal(back, rgb16)


@pytest.mark.parametrize(
    "shape, dtype",
    [
        ((10, 14), np.uint8),
        ((10, 14, 3), np.uint8),
        ((10, 14, 4), np.uint8),
        ((10, 14), np.uint16),
        ((10, 14), np.float32),
    ],
)
def test_tiff_round_trip_is_exact(tmp_path, rng, shape, dtype):
    pytest.importorskip("PIL")
    image = _random(shape, dtype, rng)
    write_image(tmp_path / "a.tif", image)
    back, info = read_image(tmp_path / "a.tif")
    assert info.format == "TIFF" and back.dtype == image.dtype
    np.testing.assert_array_equal(back, image)


def test_jpeg_round_trip_keeps_layout_quality_and_icc_profile(tmp_path):
    ImageCms = pytest.importorskip("PIL.ImageCms")
    Image = pytest.importorskip("PIL.Image")
    icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    y, x = np.mgrid[0:32, 0:48]
    smooth = np.stack([x * 5, y * 7, (x + y) * 3], axis=-1).astype(np.uint8)
    Image.fromarray(smooth).save(tmp_path / "in.jpg", quality=80, icc_profile=icc, dpi=(300, 300))
    image, info = read_image(tmp_path / "in.jpg")
    assert image.shape == (32, 48, 3) and image.dtype == np.uint8 and info.icc_profile == icc
    write_image(tmp_path / "out.jpg", image, info)
    again, info2 = read_image(tmp_path / "out.jpg")
    assert info2.icc_profile == icc
    assert info2.jpeg_qtables == info.jpeg_qtables  # the input's quality, not a default
    assert np.abs(again.astype(int) - image.astype(int)).max() <= 8
    assert tuple(round(d) for d in info2.dpi) == (300, 300)


@pytest.mark.parametrize("name", ["out.png", "out.tif"])
def test_icc_profile_is_kept_in_png_and_tiff(tmp_path, rng, name):
    ImageCms = pytest.importorskip("PIL.ImageCms")
    icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    info = io.ImageInfo(format="JPEG", mode="RGB", icc_profile=icc)
    write_image(tmp_path / name, _random((6, 5, 3), np.uint8, rng), info)
    assert read_image(tmp_path / name)[1].icc_profile == icc


def test_palette_and_bilevel_images_widen_to_rgb_and_gray(tmp_path, rng):
    Image = pytest.importorskip("PIL.Image")
    rgb = _random((8, 8, 3), np.uint8, rng)
    Image.fromarray(rgb).convert("P").save(tmp_path / "p.png")
    image, info = read_image(tmp_path / "p.png")
    assert image.shape == (8, 8, 3) and info.mode == "RGB"
    Image.fromarray(rgb[..., 0] > 128).save(tmp_path / "b.png")
    image, _ = read_image(tmp_path / "b.png")
    assert image.dtype == np.uint8 and set(np.unique(image)) <= {0, 255}


@pytest.mark.parametrize(
    "name, shape, dtype, problem",
    [
        ("a.jpg", (4, 4, 4), np.uint8, "JPEG cannot store 8-bit RGBA"),
        ("a.jpg", (4, 4), np.uint16, "JPEG cannot store 16-bit gray"),
        ("a.tif", (4, 4, 3), np.uint16, "TIFF cannot store 16-bit RGB"),
        ("a.png", (4, 4), np.float32, "PNG cannot store float32"),
        ("a.xyz", (4, 4), np.uint8, "cannot tell the image format"),
    ],
)
def test_formats_refuse_what_they_cannot_store(tmp_path, name, shape, dtype, problem):
    if not name.endswith(".png"):
        pytest.importorskip("PIL")
    with pytest.raises(ImageError, match=problem):
        write_image(tmp_path / name, np.zeros(shape, dtype))
    assert list(tmp_path.iterdir()) == []


def test_writing_jpeg_without_pillow_says_what_to_install(tmp_path, no_pillow):
    with pytest.raises(ImageError, match=r"pip install 'fpiwarp\[io\]'"):
        write_image(tmp_path / "a.jpg", np.zeros((4, 4, 3), np.uint8))


def test_16_bit_color_tiff_is_refused_not_truncated(tmp_path, rng):
    pytest.importorskip("PIL")
    cv2 = pytest.importorskip("cv2")
    cv2.imwrite(str(tmp_path / "deep.tif"), _random((6, 7, 3), np.uint16, rng))
    with pytest.raises(ImageError, match="16-bit RGB TIFF would be reduced to 8 bits"):
        read_image(tmp_path / "deep.tif")


def test_unreadable_files_give_clear_errors(tmp_path, rng):
    write_image(tmp_path / "good.png", _random((8, 8, 3), np.uint8, rng))
    data = (tmp_path / "good.png").read_bytes()
    (tmp_path / "truncated.png").write_bytes(data[: len(data) // 2])
    flipped = bytearray(data)
    flipped[60] ^= 0xFF
    (tmp_path / "crc.png").write_bytes(bytes(flipped))
    (tmp_path / "notes.png").write_text("not an image")
    with pytest.raises(ImageError, match="truncated"):
        read_image(tmp_path / "truncated.png")
    with pytest.raises(ImageError, match="corrupt PNG"):
        read_image(tmp_path / "crc.png")
    with pytest.raises((ImageError,), match="notes.png"):
        read_image(tmp_path / "notes.png")
    with pytest.raises(FileNotFoundError):
        read_image(tmp_path / "missing.png")
    with pytest.raises(ImageError, match="folder"):
        read_image(tmp_path)


def test_animations_are_refused(tmp_path):
    Image = pytest.importorskip("PIL.Image")
    frames = [Image.new("L", (4, 4), v) for v in (0, 255)]
    frames[0].save(tmp_path / "anim.gif", save_all=True, append_images=frames[1:])
    with pytest.raises(ImageError, match="2 frames"):
        read_image(tmp_path / "anim.gif")


def test_existing_output_is_kept_without_overwrite(tmp_path, rng):
    path = tmp_path / "out.png"
    path.write_bytes(b"precious")
    with pytest.raises(OutputExistsError, match="already exists"):
        write_image(path, _random((4, 4), np.uint8, rng))
    assert path.read_bytes() == b"precious" and _leftovers(tmp_path) == []
    image = _random((4, 4), np.uint8, rng)
    write_image(path, image, overwrite=True)
    np.testing.assert_array_equal(read_image(path)[0], image)


def test_written_files_get_ordinary_permissions(tmp_path, rng):
    write_image(tmp_path / "out.png", _random((4, 4), np.uint8, rng))
    mode = os.stat(tmp_path / "out.png").st_mode & 0o777
    assert mode == 0o666 & ~io._UMASK


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


def test_builtin_png_reader_refuses_decompression_bombs(tmp_path, monkeypatch):
    """A header promising more pixels than the limit is refused before any
    inflation; data inflating past the header's size is corrupt."""
    from fpiwarp import io as fio

    path = tmp_path / "big.png"
    fio.write_image(path, np.zeros((64, 64, 3), np.uint16))  # 16-bit: the built-in reader
    monkeypatch.setattr(fio, "MAX_PNG_PIXELS", 64 * 64 - 1)
    with pytest.raises(fio.ImageError, match="limit"):
        fio.read_image(path)
