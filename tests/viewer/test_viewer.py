"""Real-time preview: fpiwarp.viewer.Renderer, the viewer's Editor, the
``fpiwarp preview`` command and the embedding examples, under Mesa's
llvmpipe (headless EGL).

The screenshot without overlays is the picture warp_image makes (within 2
levels on >= 99% of pixels; in practice within 1 everywhere); moving a
handle uploads a new parameter block and compiles nothing; the heat map
shows the dilation the host computes; the examples render a frame; a
missing display or GL driver gives one clear line, never a traceback.
"""

import importlib.util
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, LocalDeformation
from fpiwarp.cli.commands import main
from fpiwarp.io import images as io

H, W = 48, 64
SRC = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]
DST = [[4, 3], [60, -2], [66, 50], [-3, 44]]
LEVELS, FRACTION = 2, 0.99

@pytest.fixture
def ctx(gl_backend):
    """The gl backend's headless context. One context per process: a
    second one would take "current" from it (moderngl does not switch)."""
    from fpiwarp.backends.gl import shared_context

    c = shared_context()
    assert c.error == "GL_NO_ERROR"
    yield c
    assert c.error == "GL_NO_ERROR"


@pytest.fixture
def picture(rng):
    """A smooth RGB picture with some texture (bilinear differences show)."""
    y, x = np.mgrid[0:H, 0:W]
    base = np.stack([x * 4, y * 5, (x + y) * 2], -1).astype(np.float64)
    return np.clip(base + rng.integers(0, 40, size=(H, W, 3)), 0, 255).astype(np.uint8)


def _close(frame, ref, levels=LEVELS, fraction=FRACTION):
    assert frame.shape == ref.shape and frame.dtype == ref.dtype
    d = np.abs(frame.astype(np.float64) - ref.astype(np.float64))
    assert np.mean(d <= levels) >= fraction, f"max diff {d.max()}, {np.mean(d > levels):.4f} beyond {levels}"


def _one_line(err):
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def _has_handle(frame):
    """Some pixel has the handles' colour (fpiwarp.viewer.HANDLE_COLOR)."""
    from fpiwarp.viewer import HANDLE_COLOR

    return np.any(np.all(np.abs(frame[..., :3] - np.array(HANDLE_COLOR[:3]) * 255) <= 2, axis=-1))


def _line_distance(p, a, b):
    d = np.asarray(b, float) - a
    return np.abs((p[..., 0] - a[0]) * d[1] - (p[..., 1] - a[1]) * d[0]) / np.hypot(*d)


def _frame(renderer, size):
    """Draw into an offscreen framebuffer; the RGB frame, top row first."""
    from fpiwarp.backends.gl import bound_framebuffer

    c = renderer.ctx
    previous = bound_framebuffer(c)
    fbo = c.simple_framebuffer(size)
    try:
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 1.0)
        renderer.draw((0, 0) + tuple(size), y_down=True)
        data = fbo.read(components=3, alignment=1)
    finally:
        previous.use()  # never leave a deleted framebuffer bound
        fbo.release()
    return np.frombuffer(data, np.uint8).reshape(size[1], size[0], 3).copy()


# ---------------------------------------------------------------- the command
def test_screenshot_without_overlay_is_the_warped_image(tmp_path, capsys, picture, gl_backend):
    path = tmp_path / "in.png"
    io.write_image(path, picture)
    out = tmp_path / "shot.png"
    src, dst = ",".join(str(v) for p in SRC for v in p), ",".join(str(v) for p in DST for v in p)
    code = main(["preview", str(path), "--src", src, "--dst", dst, "--screenshot", str(out), "--no-overlay"])
    assert code == 0, capsys.readouterr().err
    frame = io.read_image(out)
    _close(frame, fpiwarp.warp_image(picture, FPI(SRC, DST)))


def test_screenshot_of_a_spec_with_overlays(tmp_path, capsys, picture, gl_backend):
    path, spec, out = tmp_path / "in.png", tmp_path / "spec.json", tmp_path / "shot.png"
    io.write_image(path, picture)
    fpiwarp.spec.save_spec(FPI(SRC, DST), spec)
    assert main(["preview", str(path), "--spec", str(spec), "--screenshot", str(out)]) == 0
    frame = io.read_image(out)
    assert frame.shape == (H, W, 3)
    plain = fpiwarp.warp_image(picture, FPI(SRC, DST))
    changed = np.any(frame != plain, axis=2)
    assert 0.01 < changed.mean() < 0.5  # the outline and handles, drawn over the picture
    assert main(["preview", str(path), "--spec", str(spec), "--screenshot", str(out)]) == 1
    assert "already exists" in _one_line(capsys.readouterr().err)


@pytest.mark.parametrize("dtype,channels", [(np.uint8, 1), (np.uint8, 4), (np.uint16, 3), (np.float32, 2)])
def test_render_image_keeps_dtype_and_channels(dtype, channels, picture, gl_backend):
    from fpiwarp.viewer import render_image

    img = np.dstack([picture, picture[..., :1]])[..., :channels].astype(np.float64)
    scale = {np.uint8: 1.0, np.uint16: 257.0, np.float32: 1 / 255}[dtype]
    img = (img * scale).astype(dtype)
    img = img[..., 0] if channels == 1 else img
    t = FPI(SRC, DST)
    # one uint8 level of the picture's range: float32 display arithmetic on
    # normalized uint16 values is good to a few of its 65536 levels
    _close(render_image(img, t, cval=7 * scale), fpiwarp.warp_image(img, t, cval=7 * scale), levels=2 * scale)


def test_missing_display_is_one_clear_line(tmp_path, capsys, picture, monkeypatch):
    path = tmp_path / "in.png"
    io.write_image(path, picture)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    code = main(["preview", str(path)])
    out, err = capsys.readouterr()
    assert code == 1 and out == ""
    line = _one_line(err)
    assert "no display" in line and "--screenshot" in line


def test_missing_gl_driver_is_one_clear_line(tmp_path, capsys, picture, monkeypatch):
    from fpiwarp import backends

    path = tmp_path / "in.png"
    io.write_image(path, picture)
    monkeypatch.setitem(backends._status, "gl", (None, "no OpenGL 3.3 context: egl: eglInitialize failed"))
    code = main(["preview", str(path), "--screenshot", str(tmp_path / "s.png")])
    _, err = capsys.readouterr()
    assert code == 1
    assert "cannot render offscreen" in _one_line(err) and "eglInitialize" in err
    assert not (tmp_path / "s.png").exists()


# ---------------------------------------------------------------- the renderer
def test_moving_a_handle_uploads_uniforms_only(ctx, picture):
    from fpiwarp.viewer import Editor, Renderer

    r = Renderer(ctx)
    r.handles = r.outline = r.heatmap = r.checkerboard = True
    ed = Editor(r, picture, FPI(SRC, DST))
    r.view = (-0.5, -0.5, W - 0.5, H - 0.5)
    vp = (0, 0, W, H)
    before = _frame(r, (W, H))
    compiled, uploads = r.compile_count, r.uploads
    assert compiled >= 2  # the image program and the overlay program
    handle = r.output_to_window(ed.dst[2], vp)
    ed.press(handle, vp)
    assert ed.drag == 2
    for step in range(1, 6):
        ed.move(handle + [-2.0 * step, 1.0 * step], vp)
        after = _frame(r, (W, H))
    ed.release()
    assert r.compile_count == compiled  # no new program: values only
    assert r.uploads == uploads + 5
    np.testing.assert_allclose(ed.dst[2], np.array(DST[2]) + [-10, -5], atol=1e-9)  # window y is up
    assert np.any(after != before)
    r.handles = r.outline = r.heatmap = r.checkerboard = False
    _close(_frame(r, (W, H)), fpiwarp.warp_image(picture, FPI(SRC, ed.dst)))
    r.release()


def test_fpi_heat_map_is_constant_and_local_deformation_heat_map_follows_the_dilation(ctx, picture):
    from fpiwarp.viewer import Renderer

    def jet(t):
        t = np.clip(t, 0, 1)[..., None]
        return np.clip(1.5 - np.abs(4 * t - np.array([3.0, 2.0, 1.0])), 0, 1)

    r = Renderer(ctx)
    r.set_image(picture)
    r.heatmap, r.heat_mix, r.heat_max = True, 1.0, 0.25
    fpi = FPI(SRC, DST)
    r.set_transform(fpi)
    frame = _frame(r, (W, H)).astype(np.float64)
    src = fpi.inverse(np.stack(np.meshgrid(np.arange(W), np.arange(H)), -1).astype(float))
    inside = np.all((src > 0.5) & (src < np.array([W - 1.5, H - 1.5])), -1)
    d = (fpi.K - 1) / (fpi.K + 1)
    assert d > 0.01
    r.heat_max = 0.05
    frame = _frame(r, (W, H)).astype(np.float64)
    np.testing.assert_allclose(frame[inside], np.broadcast_to(255 * jet(np.array(d / 0.05)), frame[inside].shape),
                               atol=1.0)
    r.heat_max = 0.25

    local = LocalDeformation([[10, 8], [54, 8], [54, 40], [10, 40]], [[10, 8], [54, 8], [58, 36], [7, 44]],
                             edges=(0, 2))
    r.set_transform(local)
    frame = _frame(r, (W, H)).astype(np.float64)
    grid = np.stack(np.meshgrid(np.arange(W), np.arange(H)), -1).astype(float)
    src = local.inverse(grid)
    dil = local.dilation_at(src)
    inside = np.all((src > 0.5) & (src < np.array([W - 1.5, H - 1.5])), -1) & np.isfinite(dil)
    # Fragments difference the map over 2x2 blocks: compare with the
    # dilation's range over each pixel's 3x3 neighbourhood, away from the
    # lines of the constrained edges (there the map is only continuous, and
    # blocks straddling a line show a wrong colour: a line 1-2 px wide).
    dst = np.array(local.dst)
    far = (_line_distance(grid, dst[0], dst[1]) > 1.5) & (_line_distance(grid, dst[2], dst[3]) > 1.5)
    pad = np.pad(np.where(np.isfinite(dil), dil, np.nan), 1, mode="edge")
    near = np.stack([pad[i:i + H, j:j + W] for i in range(3) for j in range(3)])
    sel = inside & far
    assert sel.mean() > 0.6
    lo, hi = np.nanmin(near, 0)[sel], np.nanmax(near, 0)[sel]
    ts = lo[:, None] + (hi - lo)[:, None] * np.linspace(0, 1, 33)
    err = np.abs(255 * jet(ts / 0.25) - frame[sel][:, None, :]).max(-1).min(-1)
    # 20 levels: 0.005 of dilation (the continuous construction's spline bends across the whole band,
    # so the fragments' 2x2 differences stray a little more than they did near the region alone)
    assert err.max() <= 20, np.percentile(err, [50, 99, 100])
    assert dil[inside].max() > 0.05 and dil[inside].min() < 1e-6  # varies: the outer similarities have 0
    r.release()


def test_mesh_path_is_the_backends_mesh_warp(ctx, picture):
    from fpiwarp.backends.gl import warp_image_mesh
    from fpiwarp.viewer import Renderer

    local = LocalDeformation([[10, 8], [54, 8], [54, 40], [10, 40]], [[10, 8], [54, 8], [58, 36], [7, 44]],
                             edges=(0, 2))
    r = Renderer(ctx, method="mesh")
    r.mesh_step = 2.0
    r.set_image(picture)
    r.set_transform(local)
    _close(_frame(r, (W, H)), warp_image_mesh(picture, local, grid_step=2.0)[..., :3], levels=1, fraction=0.999)
    r.method = "auto"  # an FPI: per pixel, exact
    r.set_transform(FPI(SRC, DST))
    _close(_frame(r, (W, H)), fpiwarp.warp_image(picture, FPI(SRC, DST)))
    r.release()


def test_dragging_a_local_deformation_draws_the_mesh_then_the_exact_picture(ctx, picture):
    from fpiwarp.viewer import Editor, Renderer

    src = [[10, 8], [54, 8], [54, 40], [10, 40]]
    local = LocalDeformation(src, [[10, 8], [54, 8], [58, 36], [7, 44]], edges=(0, 2))
    r = Renderer(ctx)
    ed = Editor(r, picture, local)
    r.view = (-0.5, -0.5, W - 0.5, H - 0.5)
    vp = (0, 0, W, H)
    handle = r.output_to_window(ed.dst[2], vp)
    ed.press(handle, vp)
    assert r.method == "auto" and r._method() == "mesh"
    ed.move(handle + [1.0, 0.0], vp)
    _frame(r, (W, H))
    compiled = r.compile_count
    for step in range(2, 5):
        ed.move(handle + [step, -step], vp)
        _frame(r, (W, H))
    assert r.compile_count == compiled
    ed.release()
    assert r.method == "pixel" and isinstance(ed.transform, LocalDeformation)
    _close(_frame(r, (W, H)), fpiwarp.warp_image(picture, ed.transform))
    r.release()


def test_view_fits_the_viewport_and_maps_mouse_positions(ctx, picture):
    from fpiwarp.viewer import Renderer

    r = Renderer(ctx)
    r.set_image(picture)
    r.set_transform(FPI(SRC, DST))
    r.fit()
    vp = (10, 20, 300, 200)
    pts = np.array([[0.0, 0.0], [W - 1.0, H - 1.0], [12.5, 30.25]])
    win = r.output_to_window(pts, vp)
    np.testing.assert_allclose(r.window_to_output(win, vp), pts, atol=1e-9)
    assert np.all((win >= [10, 20]) & (win <= [310, 220]))
    assert win[0, 1] > win[1, 1]  # window y is up, image y is down
    r.release()


# ---------------------------------------------------------------- the editor
def test_editor_constrains_edges_saves_and_exports(ctx, picture, tmp_path):
    from fpiwarp.viewer import Editor, Renderer

    r = Renderer(ctx)
    r.outline = True
    src = [[10, 8], [54, 8], [54, 40], [10, 40]]
    dst = [[10, 8], [54, 8], [58, 36], [7, 44]]
    ed = Editor(r, picture, FPI(src, dst), name=str(tmp_path / "pic"))
    vp = (0, 0, 4 * W, 4 * H)
    k_fpi = ed.K
    assert "K = " in ed.title() and f"{k_fpi:.4f}" in ed.title()
    for k in (0, 2):  # click the middle of edges 0 and 2
        mid = r.output_to_window(r._curves[k][len(r._curves[k]) // 2], vp)
        ed.press(mid, vp)
        ed.release()
    assert ed.edges == [0, 2] and isinstance(ed.transform, LocalDeformation)
    assert ed.K != k_fpi and "edges 0,2" in ed.title()
    # a degenerate quad keeps the last good map and says why
    good = ed.transform
    ed.press(r.output_to_window(ed.dst[0], vp), vp)
    ed.move(r.output_to_window(np.array(ed.dst[2]), vp), vp)
    assert ed.transform is good and r.invalid and ed.message
    ed.release()
    ed.key("r")  # reset
    assert ed.edges == [] and isinstance(ed.transform, FPI) and not r.invalid
    ed.edges = [0, 2]
    ed.rebuild()
    spec_path = ed.save_spec()
    again = ed.save_spec()  # its own file: replaced, not renamed
    assert spec_path == again
    loaded = fpiwarp.load_spec(spec_path)
    assert isinstance(loaded, LocalDeformation) and loaded.edges == (0, 2)
    np.testing.assert_allclose(loaded.dst, ed.dst)
    exported = ed.export()
    out = io.read_image(exported)
    _close(out, fpiwarp.warp_image(picture, ed.transform), levels=1, fraction=0.998)
    r.release()


def test_editor_never_replaces_a_users_file(ctx, picture, tmp_path):
    from fpiwarp.viewer import Editor, Renderer

    mine = tmp_path / "pic.spec.json"
    mine.write_text("my notes")
    r = Renderer(ctx)
    ed = Editor(r, picture, FPI(SRC, DST), name=str(tmp_path / "pic"))
    path = ed.save_spec()
    assert path != mine and mine.read_text() == "my notes"
    r.release()


def test_viewer_loop_runs_headless(gl_backend, picture, tmp_path):
    if importlib.util.find_spec("moderngl_window") is None:
        pytest.skip("moderngl-window not installed (pip install moderngl-window)")
    # in a process of its own: the headless window makes its own context
    path, shot = tmp_path / "in.png", tmp_path / "frame.png"
    io.write_image(path, picture)
    code = ("import sys, fpiwarp; from fpiwarp.viewer import run; "
            "img, info = fpiwarp.read_image(sys.argv[1], with_info=True); "
            "t = fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 3], [60, -2], [66, 50], [-3, 44]]); "
            "ed = run(img, t, window='headless', size=(320, 240), frames=2, screenshot=sys.argv[2]); "
            "print(ed.title())")
    proc = subprocess.run([sys.executable, "-c", code, str(path), str(shot)], check=False, capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert f"K = {FPI(SRC, DST).K:.4f}" in proc.stdout
    frame = io.read_image(shot)
    assert frame.shape == (240, 320, 3)
    assert _has_handle(frame)


# ---------------------------------------------------------------- examples
def _run_example(module, tmp_path, env=None):
    shot = tmp_path / f"{module}.png"
    proc = subprocess.run([sys.executable, "-m", f"fpiwarp.viewer.examples.{module}", "--frames", "1",
                           "--screenshot", str(shot)], check=False, capture_output=True, text=True, timeout=120,
                          env={**os.environ, **(env or {})})
    assert proc.returncode == 0, proc.stderr[-2000:]
    frame = io.read_image(shot)
    assert frame.shape == (720, 960, 3)
    assert _has_handle(frame)  # the handles are drawn
    assert np.mean(np.all(frame == frame[0, 0], axis=-1)) < 0.6  # the picture covers the middle


def test_moderngl_window_example_renders_a_frame(gl_backend, tmp_path):
    if importlib.util.find_spec("moderngl_window") is None:
        pytest.skip("moderngl-window not installed (pip install moderngl-window)")
    _run_example("mglw_embed", tmp_path)


@pytest.fixture
def xvfb():
    """A private X server (Qt's offscreen platform needs one for OpenGL)."""
    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.skip("Xvfb not installed (apt-get install xvfb): Qt has no headless OpenGL without an X server")
    read, write = os.pipe()
    proc = subprocess.Popen([exe, "-displayfd", str(write), "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                            pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    try:
        with os.fdopen(read) as f:
            number = f.readline().strip()
        if not number:
            pytest.skip("Xvfb did not start")
        yield f":{number}"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_viewer_opens_a_pyglet_window(gl_backend, tmp_path, xvfb, picture):
    if importlib.util.find_spec("moderngl_window") is None or importlib.util.find_spec("pyglet") is None:
        pytest.skip("moderngl-window/pyglet not installed (pip install moderngl-window)")
    path, shot = tmp_path / "in.png", tmp_path / "shot.png"
    io.write_image(path, picture)
    code = ("import sys, fpiwarp; from fpiwarp.viewer import run; "
            "img, info = fpiwarp.read_image(sys.argv[1], with_info=True); "
            "ed = run(img, info=info, frames=2, screenshot=sys.argv[2], size=(320, 240)); print(ed.title())")
    proc = subprocess.run([sys.executable, "-c", code, str(path), str(shot)], check=False, capture_output=True,
                          text=True, timeout=120, env={**os.environ, "DISPLAY": xvfb})
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "K = 1.0000" in proc.stdout  # the identity map to start with
    frame = io.read_image(shot)
    assert frame.shape == (240, 320, 3) and _has_handle(frame)


def test_qt_example_renders_a_frame(gl_backend, tmp_path, xvfb):
    if importlib.util.find_spec("PySide6") is None:
        pytest.skip("PySide6 not installed (pip install PySide6-Essentials)")
    _run_example("qt_embed", tmp_path, env={"DISPLAY": xvfb, "QT_QPA_PLATFORM": "offscreen"})


def test_renderer_release_keeps_a_shared_warper(gl_backend):
    from fpiwarp import viewer as fgl
    from fpiwarp.backends import get_backend

    backend = get_backend(gl_backend)
    renderer = fgl.Renderer(backend.ctx, warper=backend.warper)
    renderer.set_image(np.zeros((8, 8, 3), np.uint8))
    renderer.release()
    img = np.arange(64 * 3, dtype=np.uint8).reshape(8, 8, 3)
    out = fpiwarp.warp_image(img, fpiwarp.RLinear(1), backend=gl_backend)
    assert np.array_equal(out, img)  # the backend still works


def test_releasing_a_renderer_leaves_the_callers_framebuffer_bound(ctx, picture):
    """A renderer that made its own warper frees it on release; the
    framebuffer the caller drew into stays bound, and the next framebuffer
    moderngl makes works (a deleted one left bound would break it)."""
    from fpiwarp import viewer as fgl

    target = ctx.simple_framebuffer((W, H))
    previous = ctx.detect_framebuffer(0)
    try:
        renderer = fgl.Renderer(ctx)
        renderer.set_image(picture)
        renderer.set_transform(FPI(SRC, DST))
        target.use()
        renderer.draw((0, 0, W, H), y_down=True)
        renderer.warp_full()  # binds the warper's own framebuffers
        target.use()
        renderer.release()
        assert ctx.fbo is target
        ctx.framebuffer(color_attachments=[ctx.texture((2, 2), 4)]).release()
        assert ctx.error == "GL_NO_ERROR"
    finally:
        previous.use()
        target.release()
