"""Fixtures of the browser tests: one headless Chromium for the session and
a page server whose session a test can swap.

Without chromium, chromedriver or selenium the browser tests skip with the
reason in a developer run; with FPIWARP_REQUIRE_BROWSERS=chromium (.ci/run
sets it) they fail instead.
"""

import os

import numpy as np
import pytest

pytest.importorskip("anywidget", reason="the widget extra is not installed (pip install 'fpiwarp[widget]')")


def _required():
    return "chromium" in {s.strip() for s in os.environ.get("FPIWARP_REQUIRE_BROWSERS", "").split(",")}


def _unavailable(reason):
    if _required():
        pytest.fail(f"{reason} (required by FPIWARP_REQUIRE_BROWSERS)")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def chromium():
    """A headless Chromium (selenium WebDriver), shared by the browser tests."""
    from fpiwarp import FpiwarpError
    from fpiwarp.widget import browser

    try:
        driver = browser.launch(size=(900, 700))
    except FpiwarpError as exc:
        _unavailable(f"headless chromium unavailable: {exc}")
    yield driver
    driver.quit()


class SwappableSession:
    """Serves whatever session the test puts in ``.current``."""

    def __init__(self, session):
        self.current = session

    def __getattr__(self, name):
        return getattr(self.current, name)


@pytest.fixture(scope="module")
def page(chromium):
    """(driver, server): the editor page loaded from a PageServer whose
    session a test sets with ``show(session)``."""
    from fpiwarp import FPI
    from fpiwarp.widget import browser
    from fpiwarp.widget.server import PageServer
    from fpiwarp.widget.session import Session

    img = np.zeros((8, 8, 3), np.uint8)
    holder = SwappableSession(Session(img, FPI([[0, 0], [7, 0], [7, 7], [0, 7]], [[0, 0], [7, 0], [7, 7], [0, 7]])))
    server = PageServer(holder).start()
    browser.open_page(chromium, server.url)
    chromium.get_log("browser")  # start each module with an empty console

    def show(session):
        holder.current = session
        chromium.execute_async_script(
            "window.fpiwarpEditor.reload().then(() => window.fpiwarpEditor.whenIdle())"
            ".then(arguments[arguments.length - 1]);")

    yield chromium, server, show
    server.close()
