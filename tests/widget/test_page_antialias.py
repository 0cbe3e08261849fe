"""The page's antialiasing (the A key): the browser's frame of a shrinking
map over the display texture's pyramid equals warp_image(antialias=True,
backend="numpy"); the pyramid is built once per picture."""

import numpy as np

import fpiwarp
from fpiwarp import FPI, RLinear
from fpiwarp.widget import browser
from fpiwarp.widget.session import Session

H, W = 120, 160
SRC = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]


def zone_plate():
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    plate = 0.5 + 0.5 * np.cos(np.pi * ((x - W / 2) ** 2 + (y - H / 2) ** 2) / W)
    return np.repeat(np.round(255 * plate).astype(np.uint8)[..., None], 3, axis=-1)


def _js(driver, script):
    return driver.execute_script("const ed = window.fpiwarpEditor; " + script)


def _press(driver, key):
    driver.execute_async_script(f"window.fpiwarpEditor.key({key!r}); "
                                "window.fpiwarpEditor.whenIdle().then(arguments[arguments.length - 1]);")


def test_key_a_antialiases_the_page_over_the_pyramid(page):
    driver, _, show = page
    img = zone_plate()
    # shrinks 1/8 and 1/6 x 1/2 (pyramid levels 1 and 2, a blend band between them)
    shrinks = [RLinear(0.125, 0, 20 + 15j), RLinear((1 / 6 + 1 / 2) / 2, (1 / 6 - 1 / 2) / 2, 10 + 5j)]
    session = Session(img, FPI(SRC, SRC), overlays=())
    show(session)
    builds = _js(driver, "return ed.pyramidBuilds;")
    _press(driver, "a")
    assert session.view.antialias and _js(driver, "return ed.state.antialias;")
    for f in shrinks:
        session.editor.prefix = [f]  # the map shown: f after the edited identity step
        session.editor.rebuild()
        show(session)
        want = fpiwarp.warp_image(img, session.transform, antialias=True, backend="numpy")
        plain = fpiwarp.warp_image(img, session.transform, backend="numpy")
        got = browser.capture(driver)[:, :, :3]
        inside = np.abs(want.astype(int) - plain).max(-1) > 0  # where antialiasing changes the picture
        diff = np.abs(got.astype(int) - want).max(-1)
        assert inside.sum() > 200 and np.mean(diff <= 1) >= 0.998, np.mean(diff <= 1)
    assert _js(driver, "return ed.pyramidBuilds;") == builds + 1  # one picture, one pyramid
    _press(driver, "a")
    assert not session.view.antialias
    show(session)
    np.testing.assert_array_less(np.abs(browser.capture(driver)[:, :, :3].astype(int) - plain).max(), 3)
    assert not browser.console_problems(driver)
