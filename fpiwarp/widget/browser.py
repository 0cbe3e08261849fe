"""Headless Chromium for the editor page: screenshots, tests and benchmarks.

Drives the system's Chromium (Debian's ``chromium`` and ``chromium-driver``)
through Selenium, headless, with WebGL2 on SwiftShader where there is no
GPU (``--use-angle=swiftshader --enable-unsafe-swiftshader``). Nothing is
downloaded: both executables must be on PATH (or named by
``FPIWARP_CHROMIUM`` / ``FPIWARP_CHROMEDRIVER``).
"""

import base64
import os
import shutil
import time

import numpy as np

from ..errors import BackendUnavailableError, MissingDependencyError

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "chrome")
DRIVERS = ("chromedriver",)
#: Flags for a quiet headless browser that reaches nothing outside the machine.
FLAGS = (
    "--headless=new", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
    "--disable-dev-shm-usage", "--no-first-run", "--no-default-browser-check", "--disable-extensions",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    # no model or hint downloads, no on-device model service
    "--disable-features=Translate,MediaRouter,OptimizationHints,OptimizationHintsFetching,"
    "OptimizationGuideModelDownloading,OptimizationTargetPrediction,OnDeviceModelService,AIPromptAPI,"
    "AISummarizationAPI,AIWriterAPI,AIRewriterAPI",
    "--disable-domain-reliability", "--disable-client-side-phishing-detection", "--metrics-recording-only",
    "--hide-scrollbars", "--mute-audio",
)
#: screenshot()'s window: the frame is captured at the display texture's
#: size whatever the window's, and the page also draws what it shows, per
#: pixel, at the window's size (on SwiftShader seconds for a local
#: deformation at 1280 x 800): keep that small.
SCREENSHOT_WINDOW = (320, 240)
INSTALL_HINT = "apt-get install chromium chromium-driver; pip install selenium"


def executables():
    """(chromium, chromedriver) paths, or a one-line BackendUnavailableError."""
    browser = os.environ.get("FPIWARP_CHROMIUM") or next(filter(None, map(shutil.which, BROWSERS)), None)
    driver = os.environ.get("FPIWARP_CHROMEDRIVER") or next(filter(None, map(shutil.which, DRIVERS)), None)
    if browser is None or driver is None:
        missing = "chromium" if browser is None else "chromedriver"
        raise BackendUnavailableError(f"no {missing} on PATH: the headless page needs both ({INSTALL_HINT})")
    for path in (browser, driver):  # a bad path must never send Selenium looking for a download
        if not (os.path.isfile(path) and os.access(path, os.X_OK)):
            raise BackendUnavailableError(f"{path} is not an executable file ({INSTALL_HINT})")
    return browser, driver


def launch(size=(1280, 800)):
    """A headless Chromium (selenium WebDriver) with the browser console
    logged; quit it when done."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        raise MissingDependencyError(f"the headless page needs selenium ({INSTALL_HINT})") from None
    browser, driver = executables()
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in FLAGS:
        options.add_argument(flag)
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        options.add_argument("--no-sandbox")  # Chromium refuses to run as root with its sandbox
    options.add_argument(f"--window-size={int(size[0])},{int(size[1])}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    try:
        return webdriver.Chrome(options=options, service=Service(executable_path=driver))
    except Exception as exc:  # noqa: BLE001 - WebDriver reports a failed start in many ways
        raise BackendUnavailableError(f"cannot start headless chromium: {' '.join(str(exc).split())[:300]}") from None


def open_page(driver, url, timeout=60):
    """Load the editor page and wait until it drew its first frame."""
    driver.get(url)
    return wait_drawn(driver, timeout)


def wait_drawn(driver, timeout=60):
    """Wait until the page's editor (the --web page's, or a notebook
    widget's) drew its first frame and is idle."""
    driver.set_script_timeout(timeout)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready = driver.execute_script(
            "const e = window.fpiwarpEditor; return e ? {frames: e.frames, failures: e.failures} : null;")
        if ready and ready["failures"]:
            raise BackendUnavailableError(f"the page failed: {ready['failures'][0]}")
        if ready and ready["frames"] > 0:
            return wait_idle(driver)
        time.sleep(0.05)
    raise BackendUnavailableError(f"the page drew nothing within {timeout} s")


def show(driver, server, session):
    """Serve ``session`` from ``server`` (a PageServer whose page the
    driver has open) instead, and wait until the page reloaded and drew it."""
    with server.lock:
        server.session = session
    driver.execute_async_script("window.fpiwarpEditor.reload().then(() => window.fpiwarpEditor.whenIdle())"
                                ".then(arguments[arguments.length - 1]);")


def wait_idle(driver):
    """Wait until every message the page sent was answered and drawn."""
    return driver.execute_async_script("window.fpiwarpEditor.whenIdle().then(arguments[arguments.length - 1]);")


def capture(driver, *, overlays=False, fmt="rgba8", width=None, height=None, view=None):
    """One frame from the page (see ``capture`` in static/editor.js):
    (H, W, 4) uint8 (``fmt="rgba8"``) or float32 (``"float"``)."""
    opts = {"overlays": bool(overlays), "format": fmt}
    if width is not None:
        opts.update(width=int(width), height=int(height))
    if view is not None:
        opts["view"] = [float(v) for v in view]
    out = driver.execute_script("return window.fpiwarpEditor.capture(arguments[0]);", opts)
    data = base64.b64decode(out["data"])
    dtype = np.float32 if fmt == "float" else np.uint8
    return np.frombuffer(data, dtype).reshape(out["height"], out["width"], 4).copy()


def drag(driver, start, moves, *, duration=10):
    """A real pointer drag on the editor's overlay canvas (Selenium's
    ActionChains: pointerdown, pointermoves, pointerup): press at canvas CSS
    pixel ``start``, move by each (dx, dy) of ``moves``, release; returns
    where the pointer was released (canvas CSS pixels)."""
    chain, (x, y) = _pointer_at(driver, start, duration)
    chain = chain.click_and_hold()
    for dx, dy in moves:
        chain = chain.move_by_offset(int(dx), int(dy))
        x, y = x + int(dx), y + int(dy)
    chain.release().perform()
    return x, y


def click(driver, at):
    """A real click at canvas CSS pixel ``at`` of the overlay canvas."""
    _pointer_at(driver, at)[0].click().perform()


def _pointer_at(driver, at, duration=10):
    """(an action chain with the pointer at canvas CSS pixel ``at``, that
    pixel rounded)."""
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = overlay_canvas(driver)
    w, h = canvas.size["width"], canvas.size["height"]
    x, y = int(round(at[0])), int(round(at[1]))
    chain = ActionChains(driver, duration=duration).move_to_element_with_offset(
        canvas, int(round(x - w / 2)), int(round(y - h / 2)))
    return chain, (x, y)


def overlay_canvas(driver):
    """The editor's overlay canvas (where the pointer events go), scrolled
    into the middle of the window."""
    from selenium.webdriver.common.by import By

    canvas = driver.find_element(By.CSS_SELECTOR, ".fpw-overlay")
    driver.execute_script("arguments[0].scrollIntoView({block: 'center', inline: 'center'});", canvas)
    return canvas


def console_problems(driver):
    """Browser console entries of level WARNING or worse (WebGL warnings,
    script errors)."""
    return [e for e in driver.get_log("browser") if e.get("level") in ("WARNING", "SEVERE")]


def screenshot(session, *, overlays=True, timeout=60):
    """One frame of ``session``'s page rendered in headless Chromium, at the
    display texture's size (the image's, below the browser's texture
    limit), showing the export area: RGB (RGBA for images with alpha)
    uint8; without overlays exactly the warped picture."""
    from .server import PageServer

    c = session.image.shape[2]
    with PageServer(session) as server:
        driver = launch(size=SCREENSHOT_WINDOW)
        try:
            open_page(driver, server.url, timeout)
            w, h = session.state()["image"]["display"]
            frame = capture(driver, overlays=overlays, width=w, height=h)
        finally:
            driver.quit()
    return frame if c in (2, 4) else frame[:, :, :3]
