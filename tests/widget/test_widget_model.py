"""WarpWidget: the anywidget model's round trip.

Python side: the page's messages (as the comm delivers them) change the
traits; traits set from Python change the map. Browser side: the widget's
own front end (its _esm: editor.js + the anywidget adapter) rendered in
headless Chromium with a stand-in for anywidget's model that relays
``model.send`` and trait changes to this WarpWidget over HTTP. Not covered
here: the Jupyter comm itself (JupyterLab's anywidget runtime).
"""

import base64
import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, ArgumentError, LocalDeformation
from fpiwarp.widget import WarpWidget, browser

H, W = 60, 80
SRC = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]]
DST = [[4, 3], [W - 5, -3], [W + 3, H + 2], [-3, H - 4]]


def picture():
    return (np.random.default_rng(5).random((H, W, 3)) * 255).astype(np.uint8)


def test_page_messages_change_traits_and_map():
    w = WarpWidget(picture(), SRC, DST)
    assert w.dst == DST and w.src == SRC and w.edges == [] and w.K == pytest.approx(FPI(SRC, DST).K)
    w._on_page_message(w, {"type": "move", "index": 1, "xy": [70.0, 2.0], "seq": 1}, [])
    assert w.dst[1] == [70.0, 2.0] and w._state["seq"] == 1
    assert w.K == pytest.approx(FPI(SRC, w.dst).K) and isinstance(w.transform, FPI)
    w._on_page_message(w, {"type": "release"}, [])
    for k in (1, 3):
        w._on_page_message(w, {"type": "edge", "index": k}, [])
    assert w.edges == [1, 3]
    # continuous over the picture, as fpiwarp warp builds it
    np.testing.assert_array_equal(w.transform.params(),
                                  LocalDeformation(SRC, w.dst, edges=(1, 3)).for_picture(W, H).params())
    with pytest.raises(Exception, match="read-only"):
        w.K = 2.0


def test_a_local_deformation_given_is_made_continuous_over_the_picture():
    """As fpiwarp warp builds it: the picture's extent, unless it has its own."""
    from fpiwarp.widget.session import Session

    given = LocalDeformation(SRC, DST, edges=(0, 2))
    w = WarpWidget(picture(), transform=given)
    np.testing.assert_array_equal(w.transform.params(), given.for_picture(W, H).params())
    assert not np.array_equal(w.transform.params(), given.params())
    own = LocalDeformation(SRC, DST, edges=(0, 2), extent=(-10, -10, 2 * W, 2 * H))
    assert Session(picture(), own).transform is own


def test_python_traits_rebuild_the_map_and_bad_ones_keep_it():
    w = WarpWidget(picture(), SRC, DST, edges=(0, 2))
    assert isinstance(w.transform, LocalDeformation) and w.edges == [0, 2]
    w.edges = []
    assert isinstance(w.transform, FPI)
    w.dst = [[1, 1], [W - 2, 0], [W, H], [0, H - 2]]
    assert np.allclose(w.transform.dst, w.dst) and w._state["dst"] == w.dst
    good = w.transform
    with pytest.raises(ArgumentError, match="src/dst/edges"):
        w.dst = [[0, 0], [1, 0], [2, 0], [3, 0]]  # collinear: no map
    np.testing.assert_array_equal(w.transform.params(), good.params())
    assert np.allclose(w.dst, good.dst)


def test_image_replaced_and_exported_at_full_size(tmp_path):
    w = WarpWidget(picture(), SRC, DST)
    version = w._image_meta["version"]
    w.image = picture()[::-1].copy()  # same size: the handles stay
    assert w._image_meta["version"] != version and w.dst == DST
    w.image = np.zeros((30, 40), np.uint16)  # another size: the handles start on its corners
    assert w.dst == [[0, 0], [39, 0], [39, 29], [0, 29]] and w._image_meta["dtype"] == "uint16"
    big = (np.random.default_rng(1).random((120, 2600, 3)) * 255).astype(np.uint8)
    w = WarpWidget(big, [[0, 0], [2599, 0], [2599, 119], [0, 119]], [[10, 5], [2590, -20], [2610, 130], [-8, 110]])
    w._on_page_message(w, {"type": "texture_limit", "value": 2048}, [])
    assert (w._image_meta["width"], w._image_meta["height"]) == (2048, 95)  # shown downscaled
    assert len(w._image) == 2048 * 95 * 3
    path = w.export(tmp_path / "full.png", antialias=True)
    out = fpiwarp.read_image(path)
    assert out.shape == big.shape  # exported at full size
    np.testing.assert_array_equal(out, fpiwarp.warp_image(big, w.transform, antialias=True))
    with pytest.raises(fpiwarp.OutputExistsError):
        w.export(tmp_path / "full.png")


# ---- the widget's front end in the browser, with a stand-in model
PAGE = """<!doctype html><html><head><meta charset="utf-8"><link rel="icon" href="data:,">
<style>%(css)s</style></head><body><div id="w"></div>
<script type="module">
import widget from "/esm.js";
const data = {};
const listeners = {};
function take(traits) {
  const changed = [];
  for (const [k, v] of Object.entries(traits)) {
    const value = k === "_image" ? new DataView(Uint8Array.from(atob(v), (c) => c.charCodeAt(0)).buffer) : v;
    if (JSON.stringify(data[k]) !== JSON.stringify(v) || k === "_image") changed.push(k);
    data[k] = value;
  }
  for (const k of changed) (listeners["change:" + k] || []).forEach((cb) => cb());
}
const model = {
  get: (k) => data[k],
  on: (e, cb) => { (listeners[e] = listeners[e] || []).push(cb); },
  off: (e, cb) => { listeners[e] = (listeners[e] || []).filter((f) => f !== cb); },
  send: (msg) => fetch("/send", { method: "POST", body: JSON.stringify(msg) }).then((r) => r.json()).then(take),
};
take(await (await fetch("/traits")).json());
widget.render({ model, el: document.getElementById("w") });
</script></body></html>"""


@pytest.fixture
def bridged(chromium):
    w = WarpWidget(picture(), SRC, DST, height=420)
    lock = threading.Lock()

    def traits():
        keys = ("_state", "_programs", "_image_meta", "src", "dst", "edges", "K", "height")
        out = {k: getattr(w, k) for k in keys}
        out["_image"] = base64.b64encode(w._image).decode()
        return json.dumps(out)

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def _reply(self, body, ctype):
            data = body.encode()
            self.send_response(200)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def do_GET(self):
            if self.path == "/esm.js":
                return self._reply(w._esm, "text/javascript")
            if self.path == "/traits":
                with lock:
                    return self._reply(traits(), "application/json")
            self._reply(PAGE % {"css": w._css}, "text/html")

        def do_POST(self):
            msg = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
            with lock:
                w._on_page_message(w, msg, [])  # as the comm delivers a custom message
                self._reply(traits(), "application/json")

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    browser.open_page(chromium, f"http://127.0.0.1:{httpd.server_address[1]}/")
    yield chromium, w
    httpd.shutdown()
    httpd.server_close()


def test_widget_front_end_drag_changes_dst_and_k(bridged):
    driver, w = bridged
    k0 = w.K
    start = driver.execute_script("return window.fpiwarpEditor.toScreen(window.fpiwarpEditor.state.dst[0]);")
    browser.drag(driver, start, [(30, 20), (10, 10)])
    browser.wait_idle(driver)
    assert w.dst[0] != DST[0] and w.dst[1:] == DST[1:]
    assert w.K != k0 and w.K == pytest.approx(FPI(SRC, w.dst).K)
    frame = browser.capture(driver)[:, :, :3]
    ref = fpiwarp.warp_image(w.image, w.transform, backend="numpy")
    inside = fpiwarp.warp_image(np.ones((H, W), np.float32), w.transform, backend="numpy") == 1.0
    assert 0.5 < inside.mean() and np.mean(np.abs(frame.astype(int) - ref).max(-1)[inside] <= 2) >= 0.99
    outside = fpiwarp.warp_image(np.ones((H, W), np.float32), w.transform, backend="numpy") == 0.0
    assert np.all(frame[outside] == [46, 46, 51])  # the widget's grey background (0.18, 0.18, 0.2)
    assert not browser.console_problems(driver)
