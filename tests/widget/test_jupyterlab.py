"""WarpWidget in a real JupyterLab: the notebook's cells run in the lab
(its anywidget runtime and the widget's comm to an ipykernel), a synthetic
drag of a handle in the page changes ``widget.dst`` and ``widget.K`` in the
kernel, and the browser console stays clean.

The server (conftest.py's ``jupyterlab``) and the browser run on this
machine only; the lab's own app object (``window.jupyterapp``) runs the
cells, as its menu would.
"""

import json
import time

import numpy as np
import pytest

from fpiwarp import FPI
from fpiwarp.widget import browser

H, W = 60, 80
SRC = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]
DST = [[4, 3], [W - 5, -3], [W + 2, H + 1], [-3, H - 4]]
SETUP = f"""import json
import numpy as np
from fpiwarp.widget import WarpWidget

y, x = np.mgrid[0:{H}, 0:{W}]
img = np.stack([x * 3, y * 4, (x // 10 + y // 10) % 2 * 255], -1).astype(np.uint8)
w = WarpWidget(img, dst={DST}, height=240)
w"""
#: What the kernel sees, written to a file each time the cell runs.
REPORT = """n = globals().get("n", 0) + 1
with open(f"state-{n}.json", "w") as fh:
    json.dump({"src": w.src, "dst": w.dst, "K": w.K, "edges": w.edges}, fh)"""
#: Bounds of the steps in the browser (the whole test takes ~20-30 s).
OPEN_S, RUN_S = 60, 60
#: The lab's window (its side bars and toolbars need room; the shared
#: browser's is smaller), restored after the test.
LAB_WINDOW = (1000, 700)

RUN_CELL = """
const [index, done] = [arguments[0], arguments[arguments.length - 1]];
const app = window.jupyterapp;
const panel = app.shell.currentWidget;
panel.content.activeCellIndex = index;
app.commands.execute(index < 0 ? "notebook:run-all-cells" : "notebook:run-cell")
  .then(() => done(null), (err) => done(String(err)));
"""
KERNEL_READY = """
const app = window.jupyterapp;
const panel = app && app.shell.currentWidget;
const kernel = panel && panel.sessionContext && panel.sessionContext.session && panel.sessionContext.session.kernel;
return kernel ? kernel.status : null;
"""


def _notebook(path):
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(SETUP), nbformat.v4.new_code_cell(REPORT)]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbformat.write(nb, path)


def _until(what, check, timeout, lab):
    deadline = time.monotonic() + timeout
    while True:
        value = check()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"JupyterLab: {what} not within {timeout} s; server log: {lab.log(1500)!r}")
        time.sleep(0.1)


def _report(lab, n, timeout=RUN_S):
    path = lab.root / f"state-{n}.json"
    return _until(f"the kernel's report {n}", lambda: path.exists() and path.stat().st_size and
                  json.loads(path.read_text(encoding="utf-8")), timeout, lab)


@pytest.fixture
def lab_window(chromium):
    size = chromium.get_window_size()
    chromium.set_window_size(*LAB_WINDOW)
    yield chromium
    chromium.set_window_size(size["width"], size["height"])


def test_drag_in_jupyterlab_changes_dst_and_k_in_the_kernel(jupyterlab, lab_window):
    lab, driver = jupyterlab, lab_window
    _notebook(lab.root / "warp.ipynb")
    driver.set_script_timeout(RUN_S)
    driver.get(lab.url("/lab/tree/warp.ipynb"))
    _until("the notebook's kernel", lambda: driver.execute_script(KERNEL_READY) == "idle", OPEN_S, lab)
    assert driver.execute_async_script(RUN_CELL, -1) is None  # run all: the widget, then the first report
    before = _report(lab, 1)
    assert before["dst"] == DST and before["src"] == SRC and before["K"] == pytest.approx(FPI(SRC, DST).K)
    browser.wait_drawn(driver, RUN_S)  # the widget's canvas drew its first frame

    start = driver.execute_script("return window.fpiwarpEditor.toScreen(window.fpiwarpEditor.state.dst[2]);")
    end = browser.drag(driver, start, [(6, 4)] * 5)  # real pointer events: 30 x 20 CSS pixels in five moves
    browser.wait_idle(driver)  # every move answered by the kernel and drawn
    expected = driver.execute_script("return window.fpiwarpEditor.toOutput(arguments[0], arguments[1]);", *end)

    assert driver.execute_async_script(RUN_CELL, 1) is None  # the report cell again, after the drag
    after = _report(lab, 2)
    per_css_px = driver.execute_script("const v = window.fpiwarpEditor.view; return (v[2] - v[0]) / 100;")
    assert after["dst"][2] != DST[2] and np.allclose(after["dst"][2], expected, atol=0.51 * per_css_px), (
        after["dst"][2], expected)
    assert after["dst"][:2] + after["dst"][3:] == DST[:2] + DST[3:] and after["src"] == SRC
    assert after["K"] != before["K"] and after["K"] == pytest.approx(FPI(SRC, after["dst"]).K)
    state = driver.execute_script("return window.fpiwarpEditor.state;")
    assert np.allclose(state["dst"], after["dst"]) and state["K"] == pytest.approx(after["K"])
    problems = [e for e in browser.console_problems(driver)]
    assert not problems, problems
