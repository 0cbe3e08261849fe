"""Reliability run: how fpiwarp answers bad input, counted.

``python3 -m benchmarks.reliability [--out DIR] [--verbose]``

Families of bad API inputs (wrong types, shapes and dtypes, NaN/inf, huge
and subnormal values, swapped arguments, masked arrays, bad points and
quads, bad backend options, damaged and unusual image files, special files
as outputs) and command-line cases (bad paths, special files, corrupt
images, bad specs, a missing extra, batches with stray files), all run in
this process: the command line through :func:`fpiwarp.cli.main` with its
output captured, stderr captured at the file-descriptor level too (libpng
and other C libraries write there directly), Python warnings recorded.

Each case says what a demanding user expects: a refusal (a one-line
``FpiwarpError``; on the command line exit status 1 or 2 and one line on
stderr) or an answer (checked). Outcomes:

- ``clean``: the expected refusal, one line, no warning, nothing else on stderr;
- ``correct``: the expected answer, checked;
- ``accepted``: an answer where a refusal was due (data silently lost or wrong);
- ``wrong answer``: an answer that fails its check;
- ``refused``: a refusal where an answer was due;
- ``other exception`` / ``traceback``: not an FpiwarpError / CLI status 70;
- ``bad message``: a refusal on several lines or over 300 characters (an array printed);
- ``warnings``: a Python warning or C-library text on stderr;
- ``hang``: no answer in 20 s (a FIFO read, ...).

Writes ``reliability.md`` into DIR (default benchmarks/results/);
``reliability_before.md`` there is the run on the tree before the fixes of
issue 25 (items 4-10), kept for comparison.
"""

import argparse
import contextlib
import io
import os
import socket
import stat
import sys
import tempfile
import threading
import warnings
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.errors import FpiwarpError
from fpiwarp.spec import save_spec
from fpiwarp.warping import Warper

from .common import cpu_model

DEFAULT_OUT = Path(__file__).resolve().parent / "results"
MAX_MESSAGE = 300
TIMEOUT_S = 20.0

SRC = [[0, 0], [63, 0], [63, 47], [0, 47]]
DST = [[4, 2], [60, 1], [62, 45], [1, 44]]


class Case:
    """One bad input: ``run()`` does it; ``expect`` is "refuse", "answer"
    (then ``check(result)`` must be true) or "either"."""

    def __init__(self, family, name, run, expect="refuse", check=None, cli=False, accept=(), names=None):
        self.family, self.name, self.run, self.expect, self.check, self.cli = family, name, run, expect, check, cli
        self.names = names  # a word the refusal must contain (the user's argument, not an internal one)
        self.accept = accept  # other exception types that are a right refusal (FileNotFoundError)


# --------------------------------------------------------------------------
# Files to read and special files to write to


def _files(root):
    """Bad and unusual image files and special output paths in ``root``."""
    from PIL import Image, ImageCms

    f = {}
    rgb = (np.arange(48 * 64 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)
    f["good_png"] = root / "good.png"
    Image.fromarray(rgb).save(f["good_png"])
    f["good_jpg"] = root / "good.jpg"
    Image.fromarray(rgb).save(f["good_jpg"], quality=90)
    data = f["good_jpg"].read_bytes()
    f["truncated_jpg"] = root / "truncated.jpg"
    f["truncated_jpg"].write_bytes(data[: len(data) // 2])
    f["truncated_png"] = root / "truncated.png"
    f["truncated_png"].write_bytes(f["good_png"].read_bytes()[:-40])
    # a 1 KB JPEG whose header claims 9000 x 9000
    big = io.BytesIO()
    Image.new("L", (16, 16), 128).save(big, format="JPEG")
    raw = bytearray(big.getvalue())
    sof = raw.find(b"\xff\xc0")
    raw[sof + 5 : sof + 9] = (9000).to_bytes(2, "big") + (9000).to_bytes(2, "big")
    f["bomb_jpg"] = root / "claims-9000.jpg"
    f["bomb_jpg"].write_bytes(bytes(raw[:-2]) + b"\x00" * max(0, 1024 - len(raw)) + b"\xff\xd9")
    # an interlaced 16-bit PNG with too little data
    try:
        import imagecodecs

        arr16 = (np.arange(32 * 32 * 3) * 37 % 65536).astype(np.uint16).reshape(32, 32, 3)
        png = bytes(imagecodecs.png_encode(arr16))
        f["short16_png"] = root / "short16.png"
        f["short16_png"].write_bytes(_interlaced_short(png))
    except ImportError:
        pass
    cmyk = Image.new("CMYK", (32, 24), (0, 255, 255, 0))  # red
    f["cmyk_jpg"] = root / "cmyk.jpg"
    cmyk.save(f["cmyk_jpg"])
    f["cmyk_icc_jpg"] = root / "cmyk-icc.jpg"
    cmyk.save(f["cmyk_icc_jpg"], icc_profile=ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes())
    f["ycbcr_jpg"] = root / "ycbcr.tif"
    Image.new("RGB", (32, 24), (200, 30, 40)).convert("YCbCr").save(f["ycbcr_jpg"])
    f["lab_tif"] = root / "lab.tif"
    Image.new("LAB", (32, 24), (128, 128, 128)).save(f["lab_tif"])
    f["palette_png"] = root / "palette.png"
    Image.new("P", (32, 24), 3).save(f["palette_png"])
    f["bilevel_png"] = root / "bilevel.png"
    Image.new("1", (32, 24), 1).save(f["bilevel_png"])
    f["text"] = root / "notes.txt"
    f["text"].write_text("not an image\n")
    f["fifo"] = root / "fifo.png"
    os.mkfifo(f["fifo"])
    f["fifo_in"] = root / "fifo-in.png"  # read from (the other one is written to, and may be replaced)
    os.mkfifo(f["fifo_in"])
    f["sock"] = root / "sock.png"
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(f["sock"]))
    f["_socket"] = s
    f["link_fifo"] = root / "link-to-fifo.png"
    os.symlink(f["fifo"], f["link_fifo"])
    f["chardev"] = root / "null.png"
    try:  # a device node of our own (never the system's /dev/null: --overwrite could replace it)
        os.mknod(f["chardev"], stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, OSError):
        os.symlink("/dev/null", f["chardev"])
    f["folder"] = root / "folder.png"
    f["folder"].mkdir()
    f["spec_bad_json"] = root / "bad.json"
    f["spec_bad_json"].write_text("{not json")
    f["spec_missing"] = root / "missing-field.json"
    f["spec_missing"].write_text('{"type": "fpi", "src": [[0, 0], [1, 0], [1, 1], [0, 1]]}')
    f["spec_types"] = root / "types.json"
    f["spec_types"].write_text('{"type": "fpi", "src": "abc", "dst": 3}')
    f["spec_good"] = root / "good.json"
    save_spec(fpiwarp.FPI(SRC, DST), f["spec_good"])
    return f


def _interlaced_short(png):
    """``png`` (a PNG file's bytes) re-encoded interlaced (Adam7) and with
    its pixel data cut to a third: decodable by a forgiving decoder."""
    import struct
    import zlib

    from fpiwarp.io.png import PNG_SIGNATURE, png_chunks

    chunks = png_chunks(png, "png")
    ihdr = bytearray(chunks[0][1])
    w, h = struct.unpack(">II", bytes(ihdr[:8]))
    raw = zlib.decompress(b"".join(p for t, p in chunks if t == b"IDAT"))
    stride = 1 + w * 6
    rows = [raw[i * stride + 1 : (i + 1) * stride] for i in range(h)]
    out = bytearray()
    for x0, y0, dx, dy in ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2),
                           (0, 1, 1, 2)):
        for y in range(y0, h, dy):
            px = [rows[y][6 * x : 6 * x + 6] for x in range(x0, w, dx)]
            if px:
                out += b"\0" + b"".join(px)
    ihdr[12] = 1
    packed = zlib.compress(bytes(out))
    data = packed[: len(packed) // 3]

    def chunk(t, p):
        return struct.pack(">I", len(p)) + t + p + struct.pack(">I", zlib.crc32(t + p))

    return PNG_SIGNATURE + chunk(b"IHDR", bytes(ihdr)) + chunk(b"IDAT", data) + chunk(b"IEND", b"")


# --------------------------------------------------------------------------
# The cases


def _api_cases(f, root):
    img = np.zeros((48, 64, 3), np.uint8)
    fpi = fpiwarp.FPI(SRC, DST)
    cases = []

    def add(family, name, run, expect="refuse", check=None, accept=(), names=None):
        cases.append(Case(family, name, run, expect, check, accept=accept, names=names))

    w = fpiwarp.warp_image
    for name, bad in [("list", [[0, 1], [2, 3]]), ("str", "image.png"), ("None", None), ("dict", {}),
                      ("object dtype", np.zeros((4, 4), object)), ("complex", np.zeros((4, 4), complex)),
                      ("int8", np.zeros((4, 4), np.int8)), ("shape (0, 0)", np.zeros((0, 0), np.uint8)),
                      ("1-D", np.zeros(16, np.uint8)), ("5 channels", np.zeros((4, 4, 5), np.uint8)),
                      ("4-D", np.zeros((2, 4, 4, 3), np.uint8)), ("path object", Path("x.png"))]:
        add("image type/shape", name, lambda bad=bad: w(bad, fpi))
    add("image values", "NaN pixels", lambda: w(np.full((8, 8), np.nan, np.float32), fpi), "either")
    add("image values", "inf pixels", lambda: w(np.full((8, 8), np.inf, np.float32), fpi), "either")
    add("image values", "float64 1e300", lambda: w(np.full((8, 8), 1e300), fpi), "either")
    masked = np.ma.masked_array(img, mask=np.zeros(img.shape, bool))
    masked.mask[:10] = True
    add("masked arrays", "warp_image", lambda: w(masked, fpi))
    add("masked arrays", "Warper", lambda: Warper(fpi)(masked))
    add("masked arrays", "warp_batch", lambda: fpiwarp.warp_batch(np.ma.stack([masked, masked]), fpi))
    add("masked arrays", "warp_images", lambda: list(fpiwarp.warp_images([masked], fpi)))
    add("masked arrays", "write_image", lambda: fpiwarp.write_image(root / "masked.png", masked))
    add("swapped arguments", "write_image(array, path)", lambda: fpiwarp.write_image(img, root / "swap.png"))
    add("swapped arguments", "write_image(big array, path)",
        lambda: fpiwarp.write_image(np.zeros((480, 640, 3), np.uint8), root / "swap2.png"))
    add("swapped arguments", "warp_image(fpi, image)", lambda: w(fpi, img))
    add("swapped arguments", "read_image(array)", lambda: fpiwarp.read_image(img))
    for name, pts in [("NaN", [[np.nan, 0], [1, 0], [1, 1], [0, 1]]), ("inf", [[np.inf, 0], [1, 0], [1, 1], [0, 1]]),
                      ("3 points", [[0, 0], [1, 0], [1, 1]]), ("3-D points", [[0, 0, 0]] * 4),
                      ("strings", [["a", "b"]] * 4), ("coincident", [[0, 0], [0, 0], [1, 1], [0, 1]]),
                      ("collinear", [[0, 0], [1, 0], [2, 0], [0, 1]]), ("bow-tie", [[0, 0], [1, 1], [1, 0], [0, 1]]),
                      ("huge 1e300", (np.array(SRC) * 1e300).tolist()),
                      ("subnormal 1e-310", (np.array(SRC) * 1e-310 / 63).tolist()),
                      ("tiny 1e-200", (np.array(SRC) * 1e-200).tolist()), ("None", None)]:
        add("bad quads", f"FPI src {name}", lambda pts=pts: fpiwarp.FPI(pts, DST),
            "either" if "tiny" in name else "refuse", names="src")
    add("bad quads", "FPI dst subnormal", lambda: fpiwarp.FPI(SRC, (np.array(DST) * 1e-310 / 63).tolist()),
        names="dst")
    add("bad quads", "LocalDeformation bad edges", lambda: fpiwarp.LocalDeformation(SRC, DST, edges=(0, 0)))
    add("bad quads", "LocalDeformation edges 7", lambda: fpiwarp.LocalDeformation(SRC, DST, edges=(0, 7)))
    for name, pts in [("NaN", np.array([[np.nan, 1.0]])), ("shape (3,)", np.zeros(3)), ("str", "points"),
                      ("(2, 3)", np.zeros((2, 3)))]:
        add("bad points", f"map_points {name}", lambda pts=pts: fpiwarp.map_points(fpi, pts),
            "either" if name == "NaN" else "refuse")
    for name, kw in [("order 2", {"order": 2}), ("order '1'", {"order": "1"}), ("order 1.5", {"order": 1.5}),
                     ("mode 'foo'", {"mode": "foo"}), ("cval 'x'", {"cval": "x"}), ("cval NaN", {"cval": np.nan}),
                     ("cval 5 values", {"cval": [1, 2, 3, 4, 5]}), ("output_shape (0, 5)", {"output_shape": (0, 5)}),
                     ("output_shape (-1, 5)", {"output_shape": (-1, 5)}),
                     ("output_shape (2.5, 3)", {"output_shape": (2.5, 3)}),
                     ("output_shape 1e9", {"output_shape": (10**9, 10**9)}), ("backend 'nope'", {"backend": "nope"}),
                     ("backend 3", {"backend": 3}), ("backend_options bad key", {"backend_options": {"nope": 1}}),
                     ("antialias 'yes'", {"antialias": "yes"}), ("transform None", {"transform": None}),
                     ("transform str", {"transform": "fpi"})]:
        kwargs = dict(kw)
        transform = kwargs.pop("transform", fpi)
        add("bad options", name, lambda t=transform, k=kwargs: w(img, t, **k))
    r = fpiwarp.read_image
    add("files read", "missing file", lambda: r(root / "missing.png"), accept=(FileNotFoundError,))
    add("files read", "folder", lambda: r(f["folder"]))
    add("files read", "text file", lambda: r(f["text"]))
    add("files read", "truncated JPEG", lambda: r(f["truncated_jpg"]))
    add("files read", "truncated PNG", lambda: r(f["truncated_png"]))
    add("files read", "JPEG header claims 9000x9000", lambda: r(f["bomb_jpg"]))
    if "short16_png" in f:
        add("files read", "interlaced 16-bit PNG, short data", lambda: r(f["short16_png"]))
    add("files read", "FIFO", lambda: r(f["fifo_in"]))
    add("files read", "character device", lambda: r(f["chardev"]))

    def is_rgb(array, colour=None):
        ok = array.ndim == 3 and array.shape[2] in (3, 4)
        return ok and (colour is None or np.abs(array[0, 0, :3].astype(int) - colour).max() <= 12)

    add("modes read", "CMYK JPEG -> RGB red", lambda: r(f["cmyk_jpg"]), "answer", lambda a: is_rgb(a, (255, 0, 0)))
    add("modes read", "CMYK JPEG with ICC -> RGB", lambda: r(f["cmyk_icc_jpg"]), "either",
        lambda a: is_rgb(a))
    add("modes read", "YCbCr TIFF -> RGB", lambda: r(f["ycbcr_jpg"]), "answer", lambda a: is_rgb(a, (200, 30, 40)))
    add("modes read", "LAB TIFF -> RGB gray", lambda: r(f["lab_tif"]), "answer", lambda a: is_rgb(a))
    add("modes read", "palette PNG -> RGB", lambda: r(f["palette_png"]), "answer", lambda a: a.ndim == 3)
    add("modes read", "bilevel PNG -> gray", lambda: r(f["bilevel_png"]), "answer",
        lambda a: a.ndim == 2 and a.max() == 255)
    add("modes read", "CMYK JPEG written as PNG",
        lambda: fpiwarp.write_image(root / "cmyk-out.png", *r(f["cmyk_jpg"], with_info=True)), "answer",
        lambda _: is_rgb(r(root / "cmyk-out.png"), (255, 0, 0)))
    wi = fpiwarp.write_image
    add("files written", "folder", lambda: wi(f["folder"], img, overwrite=True))
    add("files written", "FIFO, overwrite", lambda: wi(f["fifo"], img, overwrite=True))
    add("files written", "socket, overwrite", lambda: wi(f["sock"], img, overwrite=True))
    add("files written", "character device, overwrite", lambda: wi(f["chardev"], img, overwrite=True))
    add("files written", "symlink to FIFO, overwrite", lambda: wi(f["link_fifo"], img, overwrite=True))
    add("files written", "existing file", lambda: wi(f["good_png"], img))
    add("files written", "unknown extension", lambda: wi(root / "out.xyz", img))
    add("files written", "missing folder", lambda: wi(root / "no" / "out.png", img), accept=(FileNotFoundError,))
    add("files written", "16-bit RGB as JPEG", lambda: wi(root / "o16.jpg", np.zeros((4, 4, 3), np.uint16)))
    return cases


def _cli_cases(f, root):
    cases = []
    src = "--src", ",".join(str(v) for p in SRC for v in p)
    dst = "--dst", ",".join(str(v) for p in DST for v in p)

    def add(family, name, argv, expect="refuse", check=None, setup=None, names=None):
        def run(argv=argv, setup=setup):
            with contextlib.ExitStack() as stack:
                if setup is not None:
                    setup(stack)
                return _cli(argv)
        cases.append(Case(family, name, run, expect, check, cli=True, names=names))

    good = str(f["good_png"])
    add("paths", "missing input", ["warp", str(root / "missing.png"), str(root / "o1.png"), *src, *dst])
    add("paths", "input is a folder", ["warp", str(f["folder"]), str(root / "o2.png"), *src, *dst])
    add("paths", "output is a folder", ["warp", good, str(f["folder"]), *src, *dst])
    add("paths", "output exists", ["warp", good, str(f["good_jpg"]), *src, *dst])
    add("paths", "output is the input", ["warp", good, good, "--overwrite", *src, *dst])
    add("paths", "output folder missing", ["warp", good, str(root / "nope" / "o.png"), *src, *dst])
    add("special files", "--overwrite onto a FIFO", ["warp", good, str(f["fifo"]), "--overwrite", *src, *dst])
    add("special files", "--overwrite onto a socket", ["warp", good, str(f["sock"]), "--overwrite", *src, *dst])
    add("special files", "--overwrite onto a device", ["warp", good, str(f["chardev"]), "--overwrite", *src, *dst])
    add("special files", "--overwrite onto a link to a FIFO",
        ["warp", good, str(f["link_fifo"]), "--overwrite", *src, *dst])
    add("special files", "input is a FIFO", ["warp", str(f["fifo_in"]), str(root / "o3.png"), *src, *dst])
    add("corrupt images", "truncated JPEG", ["warp", str(f["truncated_jpg"]), str(root / "o4.png"), *src, *dst])
    add("corrupt images", "JPEG claims 9000x9000", ["warp", str(f["bomb_jpg"]), str(root / "o5.png"), *src, *dst])
    if "short16_png" in f:
        add("corrupt images", "interlaced 16-bit PNG, short",
            ["warp", str(f["short16_png"]), str(root / "o6.png"), *src, *dst])
    add("corrupt images", "text file", ["warp", str(f["text"]), str(root / "o7.png"), *src, *dst])
    add("modes", "CMYK JPEG to PNG", ["warp", str(f["cmyk_jpg"]), str(root / "o8.png"), *src, *dst], "answer",
        lambda res: res[0] == 0)
    add("specs", "not JSON", ["warp", good, str(root / "o9.png"), "--spec", str(f["spec_bad_json"])])
    add("specs", "missing field", ["warp", good, str(root / "o10.png"), "--spec", str(f["spec_missing"])])
    add("specs", "wrong types", ["warp", good, str(root / "o11.png"), "--spec", str(f["spec_types"])])
    add("specs", "missing spec", ["warp", good, str(root / "o12.png"), "--spec", str(root / "none.json")])
    add("arguments", "--src 3 numbers", ["warp", good, str(root / "o13.png"), "--src", "1,2,3", *dst])
    add("arguments", "--src letters", ["warp", good, str(root / "o14.png"), "--src", "a,b,c,d,e,f,g,h", *dst])
    add("arguments", "--src subnormal",
        ["warp", good, str(root / "o15.png"), "--src", "0,0,1e-310,0,1e-310,1e-310,0,1e-310", *dst],
        names="src")
    add("arguments", "--output-shape 0x0", ["warp", good, str(root / "o16.png"), *src, *dst, "--output-shape", "0x0"])
    add("arguments", "--backend nope", ["warp", good, str(root / "o17.png"), *src, *dst, "--backend", "nope"])
    add("arguments", "--edges 0,0", ["warp", good, str(root / "o18.png"), *src, *dst, "--edges", "0,0"])

    def no_preview(stack):
        for mod in ("moderngl", "moderngl_window"):
            stack.enter_context(_module_missing(mod))

    add("missing extras", "preview without moderngl",
        ["preview", good, "--screenshot", str(root / "o19.png")], setup=no_preview)
    add("missing extras", "preview window without moderngl", ["preview", good], setup=no_preview)
    batch_in = root / "batch-in"
    batch_in.mkdir()
    fpiwarp.write_image(batch_in / "a.png", np.zeros((48, 64, 3), np.uint8))
    fpiwarp.write_image(batch_in / "b.png", np.zeros((30, 20, 3), np.uint8))
    (batch_in / "notes.txt").write_text("notes")
    add("batches", "stray notes.txt", ["batch", str(f["spec_good"]), str(batch_in), str(root / "bo1"),
                                       "--no-progress"], "answer", lambda res: res[0] == 0)
    add("batches", "--pattern '*.png'", ["batch", str(f["spec_good"]), str(batch_in), str(root / "bo2"),
                                         "--no-progress", "--pattern", "*.png"], "answer", lambda res: res[0] == 0)
    add("batches", "missing input folder", ["batch", str(f["spec_good"]), str(root / "none"), str(root / "bo3")])
    add("batches", "input folder is a file", ["batch", str(f["spec_good"]), good, str(root / "bo4")])
    return cases


@contextlib.contextmanager
def _module_missing(name):
    """``import name`` (and its submodules) raises ModuleNotFoundError inside."""
    saved = {k: v for k, v in sys.modules.items() if k == name or k.startswith(name + ".")}
    viewer = {k: v for k, v in sys.modules.items() if k.startswith(("fpiwarp.viewer", "fpiwarp.widget"))}
    for k in list(saved) + list(viewer):
        sys.modules.pop(k, None)
    sys.modules[name] = None
    try:
        yield
    finally:
        sys.modules.pop(name, None)
        for k in [k for k in sys.modules if k.startswith(("fpiwarp.viewer", "fpiwarp.widget"))]:
            sys.modules.pop(k, None)
        sys.modules.update(saved)
        sys.modules.update(viewer)


def _cli(argv):
    from fpiwarp.cli import main

    return main(list(argv))  # its stdout and stderr are captured by classify, in the main thread


# --------------------------------------------------------------------------
# Running and counting


@contextlib.contextmanager
def _fd_stderr():
    """Collect what C code writes to file descriptor 2."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        box = []
        try:
            yield box
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            box.append(tmp.read().decode("utf-8", "replace"))


def _call(case):
    """(result, exception, hung) of ``case.run()`` in a thread with a timeout."""
    box = {}

    def target():
        try:
            box["result"] = case.run()
        except BaseException as exc:  # noqa: BLE001 - counted
            box["exc"] = exc

    t = threading.Thread(target=target, daemon=True)
    t.start()
    t.join(TIMEOUT_S)
    return box.get("result"), box.get("exc"), t.is_alive()


def classify(case):
    """(outcome, detail) of one case."""
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, _fd_stderr() as fd_err:
        warnings.simplefilter("always")
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            result, exc, hung = _call(case)
    if case.cli and exc is None and not hung:
        result = (result, out.getvalue(), err.getvalue())
    c_text = fd_err[0].strip() if fd_err else ""
    noise = [str(w.message) for w in caught] + ([c_text] if c_text else [])
    if hung:
        return "hang", f"no answer in {TIMEOUT_S:.0f} s"
    if case.cli:
        if exc is not None:
            return "other exception", f"{type(exc).__name__}: {_short(exc)}"
        status, out, err = result
        if status == 70 or "Traceback" in err:
            return "traceback", err.strip().splitlines()[-1] if err.strip() else f"status {status}"
        lines = [ln for ln in err.splitlines() if ln.strip()]
        refused = status in (1, 2)
        if refused and len(lines) != 1 and case.expect != "answer":
            return "bad message", f"status {status}, {len(lines)} lines on stderr"
        if noise:
            return "warnings", _short(noise[0])
        if refused:
            if case.expect == "answer":
                return "refused", lines[0] if lines else f"status {status}"
            if len(lines[0]) > MAX_MESSAGE:
                return "bad message", f"{len(lines[0])} characters"
            if case.names and case.names not in lines[0]:
                return "bad message", f"does not name {case.names!r}: {_short(lines[0])}"
            return "clean", lines[0]
        if case.expect == "refuse":
            return "accepted", f"status {status}"
        if case.check is not None and not case.check(result):
            return "wrong answer", f"status {status}: {' '.join(err.split())[:120]}"
        return "correct", f"status {status}" + (f"; {lines[-1]}" if lines else "")
    if exc is None:
        if noise:
            return "warnings", _short(noise[0])
        if case.expect == "refuse":
            return "accepted", "returned without error"
        try:
            ok = case.check is None or case.check(result)
        except Exception as cexc:  # noqa: BLE001
            ok = False
            result = cexc
        return ("correct", "") if ok else ("wrong answer", _short(repr(result)))
    if not isinstance(exc, (FpiwarpError, *case.accept)):
        return "other exception", f"{type(exc).__name__}: {_short(exc)}"
    text = str(exc)
    if "\n" in text.strip() or len(text) > MAX_MESSAGE:
        return "bad message", f"{type(exc).__name__}, {len(text)} characters, {text.count(chr(10)) + 1} lines"
    if noise:
        return "warnings", _short(noise[0])
    if case.expect == "answer":
        return "refused", f"{type(exc).__name__}: {text}"
    if case.names and case.names not in text:
        return "bad message", f"does not name {case.names!r}: {type(exc).__name__}: {_short(text)}"
    return "clean", f"{type(exc).__name__}: {text}"


def _short(value, n=160):
    text = " ".join(str(value).split())
    return text if len(text) <= n else text[: n - 3] + "..."


GOOD = ("clean", "correct")


def run(verbose=False):
    """[(case, outcome, detail)] of every case."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="fpiwarp-reliability-") as tmp:
        api_root, cli_root = Path(tmp) / "api", Path(tmp) / "cli"
        api_root.mkdir()
        cli_root.mkdir()
        api_files, cli_files = _files(api_root), _files(cli_root)  # each side its own special files
        try:
            for case in _api_cases(api_files, api_root) + _cli_cases(cli_files, cli_root):
                outcome, detail = classify(case)
                detail = detail.replace(str(tmp), "<tmp>")  # the run's scratch folder, not a path to publish
                rows.append((case, outcome, detail))
                if verbose:
                    print(f"{'cli' if case.cli else 'api'} {case.family:18} {case.name:38} {outcome:15} {detail}")
        finally:
            for files in (api_files, cli_files):
                _unblock(files)
                files["_socket"].close()
    return rows


def _unblock(files):
    """Open the FIFOs' other end, so that a reader that hung gets EOF."""
    for name in ("fifo", "fifo_in"):
        try:
            os.close(os.open(files[name], os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass


def report(rows):
    """The Markdown report: totals, per family, then every case not good."""
    outcomes = sorted({o for _, o, _ in rows}, key=lambda o: (o not in GOOD, o))
    lines = ["# Reliability run", "", f"CPU: {cpu_model()}; fpiwarp {fpiwarp.__version__}; "
             f"numpy {np.__version__}; Python {sys.version.split()[0]}", ""]
    for kind in ("api", "cli"):
        sub = [r for r in rows if r[0].cli == (kind == "cli")]
        good = sum(o in GOOD for _, o, _ in sub)
        lines.append(f"- {kind.upper()}: {len(sub)} cases, {good} clean refusals or correct answers, "
                     f"{len(sub) - good} not")
    lines += ["", "| family | cases | " + " | ".join(outcomes) + " |", "|---|---|" + "---|" * len(outcomes)]
    families = []
    for case, _, _ in rows:
        key = ("cli " if case.cli else "api ") + case.family
        if key not in families:
            families.append(key)
    for fam in families:
        sub = [o for c, o, _ in rows if ("cli " if c.cli else "api ") + c.family == fam]
        lines.append(f"| {fam} | {len(sub)} | " + " | ".join(str(sub.count(o) or "") for o in outcomes) + " |")
    bad = [(c, o, d) for c, o, d in rows if o not in GOOD]
    if bad:
        lines += ["", "## Cases not answered well", "", "| kind | family | case | outcome | detail |",
                  "|---|---|---|---|---|"]
        for c, o, d in bad:
            lines.append(f"| {'cli' if c.cli else 'api'} | {c.family} | {c.name} | {o} | {d.replace('|', '/')} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python3 -m benchmarks.reliability", description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--verbose", action="store_true", help="one line per case as it runs")
    args = parser.parse_args(argv)
    rows = run(verbose=args.verbose)
    text = report(rows)
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "reliability.md").write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
