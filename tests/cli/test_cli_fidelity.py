"""Issue 25 items 4, 5, 7, 10 on the command line: run in-process through fpiwarp.cli.main (this tree)."""

import io
import os
import socket
import struct
import sys

import numpy as np
import pytest
from PIL import Image

import fpiwarp
from fpiwarp.cli import main

SRC = "0,0,63,0,63,47,0,47"
DST = "4,2,60,1,62,45,1,44"
IMG = (np.arange(48 * 64 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)


@pytest.fixture
def picture(tmp_path):
    path = tmp_path / "in.png"
    fpiwarp.write_image(path, IMG)
    return path


def _run(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def _one_line_error(status, err, *words):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert status == 1 and len(lines) == 1 and lines[0].startswith("fpiwarp: error:"), err
    assert "Traceback" not in err and "internal error" not in err
    for w in words:
        assert w in lines[0], lines[0]


# --- item 4: preview without its extra ----------------------------------------------------------------------------


@pytest.fixture
def without(monkeypatch):
    """Make ``import name`` fail (and fpiwarp.viewer/widget be imported afresh)."""

    def hide(*names):
        for key in list(sys.modules):
            if key.startswith(("fpiwarp.viewer", "fpiwarp.widget")) or key.split(".")[0] in names:
                monkeypatch.delitem(sys.modules, key)
        for name in names:
            monkeypatch.setitem(sys.modules, name, None)

    return hide


@pytest.mark.parametrize("missing", [("moderngl",), ("moderngl_window",), ("moderngl", "moderngl_window")])
@pytest.mark.parametrize("extra_args", [["--screenshot", "shot.png"], [], ["--src", SRC, "--dst", DST]])
def test_preview_without_the_preview_extra(capsys, picture, tmp_path, without, missing, extra_args):
    without(*missing)
    args = [a if a != "shot.png" else tmp_path / a for a in extra_args]
    status, _, err = _run(capsys, "preview", picture, *args)
    if missing == ("moderngl_window",) and not extra_args or missing == ("moderngl_window",) and "--src" in args:
        # moderngl is there: the window needs moderngl-window, said by the viewer (a display may be missing first)
        assert status == 1 and len(err.strip().splitlines()) == 1 and "internal error" not in err
        return
    if missing == ("moderngl_window",):
        assert status in (0, 1) and "internal error" not in err  # offscreen needs moderngl only
        return
    _one_line_error(status, err, "pip install 'fpiwarp[preview]'", "moderngl")


def test_preview_web_without_moderngl(capsys, picture, without):
    """The page's editor shares the viewer's package, which imports moderngl: the widget extra has it."""
    without("moderngl")
    status, _, err = _run(capsys, "preview", picture, "--web", "--no-browser")
    _one_line_error(status, err, "pip install 'fpiwarp[widget]'", "moderngl")


def test_an_unrelated_import_error_stays_a_bug(capsys, picture, monkeypatch):
    from fpiwarp.cli import commands

    def broken(module, extra, what):
        raise ImportError("cannot import name 'x' from 'fpiwarp.viewer'", name="fpiwarp.viewer")

    monkeypatch.setattr(commands, "_import_for_preview", broken)
    status, _, err = _run(capsys, "preview", picture, "--screenshot", picture.with_name("s.png"))
    assert status == commands.BUG_STATUS


# --- item 5: special files as outputs -----------------------------------------------------------------------------


def _specials(tmp_path):
    os.mkfifo(tmp_path / "fifo.png")
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(tmp_path / "sock.png"))
    (tmp_path / "null.png").symlink_to("/dev/null")
    (tmp_path / "to-fifo.png").symlink_to(tmp_path / "fifo.png")
    return sock, ["fifo.png", "sock.png", "null.png", "to-fifo.png"]


def test_warp_overwrite_refuses_special_files(capsys, picture, tmp_path):
    sock, names = _specials(tmp_path)
    try:
        for name in names:
            before = os.lstat(tmp_path / name)
            for overwrite in ([], ["--overwrite"]):
                status, _, err = _run(capsys, "warp", picture, tmp_path / name, "--src", SRC, "--dst", DST, *overwrite)
                _one_line_error(status, err, str(tmp_path / name), "not a regular file")
            assert os.lstat(tmp_path / name).st_ino == before.st_ino
    finally:
        sock.close()
    assert os.path.exists("/dev/null") and not os.path.isfile("/dev/null")


def test_demo_and_preview_screenshot_refuse_dev_null(capsys, picture):
    status, _, err = _run(capsys, "demo", "/dev/null", "--overwrite")
    _one_line_error(status, err, "/dev/null", "character device")
    status, _, err = _run(capsys, "preview", picture, "--screenshot", "/dev/null", "--overwrite")
    _one_line_error(status, err, "/dev/null")


def test_batch_fails_the_file_whose_output_is_a_fifo(capsys, tmp_path):
    spec = tmp_path / "spec.json"
    from fpiwarp.spec import save_spec

    save_spec(fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 2], [60, 1], [62, 45], [1, 44]]), spec)
    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    for n in ("a.png", "b.png"):
        fpiwarp.write_image(tmp_path / "in" / n, IMG)
    os.mkfifo(tmp_path / "out" / "a.png")
    status, out, err = _run(capsys, "batch", spec, tmp_path / "in", tmp_path / "out", "--overwrite", "--no-progress")
    assert status == 1 and "1 warped" in out and "a.png" in err and "not a regular file" in err
    assert os.path.exists(tmp_path / "out" / "a.png") and not (tmp_path / "out" / "a.png").is_file()


# --- item 7: damaged inputs ---------------------------------------------------------------------------------------


def _claims_9000(path):
    b = io.BytesIO()
    Image.new("L", (16, 16), 128).save(b, format="JPEG")
    raw = bytearray(b.getvalue())
    sof = raw.find(b"\xff\xc0")
    raw[sof + 5 : sof + 9] = struct.pack(">HH", 9000, 9000)
    path.write_bytes(bytes(raw[:-2]) + b"\0" * 600 + b"\xff\xd9")


def test_warp_refuses_a_damaged_jpeg_and_accepts_it_on_request(capfd, tmp_path):
    bad = tmp_path / "claims.jpg"
    _claims_9000(bad)
    status = main(["warp", str(bad), str(tmp_path / "o.png"), "--src", SRC, "--dst", DST])
    err = capfd.readouterr().err
    _one_line_error(status, err, str(bad), "damaged JPEG", "--accept-damaged")
    small = tmp_path / "small.jpg"
    data = io.BytesIO()
    Image.fromarray(IMG).save(data, format="JPEG")
    small.write_bytes(data.getvalue()[: len(data.getvalue()) // 2])
    status = main(["warp", str(small), str(tmp_path / "o.png"), "--src", SRC, "--dst", DST])
    _one_line_error(status, capfd.readouterr().err, str(small), "truncated")
    status = main(["warp", str(small), str(tmp_path / "o.png"), "--src", SRC, "--dst", DST, "--accept-damaged"])
    out, err = capfd.readouterr()
    assert status == 0 and err == "" and (tmp_path / "o.png").is_file()


# --- item 10: batch inputs ----------------------------------------------------------------------------------------


@pytest.fixture
def folder(tmp_path):
    from fpiwarp.spec import save_spec

    spec = tmp_path / "spec.json"
    save_spec(fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 2], [60, 1], [62, 45], [1, 44]]), spec)
    src = tmp_path / "in"
    src.mkdir()
    fpiwarp.write_image(src / "a.png", IMG)
    fpiwarp.write_image(src / "b.jpg", IMG)
    fpiwarp.write_image(src / "c.png", np.zeros((30, 20, 3), np.uint8))
    (src / "notes.txt").write_text("notes")
    (src / "README").write_text("no extension")
    return spec, src, tmp_path / "out"


def test_batch_skips_stray_files_with_a_note(capsys, folder):
    spec, src, out_dir = folder
    status, out, err = _run(capsys, "batch", spec, src, out_dir, "--no-progress")
    assert status == 0, err
    assert "3 warped" in out and "of 3 files" in out
    assert "ignored" in err and "notes.txt" in err and "README" in err
    assert sorted(p.name for p in out_dir.iterdir()) == ["a.png", "b.jpg", "c.png"]


def test_batch_says_which_images_differ_in_size(capsys, folder):
    spec, src, out_dir = folder
    status, out, err = _run(capsys, "batch", spec, src, out_dir, "--no-progress")
    line = next(ln for ln in err.splitlines() if "size differs" in ln)
    assert "c.png is 20x30" in line and "a.png 64x48" in line
    assert not any("size differs" in ln and ("a.png is" in ln or "b.jpg is" in ln) for ln in err.splitlines())


def test_batch_ext_and_pattern_choose_the_inputs(capsys, folder):
    spec, src, out_dir = folder
    status, out, err = _run(capsys, "batch", spec, src, out_dir / "1", "--no-progress", "--ext", "jpg")
    assert status == 0 and "1 warped" in out and "ignored" not in err
    status, out, err = _run(capsys, "batch", spec, src, out_dir / "2", "--no-progress", "--ext", ".PNG,jpg")
    assert status == 0 and "3 warped" in out
    status, out, err = _run(capsys, "batch", spec, src, out_dir / "3", "--no-progress", "--pattern", "a.*")
    assert status == 0 and "1 warped" in out
    # named explicitly, a text file is taken, and fails
    status, out, err = _run(capsys, "batch", spec, src, out_dir / "4", "--no-progress", "--pattern", "*.txt")
    assert status == 1 and "failed: " in err and "notes.txt" in err
    status, out, err = _run(capsys, "batch", spec, src, out_dir / "5", "--no-progress", "--ext", "gif")
    assert status == 0 and "no files" in err


def test_run_batch_records_ignored_and_sizes(folder):
    from fpiwarp.batch.folders import run_batch

    spec, src, out_dir = folder
    summary = run_batch(fpiwarp.load_spec(spec), src, out_dir)
    assert [os.path.basename(p) for p in summary.ignored] == ["README", "notes.txt"]
    assert summary.sizes[str(src / "c.png")] == (20, 30) and len(summary.size_notes()) == 1
    with pytest.raises(fpiwarp.ArgumentError):
        run_batch(fpiwarp.load_spec(spec), src, out_dir, extensions=",")
