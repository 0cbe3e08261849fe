"""Batch warping: the generator and stacks give what warp_image gives, and a
folder batch loses nothing (inputs untouched, atomic outputs, resume,
failures named)."""

import hashlib
import io as pyio
import os
import pickle
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fpiwarp
from fpiwarp.batch import folders as batch_folders
from fpiwarp.batch.images import BatchSummary, Progress, Warper, list_inputs, run_batch, warp_batch, warp_images
from fpiwarp.io import images as io

H, W = 24, 32


@pytest.fixture
def fpi():
    return fpiwarp.FPI([[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]], [[2, 1], [W - 3, -2], [W + 1, H], [-1, H - 3]])


@pytest.fixture
def stack(rng):
    return rng.integers(0, 256, size=(4, H, W, 3), dtype=np.uint8)


@pytest.mark.parametrize("order, mode", [(0, "edge"), (1, "constant"), (3, "reflect"), (1, "wrap")])
def test_warp_images_matches_warp_image(fpi, stack, order, mode):
    expected = [fpiwarp.warp_image(im, fpi, order=order, mode=mode, cval=9) for im in stack]
    got = list(warp_images(iter(stack), fpi, order=order, mode=mode, cval=9))
    assert len(got) == len(expected)
    for a, b in zip(got, expected):
        np.testing.assert_array_equal(a, b)


def test_warp_images_reads_paths_lazily_and_keeps_layouts(fpi, rng, tmp_path):
    gray16 = rng.integers(0, 65536, size=(H, W), dtype=np.uint16)
    rgba = rng.integers(0, 256, size=(H + 3, W - 5, 4), dtype=np.uint8)
    io.write_image(tmp_path / "g.png", gray16)
    io.write_image(tmp_path / "c.png", rgba)

    def items():
        yield tmp_path / "g.png"
        yield str(tmp_path / "c.png")
        raise AssertionError("read past what was asked for")

    gen = warp_images(items(), fpi, output_shape=(20, 30))
    first, second = next(gen), next(gen)
    np.testing.assert_array_equal(first, fpiwarp.warp_image(gray16, fpi, (20, 30)))
    np.testing.assert_array_equal(second, fpiwarp.warp_image(rgba, fpi, (20, 30)))


def test_warp_images_checks_options_before_reading(fpi):
    with pytest.raises(ValueError, match="order"):
        warp_images([], fpi, order=2)
    with pytest.raises(ValueError, match="unknown backend"):
        warp_images([], fpi, backend="vulkan")


def test_one_map_for_a_stack_matches_per_image_warps(fpi, stack):
    expected = np.stack([fpiwarp.warp_image(im, fpi, (H + 2, W - 4), order=3, cval=(1, 2, 3)) for im in stack])
    got = warp_batch(stack, fpi, (H + 2, W - 4), order=3, cval=(1, 2, 3))
    assert got.shape == (4, H + 2, W - 4, 3) and got.dtype == np.uint8
    np.testing.assert_array_equal(got, expected)


def test_one_map_per_image(fpi, stack):
    maps = [
        fpi,
        fpi.inverse,
        fpi @ fpi,
        fpiwarp.FPI([[0, 0], [9, 0], [9, 9], [0, 9]], [[1, 0], [9, 1], [9, 9], [0, 8]]),
    ]
    got = warp_batch(stack, maps, mode="edge")
    for image, t, out in zip(stack, maps, got):
        np.testing.assert_array_equal(out, fpiwarp.warp_image(image, t, mode="edge"))
    with pytest.raises(ValueError, match="3 maps for 4 images"):
        warp_batch(stack, maps[:3])


def test_gray_stacks_of_float32(fpi, rng):
    stack = rng.standard_normal((3, H, W)).astype(np.float32)
    got = warp_batch(stack, fpi)
    assert got.shape == (3, H, W) and got.dtype == np.float32
    np.testing.assert_array_equal(got[1], fpiwarp.warp_image(stack[1], fpi))


def test_a_stack_on_each_backend_matches_that_backends_warp_image(fpi, stack, any_backend):
    got = warp_batch(stack[:2], fpi, backend=any_backend)
    for image, out in zip(stack[:2], got):
        np.testing.assert_array_equal(out, fpiwarp.warp_image(image, fpi, backend=any_backend))


def test_warper_reuses_the_map_per_output_size(fpi, stack):
    warper = Warper(fpi, backend="numpy")  # the numpy backend's bound map keeps source positions
    warper(stack[0])
    first = warper.bound.positions((H, W))
    warper(stack[1])
    assert warper.bound.positions((H, W)) is first
    np.testing.assert_allclose(first[3, 5], fpi.inverse([[5.0, 3.0]])[0], rtol=0, atol=1e-12)


# --------------------------------------------------------------------------
# Folders


def _digest(folder):
    return {p.relative_to(folder): hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.rglob("*") if p.is_file()}


def _temporaries(*folders):
    return [p for f in folders for p in f.rglob("*") if io.is_temp_file(p)]


@pytest.fixture
def photos(tmp_path, rng):
    """A folder of mixed images plus a corrupt PNG and a text file."""
    folder = tmp_path / "in"
    folder.mkdir()
    io.write_image(folder / "a_rgb.png", rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8))
    io.write_image(folder / "b_gray16.png", rng.integers(0, 65536, size=(H, W), dtype=np.uint16))
    io.write_image(folder / "c_rgba.png", rng.integers(0, 256, size=(H + 4, W, 4), dtype=np.uint8))
    if io.have_pillow():
        io.write_image(folder / "d_photo.jpg", rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8))
        io.write_image(folder / "e_float.tif", rng.standard_normal((H, W)).astype(np.float32))
    good = (folder / "a_rgb.png").read_bytes()
    (folder / "x_corrupt.png").write_bytes(good[: len(good) // 2])
    (folder / "y_notes.txt").write_text("shopping list")
    (folder / ".hidden.png").write_bytes(good)
    return folder


def _good(folder):
    return sorted(p.name for p in folder.iterdir() if p.name[0] in "abcde")


def test_folder_batch_warps_every_image_and_names_failures(photos, tmp_path, fpi):
    before = _digest(photos)
    out = tmp_path / "out"
    summary = run_batch(fpi, photos, out, jobs=2)
    assert sorted(p.rsplit("/", 1)[-1] for p in summary.done) == _good(photos)
    assert sorted(p.rsplit("/", 1)[-1] for p, _ in summary.failed) == ["x_corrupt.png"]
    assert [p.rsplit("/", 1)[-1] for p in summary.ignored] == ["y_notes.txt"]  # not an image: a note, not a failure
    assert not summary.ok and summary.total == len(_good(photos)) + 1
    assert sorted(p.name for p in out.iterdir()) == _good(photos)
    for name in _good(photos):
        image, info = io.read_image(photos / name, with_info=True)
        warped, info_out = io.read_image(out / name, with_info=True)
        assert warped.dtype == image.dtype and warped.shape == image.shape and info_out.format == info.format
        if info.format != "JPEG":  # lossless formats: exactly warp_image's pixels
            np.testing.assert_array_equal(warped, fpiwarp.warp_image(image, fpi))
    assert _digest(photos) == before
    assert _temporaries(photos, out) == []
    report = "\n".join(summary.report())
    assert "x_corrupt.png" in report and "y_notes.txt" in report


def test_rerun_resumes_and_overwrite_redoes(photos, tmp_path, fpi):
    out = tmp_path / "out"
    first = run_batch(fpi, photos, out, pattern="*.png")
    stamp = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    second = run_batch(fpi, photos, out, pattern="*.png")
    assert second.done == [] and sorted(second.skipped) == sorted(first.done)
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == stamp
    (out / "a_rgb.png").write_bytes(b"stale")
    third = run_batch(fpi, photos, out, pattern="*.png", overwrite=True)
    assert sorted(third.done) == sorted(first.done)
    assert io.read_image(out / "a_rgb.png").shape == (H, W, 3)


def test_parallel_and_serial_runs_agree(photos, tmp_path, fpi):
    run_batch(fpi, photos, tmp_path / "one", jobs=1, pattern="*.png")
    run_batch(fpi, photos, tmp_path / "three", jobs=3, pattern="*.png")
    assert _digest(tmp_path / "one") == _digest(tmp_path / "three")


def test_a_device_backend_batch_matches_its_warp_image(photos, tmp_path, fpi, gl_backend):
    out = tmp_path / "out"
    summary = run_batch(fpi, photos, out, pattern="*.png", backend=gl_backend, jobs=2)
    assert len(summary.done) == 3 and [p for p, _ in summary.failed] == [str(photos / "x_corrupt.png")]
    for name in ("a_rgb.png", "c_rgba.png"):
        expected = fpiwarp.warp_image(io.read_image(photos / name), fpi, backend=gl_backend)
        np.testing.assert_array_equal(io.read_image(out / name), expected)


def test_output_folder_must_not_be_the_input(photos, fpi):
    before = _digest(photos)
    with pytest.raises(ValueError, match="output folder is the input folder"):
        run_batch(fpi, photos, photos, overwrite=True)
    assert _digest(photos) == before


def test_recursive_pattern_keeps_subfolders_and_skips_the_output_inside(photos, fpi):
    sub = photos / "sub"
    sub.mkdir()
    (sub / "deep.png").write_bytes((photos / "a_rgb.png").read_bytes())
    out = photos / "warped"
    summary = run_batch(fpi, photos, out, pattern="**/*.png")
    assert (out / "sub" / "deep.png").is_file()
    assert all("warped" not in p for p in summary.done + [f for f, _ in summary.failed])
    again = run_batch(fpi, photos, out, pattern="**/*.png")  # outputs are not inputs
    assert again.done == [] and again.total == summary.total


def test_missing_input_folder(tmp_path, fpi):
    with pytest.raises(FileNotFoundError, match="input folder does not exist"):
        run_batch(fpi, tmp_path / "nope", tmp_path / "out")
    assert list_inputs(tmp_path) == []


def test_interrupt_leaves_only_complete_outputs_and_a_rerun_finishes(tmp_path, rng, fpi):
    src = tmp_path / "in"
    src.mkdir()
    for i in range(8):
        io.write_image(src / f"{i}.png", rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8))
    out = tmp_path / "out"
    summary = BatchSummary()

    def progress(s):
        if s.processed == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch(fpi, src, out, jobs=2, progress=progress, summary=summary)
    assert summary.interrupted and "run again to resume" in "\n".join(summary.report())
    assert _temporaries(out) == []
    written = sorted(p.name for p in out.iterdir())
    assert 2 <= len(written) < 8 and sorted(summary.done) == sorted(str(src / n) for n in written)
    for name in written:  # every file there is complete
        np.testing.assert_array_equal(
            io.read_image(out / name), fpiwarp.warp_image(io.read_image(src / name), fpi)
        )
    rest = run_batch(fpi, src, out)
    assert len(rest.done) == 8 - len(written) and len(rest.skipped) == len(written)


def test_dask_cluster_runs_the_same_batch(photos, tmp_path, fpi):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
    ) as cluster:
        summary = run_batch(fpi, photos, tmp_path / "dask", pattern="*.png", scheduler=cluster.scheduler_address)
    run_batch(fpi, photos, tmp_path / "local", pattern="*.png")
    assert len(summary.done) == 3 and len(summary.failed) == 1
    assert _digest(tmp_path / "dask") == _digest(tmp_path / "local")
    assert _temporaries(tmp_path / "dask") == []


def test_unreachable_dask_scheduler_is_a_clear_error(photos, tmp_path, fpi, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr("fpiwarp.batch.dask.DASK_CONNECT_TIMEOUT", "1s")
    with pytest.raises(ConnectionError, match="cannot connect to the Dask scheduler"):
        run_batch(fpi, photos, tmp_path / "out", scheduler="tcp://127.0.0.1:9")


def test_text_progress_bar_counts_files_and_failures():
    stream = pyio.StringIO()
    bar = Progress(4, stream=stream, enabled=True)
    bar._bar = None  # the plain text bar, with or without tqdm installed
    summary = BatchSummary(total=4)
    summary.record("done", "a")
    summary.record("failed", "b", "corrupt")
    bar(summary)
    bar.close()
    assert "2/4 files" in stream.getvalue() and "1 failed" in stream.getvalue()
    quiet = pyio.StringIO()
    Progress(4, stream=quiet)(summary)  # not a terminal: silent
    assert quiet.getvalue() == ""


def test_stacks_match_warp_image_with_the_pole_inside_the_output(rng):
    dst = [[11.218, 9.201], [12.078, 9.829], [33.717, 26.390], [2.970, 26.062]]
    fpi = fpiwarp.FPI([[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]], dst)
    x, y = fpi.pole_image
    assert 0 < x < W - 1 and 0 < y < H - 1  # output pixels near it sample far away or at infinity
    stack = rng.integers(0, 256, size=(3, H, W, 3), dtype=np.uint8)
    for order in (0, 1, 3):
        expected = np.stack([fpiwarp.warp_image(im, fpi, order=order, cval=5) for im in stack])
        np.testing.assert_array_equal(warp_batch(stack, fpi, order=order, cval=5), expected)


def test_output_folder_containing_the_input_folder(tmp_path):
    """`batch spec photos .`: the output folder holds the input folder; the
    inputs are still found (only an output folder *inside* the inputs is
    skipped)."""
    from fpiwarp.batch.images import list_inputs

    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "a.png").write_bytes(b"")
    (photos / "out").mkdir()
    (photos / "out" / "b.png").write_bytes(b"")
    assert list_inputs(photos, exclude=tmp_path) == [photos / "a.png"]
    assert list_inputs(photos, "**/*", exclude=photos / "out") == [photos / "a.png"]
    assert list_inputs(photos, "**/*", exclude=tmp_path) == [photos / "a.png", photos / "out" / "b.png"]


# --------------------------------------------------------------------------
# Issue 12: names with newlines, stale temporary files; batching by capability


@pytest.mark.parametrize("name", ["bad\nname.png", "tab\there.png", "cr\rname.png", "esc\x1b[31m.png"])
def test_a_file_name_with_control_characters_keeps_one_line_per_failure(tmp_path, fpi, name):
    src = tmp_path / "in"
    src.mkdir()
    (src / name).write_bytes(b"\x89PNG\r\n\x1a\nnope")
    (src / "other.png").write_bytes(b"not a png either")
    summary = run_batch(fpi, src, tmp_path / "out")
    lines = summary.report()
    failures = [line for line in lines if line.startswith("failed: ")]
    assert len(failures) == 2 and len(lines) == 3
    assert all(ch.isprintable() for line in lines for ch in line)
    assert any(repr(name)[1:-1] in line for line in failures)


def test_stale_temporary_files_are_removed_and_recent_ones_listed(photos, tmp_path, fpi):
    out = tmp_path / "out"
    (out / "sub").mkdir(parents=True)
    stale = out / "sub" / f".a_rgb.png.k1ll3d{io.TEMP_SUFFIX}"
    recent = out / f".b_gray16.png.w0rk1n{io.TEMP_SUFFIX}"
    kept = out / "notes.fpiwarp-tmp.txt"
    for path in (stale, recent, kept):
        path.write_bytes(b"partial")
    old = time.time() - batch_folders.STALE_TEMP_SECONDS - 60
    os.utime(stale, (old, old))
    summary = run_batch(fpi, photos, out, pattern="*.png")
    assert not stale.exists() and recent.exists() and kept.exists()
    assert summary.removed_temps == [str(stale)] and summary.recent_temps == [str(recent)]
    report = "\n".join(summary.report())
    assert "removed 1 temporary files left by an interrupted run" in report
    assert f"temporary file of a run in progress or just killed: {recent}" in report


def test_a_batching_backend_gets_the_whole_stack_in_one_call(fpi, stack, monkeypatch):
    from fpiwarp.backends import get_backend

    backend = get_backend("numpy")
    calls = []
    original = backend.warp_batch

    def counting(*args, **kwargs):
        calls.append(args[0].shape)
        return original(*args, **kwargs)

    monkeypatch.setattr(backend, "warp_batch", counting)
    out = warp_batch(stack, fpi, order=3.0, backend="numpy")
    assert calls == [stack.shape]
    np.testing.assert_array_equal(out[2], fpiwarp.warp_image(stack[2], fpi, order=3, backend="numpy"))


def test_stack_options_are_checked_like_warp_image(fpi, stack):
    with pytest.raises(fpiwarp.SizeLimitError):
        warp_batch(stack, fpi, (10**7, 10**7))
    with pytest.raises(fpiwarp.ArgumentError, match="order"):
        warp_batch(stack, fpi, order=1.5)
    with pytest.raises(fpiwarp.ArgumentError, match="backend_options"):
        list(warp_images(stack, fpi, backend_options={"hardware_filter": True}))


def test_warpers_pickle_without_their_bound_map(fpi, stack):
    warper = Warper(fpi)
    warper(stack[0])
    clone = pickle.loads(pickle.dumps(warper))
    np.testing.assert_array_equal(clone(stack[1]), warper(stack[1]))


@settings(max_examples=200, deadline=None)
@given(names=st.lists(st.text(min_size=1, max_size=12), min_size=1, max_size=5),
       reason=st.text(max_size=30))
def test_the_failure_list_keeps_one_line_per_file_whatever_the_names(names, reason):
    summary = BatchSummary(total=len(names))
    for name in names:
        summary.record("failed", f"in/{name}", f"in/{name}: {reason}")
    lines = summary.report()
    assert len(lines) == 1 + len(names)
    assert all("\n" not in line and "\r" not in line and all(ch.isprintable() for ch in line) for line in lines)
