"""The ``fpiwarp`` command: the demo, one-image and folder warps, and one
clear line (never a traceback) for a user's mistake."""

import hashlib
import json
import re
import shutil
import subprocess
import sys
from importlib import resources

import numpy as np
import pytest

import fpiwarp
from fpiwarp.cli.commands import DEMO_DST, main
from fpiwarp.io import images as io

H, W = 24, 32
SRC = "0,0,31,0,31,23,0,23"
DST = "2,1,29,-2,33,24,-1,21"


def _quad(text):
    return np.array([float(v) for v in text.split(",")]).reshape(4, 2)


@pytest.fixture
def image_file(tmp_path, rng):
    path = tmp_path / "in.png"
    io.write_image(path, rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8))
    return path


def _run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def _one_clean_line(err):
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_demo_writes_the_warped_sample_and_reports_k(tmp_path, capsys):
    out_path = tmp_path / "demo.png"
    code, out, err = _run(capsys, "demo", out_path)
    assert code == 0 and err == ""
    assert str(out_path) in out
    k = float(re.search(r"K = ([0-9.]+)", out).group(1))
    sample = io.read_image(resources.files("fpiwarp.data") / "sample.png")
    h, w = sample.shape[:2]
    fpi = fpiwarp.FPI(
        [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], [[a * (w - 1), b * (h - 1)] for a, b in DEMO_DST]
    )
    assert k == pytest.approx(fpi.K, abs=1e-4) and k > 1.05  # a visible warp, not a rigid motion
    warped = io.read_image(out_path)
    np.testing.assert_array_equal(warped, fpiwarp.warp_image(sample, fpi, order=3))
    assert (warped[0, 0] == 0).all() and warped[h // 2, w // 2].any()  # the corner is outside


def test_demo_never_overwrites_without_asking(tmp_path, capsys):
    out_path = tmp_path / "demo.png"
    out_path.write_bytes(b"my own file")
    code, out, err = _run(capsys, "demo", out_path)
    assert code != 0 and out == ""
    assert "already exists" in _one_clean_line(err) and "--overwrite" in err
    assert out_path.read_bytes() == b"my own file"
    code, out, _ = _run(capsys, "demo", out_path, "--overwrite")
    assert code == 0 and io.read_image(out_path).shape == (480, 640, 3)


def test_python_dash_m_demo_uses_the_default_name(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "fpiwarp", "demo"], cwd=tmp_path, capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    assert "warped-sample.png" in result.stdout and (tmp_path / "warped-sample.png").is_file()
    again = subprocess.run(
        [sys.executable, "-m", "fpiwarp", "demo"], cwd=tmp_path, capture_output=True, text=True, check=False
    )
    assert again.returncode == 1 and "Traceback" not in again.stderr


def test_console_script_is_installed():
    exe = shutil.which("fpiwarp")
    if exe is None:
        pytest.skip("the fpiwarp console script is not on PATH (package not installed)")
    result = subprocess.run([exe, "backends"], capture_output=True, text=True, check=False)
    assert result.returncode == 0 and "numpy" in result.stdout


def test_warp_with_corner_options_matches_the_library(image_file, tmp_path, capsys):
    out_path = tmp_path / "out.png"
    code, _, err = _run(capsys, "warp", image_file, out_path, "--src", SRC, "--dst", DST, "--order", "3")
    assert code == 0, err
    expected = fpiwarp.warp_image(io.read_image(image_file), fpiwarp.FPI(_quad(SRC), _quad(DST)), order=3,
                                  antialias=True)  # the command line's default at orders 1 and 3
    np.testing.assert_array_equal(io.read_image(out_path), expected)


def test_warp_options_reach_warp_image(image_file, tmp_path, capsys):
    out_path = tmp_path / "out.png"
    code, _, err = _run(
        capsys,
        "warp",
        image_file,
        out_path,
        "--src",
        SRC,
        "--dst",
        DST,
        "--mode",
        "constant",
        "--cval",
        "10,20,30",
        "--output-shape",
        "40x30",
        "--order",
        "0",
    )
    assert code == 0, err
    fpi = fpiwarp.FPI(_quad(SRC), _quad(DST))
    expected = fpiwarp.warp_image(io.read_image(image_file), fpi, (30, 40), order=0, cval=(10, 20, 30))
    got = io.read_image(out_path)
    assert got.shape == (30, 40, 3)
    np.testing.assert_array_equal(got, expected)


def test_warp_with_a_spec_file(image_file, tmp_path, capsys):
    spec = tmp_path / "w.json"
    spec.write_text(json.dumps({"steps": [{"src": _quad(SRC).tolist(), "dst": _quad(DST).tolist()}]}))
    out_path = tmp_path / "out.png"
    code, _, err = _run(capsys, "warp", image_file, out_path, "--spec", spec)
    assert code == 0, err
    expected = fpiwarp.warp_image(io.read_image(image_file), fpiwarp.FPI(_quad(SRC), _quad(DST)), antialias=True)
    np.testing.assert_array_equal(io.read_image(out_path), expected)


def test_warp_with_constrained_edges(image_file, tmp_path, capsys):
    local = pytest.importorskip("fpiwarp.maps.local")
    dst = "0,0,31,0,33,25,0,23"
    out_path = tmp_path / "out.png"
    code, _, err = _run(capsys, "warp", image_file, out_path, "--src", SRC, "--dst", dst, "--edges", "3,1")
    assert code == 0, err
    image = io.read_image(image_file)
    h, w = image.shape[:2]  # the CLI makes the operator continuous over the picture
    t = local.LocalDeformation(_quad(SRC), _quad(dst), edges=(3, 1), extent=(w, h))
    np.testing.assert_array_equal(io.read_image(out_path), fpiwarp.warp_image(image, t, antialias=True))


def _mistakes(image_file, tmp_path):
    spec = tmp_path / "bad.json"
    spec.write_text(json.dumps({"src": _quad(SRC).tolist(), "dts": []}))
    good_spec = tmp_path / "good.json"
    good_spec.write_text(json.dumps({"src": _quad(SRC).tolist(), "dst": _quad(DST).tolist()}))
    existing = tmp_path / "exists.png"
    existing.write_bytes(b"keep me")
    ok = ["--src", SRC, "--dst", DST]
    rgba = tmp_path / "rgba.png"
    io.write_image(rgba, np.full((H, W, 4), 200, np.uint8))
    return [
        (["warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", "0,0,1,1,1,0,0,1"], "self-intersecting"),
        (["warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", "0,0,1,0,2,0,0,1"], "collinear"),
        (["warp", image_file, tmp_path / "o.png", "--spec", spec], "unknown field 'dts'"),
        (["warp", image_file, tmp_path / "o.png", "--spec", tmp_path / "none.json"], "none.json"),
        (["warp", tmp_path / "missing.png", tmp_path / "o.png", *ok], "no such file"),
        (["warp", image_file, tmp_path / "o.png", *ok, "--backend", "vulkan"], "unknown backend 'vulkan'"),
        (["warp", image_file, existing, *ok], "already exists"),
        (["warp", image_file, image_file, *ok, "--overwrite"], "is the input file"),
        (["warp", rgba, tmp_path / "o.jpg", *ok], "JPEG cannot store 8-bit RGBA") if io.have_pillow() else None,
        (["warp", image_file, tmp_path / "o.png", "--src", "1,2,3", "--dst", DST], "8 numbers"),
        (["warp", image_file, tmp_path / "o.png", *ok, "--output-shape", "big"], "WIDTHxHEIGHT"),
        (["warp", image_file, tmp_path / "o.png", "--src", SRC], "--dst"),
        (["warp", image_file, tmp_path / "o.png", *ok, "--order", "2"], "invalid choice"),
        (["warp", image_file, tmp_path / "no-such-dir" / "o.png", *ok], "output folder does not exist"),
        (["batch", spec, tmp_path, tmp_path / "out"], "unknown field 'dts'"),
        (["batch", good_spec, tmp_path, tmp_path / "out", "--pattern", "/etc/*"], "relative to the input folder"),
        (["batch", good_spec, tmp_path / "nope", tmp_path / "out"], "input folder does not exist"),
        (["frobnicate"], "invalid choice"),
    ]


def test_user_mistakes_give_one_line_and_touch_nothing(image_file, tmp_path, capsys):
    for case in _mistakes(image_file, tmp_path):
        if case is None:
            continue
        args, phrase = case
        before = {p: _sha(p) for p in tmp_path.rglob("*") if p.is_file()}
        code, _, err = _run(capsys, *args)
        assert err.count("\n") == 1, (args, err)
        line = _one_clean_line(err)
        assert code != 0 and phrase in line, (args, line)
        assert {p: _sha(p) for p in tmp_path.rglob("*") if p.is_file()} == before, args


def test_ctrl_c_while_writing_leaves_no_file(image_file, tmp_path, capsys, monkeypatch):
    def interrupted(fd):
        raise KeyboardInterrupt

    monkeypatch.setattr(io.os, "fsync", interrupted)  # after the data went to the temporary file
    code, _, err = _run(capsys, "warp", image_file, tmp_path / "out.png", "--src", SRC, "--dst", DST)
    assert code == 130 and _one_clean_line(err) == "fpiwarp: interrupted"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]


def test_batch_command_summarizes_failures_and_resumes(tmp_path, rng, capsys):
    src = tmp_path / "in"
    src.mkdir()
    for i in range(3):
        io.write_image(src / f"{i}.png", rng.integers(0, 256, size=(H, W), dtype=np.uint8))
    (src / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\nnope")
    spec = tmp_path / "w.json"
    spec.write_text(json.dumps({"src": _quad(SRC).tolist(), "dst": _quad(DST).tolist()}))
    code, out, err = _run(capsys, "batch", spec, src, tmp_path / "out", "--jobs", "2")
    assert code == 1
    assert "3 warped, 0 skipped (output exists), 1 failed, of 4 files" in out
    assert re.search(r"failed: .*broken\.png: ", err) and "Traceback" not in err
    (src / "broken.png").unlink()
    code, out, err = _run(capsys, "batch", spec, src, tmp_path / "out")
    assert code == 0 and "0 warped, 3 skipped" in out and "--overwrite" in err
    code, out, _ = _run(capsys, "batch", spec, src, tmp_path / "out", "--overwrite", "--pattern", "1.*")
    assert code == 0 and "1 warped, 0 skipped" in out


def test_batch_command_on_a_dask_cluster(tmp_path, rng, capsys):
    distributed = pytest.importorskip("distributed")
    src = tmp_path / "in"
    src.mkdir()
    for i in range(2):
        io.write_image(src / f"{i}.png", rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8))
    spec = tmp_path / "w.json"
    spec.write_text(json.dumps({"src": _quad(SRC).tolist(), "dst": _quad(DST).tolist()}))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as c:
        code, out, err = _run(capsys, "batch", spec, src, tmp_path / "out", "--scheduler", c.scheduler_address)
    assert code == 0 and "2 warped" in out, err
    fpi = fpiwarp.FPI(_quad(SRC), _quad(DST))
    for i in range(2):
        expected = fpiwarp.warp_image(io.read_image(src / f"{i}.png"), fpi, antialias=True)
        np.testing.assert_array_equal(io.read_image(tmp_path / "out" / f"{i}.png"), expected)


def test_backends_lists_every_backend(capsys):
    code, out, _ = _run(capsys, "backends")
    assert code == 0
    for name in ("numpy", "opencl", "warp", "gl"):
        assert re.search(rf"^{name}\s+(available|unavailable: .+)$", out, re.MULTILINE), out


# --------------------------------------------------------------------------
# Issue 12: limits, K, the output-shape convention


@pytest.mark.parametrize("shape", ["100000x100000", "3000000000x1", "70000x70000"])
@pytest.mark.parametrize("backend", ["numpy", "opencl", "warp", "gl"])
def test_huge_output_shapes_are_one_line_naming_the_limit(image_file, tmp_path, capsys, shape, backend):
    code, _, err = _run(capsys, "warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", DST,
                        "--output-shape", shape, "--backend", backend)
    line = _one_clean_line(err)
    width, height = shape.split("x")
    assert code == 1 and f"{height}x{width}" in line and "limit" in line
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("shape", ["10^12x10^12", "1e12x1e12", "-5x5", "0x10", "12x"])
def test_malformed_output_shapes_are_one_usage_line(image_file, tmp_path, capsys, shape):
    code, _, err = _run(capsys, "warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", DST,
                        "--output-shape", shape)
    assert code == 2 and "WIDTHxHEIGHT" in _one_clean_line(err)


def test_batch_refuses_a_huge_output_shape_before_reading_files(tmp_path, rng, capsys):
    src = tmp_path / "in"
    src.mkdir()
    io.write_image(src / "a.png", rng.integers(0, 256, size=(H, W), dtype=np.uint8))
    spec = tmp_path / "w.json"
    spec.write_text(json.dumps({"src": _quad(SRC).tolist(), "dst": _quad(DST).tolist()}))
    code, _, err = _run(capsys, "batch", spec, src, tmp_path / "out", "--output-shape", "100000x100000")
    assert code == 1 and "limit" in _one_clean_line(err)
    assert not (tmp_path / "out").exists()


def test_output_shape_is_width_by_height_and_help_says_the_api_differs(image_file, tmp_path, capsys):
    code, _, _ = _run(capsys, "warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", DST,
                      "--output-shape", "40x10")
    assert code == 0 and io.read_image(tmp_path / "o.png").shape[:2] == (10, 40)
    with pytest.raises(SystemExit):
        main(["warp", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "WIDTHxHEIGHT" in help_text and "(rows, cols), i.e. (HEIGHT, WIDTH)" in help_text


def test_warp_reports_k_like_demo(image_file, tmp_path, capsys):
    code, out, _ = _run(capsys, "warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", DST)
    k = float(re.search(r"^K = ([0-9.]+)$", out, re.M).group(1))
    assert code == 0 and k == pytest.approx(fpiwarp.FPI(_quad(SRC), _quad(DST)).K, abs=1e-4)


def test_warp_with_edges_reports_the_largest_k_over_the_image(image_file, tmp_path, capsys):
    dst = "0,0,31,0,34,25,-2,23"
    code, out, _ = _run(capsys, "warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", dst, "--edges", "0,2")
    k = float(re.search(r"^K = ([0-9.]+) \(largest over the input image\)$", out, re.M).group(1))
    assert code == 0 and k >= 1.0


def test_extreme_cval_on_the_command_line(image_file, tmp_path, capsys):
    code, _, _ = _run(capsys, "warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", DST,
                      "--cval", "3.5e38", "--order", "3")
    assert code == 0  # clamped to 255 for this uint8 image
    code, _, err = _run(capsys, "warp", image_file, tmp_path / "o.png", "--src", SRC, "--dst", DST,
                        "--cval", "inf", "--overwrite")
    assert code == 2 and "finite" in _one_clean_line(err)


def _portrait_jpeg(path):
    """A photo stored 45 wide and 30 high with EXIF Orientation 6 (shown
    30 wide and 45 high)."""
    from PIL import Image

    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(np.full((30, 45, 3), 128, np.uint8)).save(path, quality=95, exif=exif.tobytes())


def _size_and_tag(path):
    from PIL import Image

    with Image.open(path) as im:
        return im.size, im.getexif().get(0x0112, 1)


@pytest.mark.parametrize("choice, size, tag", [("apply", (30, 45), 1), ("stored", (45, 30), 6)])
def test_warp_and_batch_apply_the_exif_orientation_or_keep_it(tmp_path, capsys, choice, size, tag):
    """Corners are picked on the picture as viewers show it: 'apply' (the
    default) warps that picture and writes it upright with no tag;
    'stored' warps the stored pixels and keeps their tag."""
    (tmp_path / "in").mkdir()
    _portrait_jpeg(tmp_path / "in" / "p.jpg")
    args = ["--orientation", choice] if choice != "apply" else []
    quad = "0,0,20,0,20,20,0,20"
    assert _run(capsys, "warp", str(tmp_path / "in" / "p.jpg"), str(tmp_path / "out.jpg"),
                "--src", quad, "--dst", quad, *args)[0] == 0
    assert _size_and_tag(tmp_path / "out.jpg") == (size, tag)
    spec = tmp_path / "id.json"
    square = [[0, 0], [20, 0], [20, 20], [0, 20]]
    spec.write_text(json.dumps({"src": square, "dst": square}))
    assert _run(capsys, "batch", str(spec), str(tmp_path / "in"), str(tmp_path / "out"), "--no-progress", *args)[0] == 0
    assert _size_and_tag(tmp_path / "out" / "p.jpg") == (size, tag)
