"""The interactive viewer of ``fpiwarp preview``.

Drag the four target points and see the warp live; the window title shows
the conformal distortion K (the FPI's constant K, or the maximum over the
image for a local deformation). Click an edge of the outline to constrain
it (two constrained edges make a local deformation, paper §4.1; a third
click replaces the older one; X clears them).

Keys: H handles, O outline, C checkerboard, D distortion heat map,
N all overlays off/on, M mesh or per-pixel drawing, A antialiasing on/off,
F fit the view, R reset the points, S save the spec (JSON), E export the
warped image at full resolution (antialiased when the preview is), Q or
Esc quit.

Antialiasing (A) is on by default on a GPU: where the view or the map
shrinks the picture, each screen pixel averages its footprint over the
source's pyramid (built once per picture); where nothing shrinks (zoomed
in) the frame is the plain one, bit for bit. On a software rasterizer
(Mesa llvmpipe: the CPU draws) it starts off, since an antialiased 1080p
frame there costs several plain ones (benchmarks/results/gl_pyramid.md);
A turns it on.

While a point is dragged, maps without a constant distortion (local
deformations) are drawn by the mesh path (see :class:`fpiwarp.viewer.Renderer`,
``method``), which needs no Newton steps per pixel: much faster on a
software rasterizer; on release the exact per-pixel picture comes back.

The logic lives in :class:`Editor` (no window, testable headless); the
window is moderngl-window's pyglet window (``pip install moderngl-window``,
which brings pyglet), and :func:`run` with ``window="headless"`` drives
the same code offscreen.
"""


import os
import sys
from pathlib import Path

import numpy as np

from ..backends.gl.context import software_rasterizer
from ..errors import BackendUnavailableError, DegenerateQuadError
from ..io.images import write_image
from ..maps.fpi import FPI
from ..maps.local import on_picture
from ..maps.transform import Compound
from ..spec import save_spec
from .renderer import Renderer

#: Pick distance for handles and edges, in screen pixels.
PICK_RADIUS = 10.0
OVERLAYS = ("handles", "outline", "checkerboard", "heatmap")
INSTALL_HINT = "pip install 'fpiwarp[preview]' (moderngl and moderngl-window, which brings pyglet)"


def _free_name(path):
    """``path``, or ``stem-1.ext``, ``stem-2.ext``, ... if it exists: the
    viewer never replaces a file it did not write in this session."""
    path = Path(path)
    k = 1
    candidate = path
    while candidate.exists():
        candidate = path.with_name(f"{path.stem}-{k}{path.suffix}")
        k += 1
    return candidate


def max_distortion(transform, shape, samples=48):
    """K of ``transform`` over a (H, W) image: the FPI's constant K, else
    the maximum over a grid of samples × samples source points."""
    if isinstance(transform, FPI):
        return float(transform.K)
    h, w = shape[:2]
    gx, gy = np.meshgrid(np.linspace(0, w - 1, samples), np.linspace(0, h - 1, samples))
    k = transform.distortion(np.stack([gx, gy], -1))
    return float(np.max(k))


class Editor:
    """The viewer's state and actions, independent of any window toolkit.

    Positions are GL window coordinates (y up) of a viewport; the
    :class:`~fpiwarp.viewer.Renderer` converts them to output pixels.
    """

    def __init__(self, renderer, image, transform=None, *, info=None, name="preview",
                 spec_path=None, export_path=None):
        self.renderer = renderer
        self.image = image
        self.info = info
        h, w = image.shape[:2]
        corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], dtype=np.float64)
        self.prefix = []
        last = transform
        if isinstance(transform, Compound):
            self.prefix, last = list(transform.steps[:-1]), transform.steps[-1]
        if last is None:
            last = FPI(corners, corners)
        #: The picture's extent: a local deformation is continuous over it (as ``fpiwarp warp`` builds it).
        self.extent = (w, h)
        last = on_picture(last, *self.extent)
        self.editable = hasattr(last, "src") and hasattr(last, "dst") and type(last).__name__ in (
            "FPI", "LocalDeformation")
        self.src = np.asarray(getattr(last, "src", corners), dtype=np.float64).copy()
        self.dst = np.asarray(getattr(last, "dst", corners), dtype=np.float64).copy()
        self.edges = list(getattr(last, "edges", ()) or ())
        self._initial = (self.dst.copy(), list(self.edges))
        self.spec_path = Path(spec_path or f"{name}.spec.json")
        self.export_path = Path(export_path or f"{name}-warped.png")
        self._written = set()
        self.drag = None
        self.drag_method = "auto"  # the renderer's method while dragging
        self._idle_method = renderer.method
        self.message = ""
        self.saved = []
        self.transform = None
        renderer.set_image(image)
        self._apply(last)
        renderer.fit()

    # ---- the map
    def _full(self, last):
        return Compound([*self.prefix, last]) if self.prefix else last

    def _build(self):
        if len(self.edges) == 2:
            from ..maps.local import LocalDeformation

            return LocalDeformation(self.src, self.dst, edges=tuple(self.edges), extent=self.extent)
        return FPI(self.src, self.dst)

    def _apply(self, last):
        self.transform = self._full(last)
        self.renderer.set_transform(self.transform, handles=self.dst, edges=self.edges)
        self.renderer.invalid = False
        self.K = max_distortion(self.transform, self.image.shape)

    def rebuild(self):
        """Make the map of the current points; a degenerate quad keeps the
        last good map (handles drawn red) and says why. Returns True if ok."""
        try:
            last = self._build()
        except (DegenerateQuadError, ValueError, ArithmeticError) as exc:
            self.renderer.set_transform(self.transform, handles=self.dst, edges=self.edges)
            self.renderer.invalid = True
            self.message = " ".join(str(exc).split())
            return False
        self.message = ""
        self._apply(last)
        return True

    # ---- picking
    def _pick_radius_out(self, viewport):
        return PICK_RADIUS * self.renderer.view_params(viewport)[2]

    def handle_at(self, pos, viewport):
        """Index of the handle within PICK_RADIUS pixels of pos, or None."""
        win = self.renderer.output_to_window(self.dst, viewport)
        d = np.hypot(*(win - np.asarray(pos, float)).T)
        i = int(np.argmin(d))
        return i if d[i] <= PICK_RADIUS else None

    def edge_at(self, pos, viewport):
        """Edge k (joining point k and k + 1) whose drawn curve passes within
        PICK_RADIUS pixels of pos, or None."""
        curves = self.renderer.edge_curves
        if curves is None:
            return None
        win = self.renderer.output_to_window(curves, viewport)
        d = np.hypot(*(win - np.asarray(pos, float)).transpose(2, 0, 1))
        d = np.where(np.isfinite(d), d, np.inf).min(axis=1)
        k = int(np.argmin(d))
        return k if d[k] <= PICK_RADIUS else None

    # ---- events
    def press(self, pos, viewport):
        """Mouse button down at window position pos."""
        if not self.editable:
            self.message = "this spec's last step is not a 4-point map: view only"
            return
        i = self.handle_at(pos, viewport)
        if i is not None:
            self.drag = i
            self.renderer.active_handle = i
            self._idle_method = self.renderer.method
            self.renderer.method = self.drag_method
            return
        k = self.edge_at(pos, viewport)
        if k is not None:
            self.toggle_edge(k)

    def move(self, pos, viewport):
        """Mouse moved to pos (button down): drag the picked handle."""
        if self.drag is None:
            return
        self.dst[self.drag] = self.renderer.window_to_output(pos, viewport)
        self.rebuild()

    def release(self):
        """Mouse button up: the drag ends, the exact picture comes back."""
        if self.drag is not None:
            self.renderer.method = self._idle_method
        self.drag = None
        self.renderer.active_handle = None

    def toggle_edge(self, k):
        """Constrain edge k, or free it; at most two (the older one goes)."""
        old = list(self.edges)
        if k in self.edges:
            self.edges.remove(k)
        else:
            self.edges = (self.edges + [k])[-2:]
        if not self.rebuild():
            self.edges = old
            msg = self.message
            self.rebuild()
            self.message = f"cannot constrain edge {k}: {msg}"

    def key(self, name):
        """A key press by name (lower-case letter, or 'escape'); returns
        False when the viewer should close."""
        r = self.renderer
        if name in ("q", "escape"):
            return False
        toggles = {"h": "handles", "o": "outline", "c": "checkerboard", "d": "heatmap"}
        if name in toggles:
            setattr(r, toggles[name], not getattr(r, toggles[name]))
        elif name == "n":
            on = not any(getattr(r, o) for o in OVERLAYS)
            for o in OVERLAYS:
                setattr(r, o, on and o in ("handles", "outline"))
        elif name == "m":
            r.method = self._idle_method = "mesh" if r.method == "pixel" else "pixel"
            self.message = f"{r.method} drawing"
        elif name == "a":
            r.antialias = not r.antialias
            self.message = f"antialiasing {'on' if r.antialias else 'off'}"
        elif name == "x":
            self.edges = []
            self.rebuild()
        elif name == "r":
            self.dst, self.edges = self._initial[0].copy(), list(self._initial[1])
            self.rebuild()
        elif name == "f":
            r.fit()
        elif name == "s":
            self.save_spec()
        elif name == "e":
            self.export()
        return True

    def _target(self, path):
        path = Path(path)
        return path if path in self._written else _free_name(path)

    def save_spec(self):
        """Write the current map as a JSON spec; returns the path."""
        path = self._target(self.spec_path)
        save_spec(self.transform, path, overwrite=True)
        self._written.add(path)
        self.saved.append(path)
        self.message = f"saved {path}"
        return path

    def export(self):
        """Write the warped image at full resolution; returns the path."""
        path = self._target(self.export_path)
        out = self.renderer.warp_full()
        write_image(path, out, self.info, overwrite=True)
        self._written.add(path)
        self.saved.append(path)
        self.message = f"exported {path}"
        return path

    def title(self):
        edges = f", edges {self.edges[0]},{self.edges[1]}" if len(self.edges) == 2 else (
            f", edge {self.edges[0]} (pick one more)" if self.edges else "")
        text = f"fpiwarp preview: K = {self.K:.4f}{edges}"
        return f"{text}: {self.message}" if self.message else text


def _check_display():
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise BackendUnavailableError(
            "no display (DISPLAY is not set): the interactive viewer needs a desktop session; "
            "render offscreen with --screenshot OUT.png")


def _on_display():
    name = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    return f" on display {name}" if name else ""


def _window_class(window):
    try:
        import moderngl_window as mglw
    except ImportError:
        raise BackendUnavailableError(f"the interactive viewer needs moderngl-window: {INSTALL_HINT}") from None
    try:
        return mglw, mglw.get_local_window_cls(window)
    except ImportError as exc:
        need = exc.name or "its toolkit"
        raise BackendUnavailableError(f"the {window} window needs {need}: {INSTALL_HINT}") from None
    except Exception as exc:  # noqa: BLE001 - pyglet opens the display on import
        raise BackendUnavailableError(f"cannot open a {window} window{_on_display()}: "
                                      f"{' '.join(str(exc).split())}") from None


def run(image, transform=None, *, info=None, name="preview", spec_path=None, export_path=None,
        overlays=("handles", "outline"), window="pyglet", size=(1280, 800), frames=None, screenshot=None,
        order=1, antialias=None):
    """Open the viewer and run its event loop until it is closed.

    ``window`` is a moderngl-window window class ("pyglet", "glfw", ... or
    "headless": offscreen, EGL); ``frames`` stops after that many frames and
    ``screenshot`` then writes the last one (tests, scripts). Raises
    BackendUnavailableError, with a one-line reason, when there is no
    display, no GL driver or no toolkit. ``antialias``: the first frames'
    antialiasing (the A key toggles it); None: on, except on a software
    rasterizer (see the module's docstring). Returns the :class:`Editor`.
    """
    if window != "headless":
        _check_display()
    mglw, cls = _window_class(window)
    try:
        kwargs = {"backend": "egl"} if window == "headless" else {}
        wnd = cls(title="fpiwarp preview", size=size, gl_version=(3, 3), resizable=True, vsync=True, **kwargs)
    except Exception as exc:  # noqa: BLE001 - every toolkit fails in its own way
        raise BackendUnavailableError(f"cannot open a {window} window{_on_display()}: "
                                      f"{' '.join(str(exc).split())}") from None
    mglw.activate_context(window=wnd)
    ctx = wnd.ctx
    if antialias is None:
        antialias = not software_rasterizer(ctx)
    renderer = Renderer(ctx, order=order, background=(0.18, 0.18, 0.2, 1.0), antialias=antialias)
    for o in overlays:
        setattr(renderer, o, True)
    editor = Editor(renderer, image, transform, info=info, name=name, spec_path=spec_path, export_path=export_path)

    def gl_pos(x, y):
        """moderngl-window's (x, y down, window units) -> GL framebuffer pixels."""
        bw, bh = wnd.buffer_size
        w, h = wnd.size
        return (x * bw / max(w, 1), (h - y) * bh / max(h, 1))

    def viewport():
        return (0, 0) + tuple(wnd.buffer_size)

    keys = wnd.keys

    def on_key(key, action, modifiers):
        if action != keys.ACTION_PRESS:
            return
        if key == keys.ESCAPE:
            name_ = "escape"
        else:
            name_ = next((ch for ch in "hocdnmaxrfseq" if key == getattr(keys, ch.upper(), None)), None)
        if name_ is not None and not editor.key(name_):
            wnd.close()

    wnd.key_event_func = on_key
    wnd.mouse_press_event_func = lambda x, y, button: editor.press(gl_pos(x, y), viewport())
    wnd.mouse_drag_event_func = lambda x, y, dx, dy: editor.move(gl_pos(x, y), viewport())
    wnd.mouse_release_event_func = lambda x, y, button: editor.release()
    wnd.resize_func = lambda w, h: renderer.fit()
    shown = [None]
    count = 0
    try:
        while not wnd.is_closing:
            wnd.use()
            ctx.clear(0.12, 0.12, 0.14, 1.0)
            renderer.draw(viewport())
            title = editor.title()
            if title != shown[0]:
                wnd.title = shown[0] = title
            count += 1
            if frames is not None and count >= frames:
                break
            wnd.swap_buffers()
        if screenshot is not None:
            ctx.finish()
            data = wnd.fbo.read(viewport=viewport(), components=3, alignment=1)
            bw, bh = wnd.buffer_size
            frame = np.frombuffer(data, np.uint8).reshape(bh, bw, 3)[::-1]
            write_image(screenshot, frame, overwrite=True)
    finally:
        renderer.release()
        wnd.destroy()
    return editor

