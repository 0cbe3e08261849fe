"""fpiwarp preview IMAGE --web --screenshot: one frame from headless Chromium."""

import numpy as np
import pytest

import fpiwarp
from fpiwarp import io
from fpiwarp.cli import main
from fpiwarp.widget import browser

DST = "6,4,75,-5,84,62,-4,55"


class _Borrowed:
    """The session's Chromium lent to one screenshot: quitting it is the
    session's job."""

    def __init__(self, driver):
        self._driver = driver

    def quit(self):
        pass

    def __getattr__(self, name):
        return getattr(self._driver, name)


@pytest.fixture
def shared_chromium(chromium, monkeypatch):
    """--screenshot's browser is the session's (no launch and no shader
    compile per frame); launch itself is what the chromium fixture runs."""
    monkeypatch.setattr(browser, "launch", lambda size=None: _Borrowed(chromium))
    return chromium


def test_web_screenshot_is_the_warped_picture(shared_chromium, tmp_path, capsys):
    rng = np.random.default_rng(2)
    img = (rng.random((60, 80, 3)) * 255).astype(np.uint8)
    src = tmp_path / "in.png"
    io.write_image(src, img)
    out = tmp_path / "exact.png"
    assert main(["preview", str(src), "--web", "--screenshot", str(out), "--no-overlay", "--dst", DST,
                 "--edges", "0,2"]) == 0
    frame = io.read_image(out)
    f = fpiwarp.LocalDeformation([[0, 0], [79, 0], [79, 59], [0, 59]], np.array(DST.split(","), float).reshape(4, 2),
                                 edges=(0, 2)).for_picture(80, 60)  # the picture's extent, as fpiwarp warp's
    ref = fpiwarp.warp_image(img, f, backend="numpy")
    assert frame.shape == img.shape
    assert np.mean(np.abs(frame.astype(int) - ref).max(-1) <= 2) >= 0.99
    shot = tmp_path / "overlay.png"
    assert main(["preview", str(src), "--web", "--screenshot", str(shot), "--dst", DST]) == 0
    frame = io.read_image(shot)
    yellow = (frame[..., 0] > 230) & (frame[..., 1] > 190) & (frame[..., 2] < 60)  # a handle's colour
    assert yellow.sum() > 20
    assert main(["preview", str(src), "--web", "--screenshot", str(shot), "--dst", DST]) == 1  # exists: kept
    assert "already exists" in capsys.readouterr().err
