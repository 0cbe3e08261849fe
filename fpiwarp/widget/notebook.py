"""The notebook widget: :class:`WarpWidget` on anywidget.

The same page as ``fpiwarp preview --web`` (static/editor.js), in a
JupyterLab, Notebook 7, VS Code or marimo output cell; the page's messages
travel over the widget's comm instead of HTTP, and the same
:class:`~fpiwarp.widget.session.Session` answers them.
"""

import anywidget
import numpy as np
import traitlets

from ..errors import ArgumentError, OutputExistsError
from ..io.images import write_image
from .server import static_text
from .session import DEFAULT_OVERLAYS, Session

#: The widget's front end: the page's editor and the anywidget adapter.
ADAPTER = """
export default {
  render({ model, el }) {
    const transport = {
      send(msg) { model.send(msg); },
      async getImage() {
        const view = model.get("_image");
        const buffer = view.buffer.slice(view.byteOffset, view.byteOffset + view.byteLength);
        return { meta: model.get("_image_meta"), buffer };
      },
      async getProgram(key) { return model.get("_programs")[key]; },
    };
    el.style.height = `${model.get("height")}px`;
    const editor = createEditor(el, transport);
    const update = () => editor.setState(model.get("_state"));
    model.on("change:_state", update);
    update();
    return () => model.off("change:_state", update);
  },
};
"""


def _points(value, what):
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (4, 2) or not np.all(np.isfinite(a)):
        raise ArgumentError(f"{what} must be four finite (x, y) points, got shape {a.shape}")
    return a


class WarpWidget(anywidget.AnyWidget):
    """Edit a warp live in a notebook: drag the four targets, click edges
    to constrain them (two make a LocalDeformation), toggle the desktop
    viewer's overlays (H handles, O outline, C checkerboard, D distortion
    heat map with its legend, N all), F fit, R reset, X clear edges,
    S save the spec, E export; K is shown live.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C), uint8, uint16 or float32
        Sent to the browser once, downscaled for display where it exceeds
        the browser's texture limit; exported at full size.
    src, dst : (4, 2) points, optional
        Source corners (default the image's) and where they go (default
        ``src``).
    edges : sequence of int
        Constrained edges (edge k joins corner k and k + 1); two make a
        :class:`~fpiwarp.LocalDeformation`.
    antialias : bool
        How :meth:`export` and the E key warp.
    transform : Transform, optional
        Start from this map instead (a Compound's last step is edited).
    order, mode, cval, overlays, backend, height
        Sampling, the overlays shown first, the export backend, the
        widget's height in CSS pixels.

    Notes
    -----
    Traits ``src``, ``dst``, ``edges`` follow the page and can be set from
    Python; ``K`` is read only. The map of the current handles is built in
    Python (the desktop viewer's :class:`~fpiwarp.viewer.Editor`), and the
    page draws its parameter block with the shaders of ``glsl/``.
    """

    _esm = static_text("editor.js") + ADAPTER
    _css = static_text("editor.css")

    src = traitlets.List().tag(sync=True)
    dst = traitlets.List().tag(sync=True)
    edges = traitlets.List(traitlets.Int()).tag(sync=True)
    K = traitlets.Float(read_only=True).tag(sync=True)
    height = traitlets.Int(480).tag(sync=True)
    _state = traitlets.Dict().tag(sync=True)
    _programs = traitlets.Dict().tag(sync=True)
    _image = traitlets.Bytes().tag(sync=True)
    _image_meta = traitlets.Dict().tag(sync=True)

    def __init__(self, image, src=None, dst=None, edges=(), antialias=False, *, transform=None, order=1,
                 mode="constant", cval=0.0, overlays=DEFAULT_OVERLAYS, backend=None, height=480, **kwargs):
        if transform is None:
            h, w = np.shape(image)[:2]
            corners = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
            s = _points(corners if src is None else src, "src")
            d = _points(s if dst is None else dst, "dst")
            transform = _initial_map(s, d)
        self._session = Session(image, transform, order=order, mode=mode, cval=cval, overlays=overlays,
                                antialias=antialias, backend=backend, background=(0.18, 0.18, 0.2, 1.0),
                                name="widget")
        if edges:
            self._session.set_points(edges=list(edges))
        self._syncing = False
        super().__init__(height=height, **kwargs)
        self.on_msg(self._on_page_message)
        self._push(image=True)

    # ---- Python side
    @property
    def transform(self):
        """The map of the current handles (an FPI, a LocalDeformation or a
        Compound ending in one)."""
        return self._session.transform

    @property
    def image(self):
        """The picture being warped (full size)."""
        return self._session.image

    @image.setter
    def image(self, value):
        self._session.set_image(value)
        self._push(image=True)

    @property
    def session(self):
        """The :class:`~fpiwarp.widget.session.Session` behind the page."""
        return self._session

    def export(self, path, antialias=True, *, overwrite=False, backend=None):
        """Write the warp of the full-resolution image by :attr:`transform`
        through the Python backends; returns the path. An existing file is
        kept unless ``overwrite``."""
        from ..warping import warp_image

        s = self._session
        if not overwrite and _exists(path):
            raise OutputExistsError(path)
        v = s.view
        cval = np.broadcast_to(np.asarray(v.cval, np.float64), (s.image.shape[2],))
        out = warp_image(s.image, s.transform, order=v.order, mode=v.mode, cval=cval, antialias=antialias,
                         backend=backend or v.backend)
        write_image(path, out, s.editor.info, overwrite=overwrite)
        return path

    @traitlets.observe("src", "dst", "edges")
    def _on_points(self, change):
        if self._syncing:
            return
        name = change["name"]
        value = _points(change["new"], name) if name != "edges" else change["new"]
        try:
            self._session.set_points(**{name: value})
        finally:
            self._push()

    # ---- the page
    def _on_page_message(self, widget, content, buffers):
        try:
            self._session.handle(content)
        except ArgumentError as exc:
            self._session.editor.message = " ".join(str(exc).split())
        self._push(image=content.get("type") == "texture_limit" if isinstance(content, dict) else False)

    def _push(self, image=False):
        """Send the session's state (and the display texture when it changed)."""
        s = self._session
        state = s.state()
        e = s.editor
        self._syncing = True
        try:
            with self.hold_sync():
                meta, data = s.image_payload()
                if image or meta != self._image_meta:
                    self._image = data
                    self._image_meta = meta
                if state["program"] not in self._programs:
                    self._programs = {**self._programs, state["program"]: s.programs[state["program"]]}
                self.src = e.src.tolist()
                self.dst = e.dst.tolist()
                self.edges = [int(k) for k in e.edges]
                self.set_trait("K", float(e.K))
                self._state = state
        finally:
            self._syncing = False


def _exists(path):
    from pathlib import Path

    return Path(path).exists()


def _initial_map(src, dst):
    from ..maps.fpi import FPI

    return FPI(src, dst)
