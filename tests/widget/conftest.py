"""Fixtures of the browser tests: one headless Chromium for the session and
a page server whose session a test can swap.

Without chromium, chromedriver or selenium the browser tests skip with the
reason in a developer run; with FPIWARP_REQUIRE_BROWSERS=chromium (.ci/run
sets it) they fail instead. The JupyterLab test (test_jupyterlab.py) needs
jupyterlab and ipykernel too: it skips without them unless
FPIWARP_REQUIRE_BROWSERS names jupyterlab (.ci/run: "chromium,jupyterlab").
"""

import importlib.util
import json
import os
import secrets
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("anywidget", reason="the widget extra is not installed (pip install 'fpiwarp[widget]')")


def _required(what="chromium"):
    return what in {s.strip() for s in os.environ.get("FPIWARP_REQUIRE_BROWSERS", "").split(",")}


def _unavailable(reason, what="chromium"):
    if _required(what):
        pytest.fail(f"{reason} (required by FPIWARP_REQUIRE_BROWSERS)")
    pytest.skip(reason)


#: The shared browser's window: small, since each frame the page shows is
#: drawn per pixel at the window's size on SwiftShader (a local
#: deformation's Newton inverse: seconds at 900 x 700 on two loaded cores);
#: the frames compared are captured at the picture's size whatever it is.
WINDOW = (640, 480)


@pytest.fixture(scope="session")
def chromium():
    """A headless Chromium (selenium WebDriver), shared by the browser tests."""
    from fpiwarp import FpiwarpError
    from fpiwarp.widget import browser

    try:
        driver = browser.launch(size=WINDOW)
    except FpiwarpError as exc:
        _unavailable(f"headless chromium unavailable: {exc}")
    yield driver
    driver.quit()


@pytest.fixture(scope="module")
def page(chromium):
    """(driver, server, show): the editor page loaded from a PageServer
    whose session a test sets with ``show(session)``."""
    from fpiwarp import FPI
    from fpiwarp.widget import browser
    from fpiwarp.widget.server import PageServer
    from fpiwarp.widget.session import Session

    img = np.zeros((8, 8, 3), np.uint8)
    server = PageServer(Session(img, FPI([[0, 0], [7, 0], [7, 7], [0, 7]], [[0, 0], [7, 0], [7, 7], [0, 7]]))).start()
    browser.open_page(chromium, server.url)
    chromium.get_log("browser")  # start each module with an empty console

    def show(session):
        browser.show(chromium, server, session)

    yield chromium, server, show
    server.close()


#: Bounds of a JupyterLab start: the server's API, then the shutdown.
LAB_START_S, LAB_STOP_S = 90, 20
#: JupyterLab user settings of the test's own settings folder: no news and
#: no update check (nothing is fetched from outside the machine).
LAB_SETTINGS = {"@jupyterlab/apputils-extension/notification.jupyterlab-settings":
                {"fetchNews": "false", "checkForUpdates": False}}


def _free_port():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _get(url, timeout=5):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.status, r.read()


class Lab:
    """A JupyterLab server of the test: ``url(path)`` with its token,
    ``root`` its notebook folder, ``log()`` what it printed."""

    def __init__(self, base, token, root, log_path):
        self.base, self.token, self.root, self.log_path = base, token, root, log_path

    def url(self, path):
        return f"{self.base}{path}{'&' if '?' in path else '?'}token={self.token}"

    def log(self, tail=4000):
        return self.log_path.read_text(encoding="utf-8", errors="replace")[-tail:]


@pytest.fixture(scope="module")
def jupyterlab(tmp_path_factory):
    """A real JupyterLab (``python -m jupyterlab``) on 127.0.0.1 at a free
    port with a token, serving a temporary folder, with fresh temporary
    Jupyter config, data, runtime, settings, workspaces and IPython folders
    (the user's are neither read nor written), reaching nothing outside the
    machine; the kernel imports this checkout's fpiwarp. Shut down (its
    kernels with it) at the end of the module."""
    for module in ("jupyterlab", "ipykernel", "nbformat"):
        if importlib.util.find_spec(module) is None:
            _unavailable(f"{module} is not installed (pip install jupyterlab ipykernel)", "jupyterlab")
    base = tmp_path_factory.mktemp("lab")
    root, home = base / "notebooks", base / "jupyter"
    root.mkdir()
    env = dict(os.environ)
    for var, sub in (("JUPYTER_CONFIG_DIR", "config"), ("JUPYTER_DATA_DIR", "data"), ("JUPYTER_RUNTIME_DIR", "runtime"),
                     ("JUPYTERLAB_SETTINGS_DIR", "settings"), ("JUPYTERLAB_WORKSPACES_DIR", "workspaces"),
                     ("IPYTHONDIR", "ipython")):
        env[var] = str(home / sub)
        (home / sub).mkdir(parents=True)
    for name, values in LAB_SETTINGS.items():
        path = home / "settings" / name.split("/", 1)[0] / name.split("/", 1)[1]
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(values), encoding="utf-8")
    import fpiwarp

    checkout = str(Path(fpiwarp.__file__).resolve().parent.parent)  # the kernel's fpiwarp is the tests'
    env["PYTHONPATH"] = os.pathsep.join([checkout, *filter(None, [env.get("PYTHONPATH")])])
    env.pop("JUPYTER_TOKEN", None)
    port, token = _free_port(), secrets.token_hex(16)
    cmd = [sys.executable, "-m", "jupyterlab", "--no-browser", "--ServerApp.ip=127.0.0.1", f"--ServerApp.port={port}",
           "--ServerApp.port_retries=0", f"--ServerApp.root_dir={root}", f"--IdentityProvider.token={token}",
           "--LabApp.expose_app_in_browser=True", "--LabApp.news_url=None", "--LabApp.extension_manager=readonly",
           "--LabApp.check_for_updates_class=jupyterlab.handlers.announcements.NeverCheckForUpdate"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--allow-root")  # jupyter server refuses root otherwise (as Chromium its sandbox)
    log_path = base / "lab.log"
    with open(log_path, "wb") as log:
        proc = subprocess.Popen(cmd, cwd=root, env=env, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    lab = Lab(f"http://127.0.0.1:{port}", token, root, log_path)
    try:
        deadline = time.monotonic() + LAB_START_S
        while True:
            if proc.poll() is not None:
                _unavailable(f"jupyter lab exited with status {proc.returncode}: {lab.log(600)!r}", "jupyterlab")
            try:
                if _get(lab.url("/api/status"))[0] == 200:
                    break
            except (OSError, urllib.error.URLError):
                pass
            if time.monotonic() > deadline:
                _unavailable(f"jupyter lab did not answer within {LAB_START_S} s: {lab.log(600)!r}", "jupyterlab")
            time.sleep(0.2)
        yield lab
    finally:
        _stop_lab(proc, lab)


def _stop_lab(proc, lab):
    """The server's own shutdown (it stops its kernels), then SIGTERM, then SIGKILL."""
    if proc.poll() is None:
        try:
            req = urllib.request.Request(lab.url("/api/shutdown"), method="POST", data=b"")
            urllib.request.urlopen(req, timeout=10).close()
        except (OSError, urllib.error.URLError):
            pass
    for stop in (None, proc.terminate, proc.kill):
        if stop is not None and proc.poll() is None:
            stop()
        try:
            proc.wait(LAB_STOP_S)
            return
        except subprocess.TimeoutExpired:
            continue
