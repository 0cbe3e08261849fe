"""The --web page driven like a user: a synthetic drag of a handle moves
the target on the Python side and changes K; clicks on two edges give the
LocalDeformation Python builds; S and E write the spec and the export;
the server keeps to its token; the console stays clean."""

import json
import urllib.error
import urllib.request

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, LocalDeformation
from fpiwarp.widget import browser
from fpiwarp.widget.session import Session

H, W = 120, 160
SRC = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]
DST = [[8, 5], [W - 10, -6], [W + 6, H + 4], [-5, H - 8]]


@pytest.fixture
def session(page, tmp_path):
    rng = np.random.default_rng(3)
    img = (rng.random((H, W, 3)) * 255).astype(np.uint8)
    s = Session(img, FPI(SRC, DST), spec_path=tmp_path / "edit.spec.json", export_path=tmp_path / "edit.png")
    page[2](s)
    return s


def _js(driver, script, *args):
    return driver.execute_script("const ed = window.fpiwarpEditor; " + script, *args)


def test_dragging_a_handle_moves_dst_and_k_in_python(page, session):
    driver = page[0]
    k0 = session.editor.K
    start = _js(driver, "return ed.toScreen(ed.state.dst[2]);")
    end = browser.drag(driver, start, [(8, 5)] * 6)  # 48 x 30 CSS pixels, in six moves
    browser.wait_idle(driver)
    expected = _js(driver, "return ed.toOutput(arguments[0], arguments[1]);", *end)
    got = session.editor.dst[2]
    assert np.allclose(got, expected, atol=0.51 * _js(driver, "return (ed.view[2] - ed.view[0]) / 100;")), (
        got, expected)
    assert np.allclose(session.editor.dst[[0, 1, 3]], DST[:2] + DST[3:])
    assert session.editor.K != k0
    assert session.editor.K == pytest.approx(FPI(SRC, session.editor.dst).K)
    state = _js(driver, "return ed.state;")
    assert state["K"] == pytest.approx(session.editor.K) and np.allclose(state["dst"], session.editor.dst)
    assert not browser.console_problems(driver)


def _click_edge(driver, k):
    mid = _js(driver, "const c = ed.state.curves[arguments[0]]; return ed.toScreen(c[c.length >> 1]);", k)
    browser.click(driver, mid)
    browser.wait_idle(driver)


def test_clicking_two_edges_builds_the_python_local_deformation(page, session):
    driver = page[0]
    _click_edge(driver, 0)
    assert session.editor.edges == [0] and isinstance(session.transform, FPI)
    _click_edge(driver, 2)
    assert session.editor.edges == [0, 2]
    built = session.transform
    assert isinstance(built, LocalDeformation)
    expected = LocalDeformation(SRC, DST, edges=(0, 2), extent=(W, H))  # the picture's, as fpiwarp warp's
    np.testing.assert_array_equal(built.params(), expected.params())
    assert _js(driver, "return ed.state.edges;") == [0, 2]
    # the page draws the block of that map: its frame is the numpy warp of it
    frame = browser.capture(driver)[:, :, :3]
    ref = fpiwarp.warp_image(session.image, expected, backend="numpy")
    # 98 %: the local deformation's float32 Newton inverse (see test_page_parity)
    assert np.mean(np.abs(frame.astype(int) - ref).max(-1) <= 2) >= 0.98
    _click_edge(driver, 0)  # a constrained edge clicked again is freed
    assert session.editor.edges == [2] and isinstance(session.transform, FPI)
    assert not browser.console_problems(driver)


def test_s_and_e_save_the_spec_and_export_full_size(page, session, tmp_path):
    from selenium.webdriver.common.by import By

    driver = page[0]
    (tmp_path / "edit.png").write_bytes(b"not ours")  # a file the session did not write is never replaced
    root = driver.find_element(By.CSS_SELECTOR, ".fpw-editor")
    root.send_keys("s")
    browser.wait_idle(driver)
    root.send_keys("e")
    browser.wait_idle(driver)
    spec, out = tmp_path / "edit.spec.json", tmp_path / "edit-1.png"
    assert spec.exists() and out.exists() and (tmp_path / "edit.png").read_bytes() == b"not ours"
    assert isinstance(fpiwarp.load_spec(spec), FPI)
    exported = fpiwarp.read_image(out)
    np.testing.assert_array_equal(exported, fpiwarp.warp_image(session.image, session.transform))
    assert "wrote" in _js(driver, "return document.querySelector('.fpw-status').textContent;")


def test_overlay_toggles_follow_the_desktop_keys(page, session):
    from selenium.webdriver.common.by import By

    driver = page[0]
    root = driver.find_element(By.CSS_SELECTOR, ".fpw-editor")
    assert sorted(_js(driver, "return [...ed.overlays];")) == ["handles", "outline"]
    root.send_keys("cd")
    assert sorted(_js(driver, "return [...ed.overlays];")) == ["checkerboard", "handles", "heatmap", "outline"]
    assert _js(driver, "return !document.querySelector('.fpw-legend').hidden;")
    root.send_keys("n")
    assert _js(driver, "return [...ed.overlays];") == []
    root.send_keys("n")
    assert sorted(_js(driver, "return [...ed.overlays];")) == ["handles", "outline"]
    assert not browser.console_problems(driver)


def test_server_refuses_requests_without_its_token(page):
    server = page[1]
    assert server.httpd.server_address[0] == "127.0.0.1"
    base = f"http://127.0.0.1:{server.port}"
    for path in ("/", "/api/state", "/api/image", "/api/state?token=wrong"):
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(base + path, timeout=10)
        assert err.value.code == 403
    with urllib.request.urlopen(f"{base}/api/state?token={server.token}", timeout=10) as r:
        assert "K" in json.load(r)
    with urllib.request.urlopen(f"{base}/static/editor.js", timeout=10) as r:
        assert r.headers["Content-Security-Policy"].startswith("default-src 'none'")
    bad = urllib.request.Request(f"{base}/api/message?token={server.token}", data=b'{"type": "nope"}',
                                 method="POST")
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(bad, timeout=10)
    assert err.value.code == 400 and "unknown page message" in json.load(err.value)["error"]


def test_image_above_the_texture_limit_is_shown_downscaled(page):
    """Above the page's texture limit the display texture is downscaled, and
    the block the page draws composes the map with full-size-to-texture
    pixels: the frame is the warp of the downscaled picture, at full size."""
    from fpiwarp import Compound
    from fpiwarp.widget.session import display_image, texture_scale

    driver, _, show = page
    y, x = np.mgrid[0:200, 0:300]
    img = np.stack([x * 255 // 300, y * 255 // 200, (x // 7 + y // 5) % 2 * 255], -1).astype(np.uint8)
    f = FPI([[0, 0], [299, 0], [299, 199], [0, 199]], [[10, 5], [290, -8], [305, 210], [-6, 190]])
    s = Session(img, f, overlays=())
    show(s)
    driver.execute_async_script("window.fpiwarpEditor.post({type: 'texture_limit', value: 150});"
                                "window.fpiwarpEditor.whenIdle().then(arguments[arguments.length - 1]);")
    assert s.state()["image"]["display"] == [150, 100]
    frame = browser.capture(driver)[:, :, :3]
    small = display_image(img, (150, 100))
    scale = texture_scale(img.shape, (150, 100))
    ref = fpiwarp.warp_image(small, Compound([scale.inverse, f]), img.shape[:2], backend="numpy")
    assert frame.shape == img.shape
    assert np.mean(np.abs(frame.astype(int) - ref).max(-1) <= 2) >= 0.99
    assert not browser.console_problems(driver)
