"""Embed fpiwarp's preview renderer in a moderngl-window application.

The application owns the window and the loop; the renderer draws the
warped sample picture into the window's framebuffer every frame, and the
mouse drags the target points (through :class:`fpiwarp.viewer.Editor`).

    python -m fpiwarp.viewer.examples.mglw_embed                  # a window (pyglet)
    python -m fpiwarp.viewer.examples.mglw_embed --frames 1 --screenshot out.png

With ``--screenshot`` and no ``--window``, it renders offscreen
(moderngl-window's headless window on EGL): no display needed.
Needs ``pip install moderngl-window``.
"""

import sys
from importlib import resources

import numpy as np

import fpiwarp

from .. import Editor, Renderer

try:
    import moderngl_window as mglw
except ImportError:  # pragma: no cover - reported by main()
    mglw = None


def sample_map(image):
    """The sample picture and a 4-point warp of its corners."""
    h, w = image.shape[:2]
    src = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    dst = [[0.1 * w, 0.08 * h], [0.92 * w, 0.0], [0.98 * w, 0.92 * h], [0.02 * w, 0.98 * h]]
    return fpiwarp.FPI(src, dst)


def make_app():
    class WarpApp(mglw.WindowConfig):
        gl_version = (3, 3)
        title = "fpiwarp in moderngl-window"
        window_size = (960, 720)
        aspect_ratio = None
        resizable = True

        @classmethod
        def add_arguments(cls, parser):
            parser.add_argument("--frames", type=int, default=None, help="render N frames, then exit")
            parser.add_argument("--screenshot", help="write the last frame to this PNG")

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
                image = fpiwarp.read_image(path)
            self.renderer = Renderer(self.ctx, background=(0.15, 0.15, 0.17, 1.0))
            self.renderer.handles = self.renderer.outline = True
            self.editor = Editor(self.renderer, image, sample_map(image))
            self.frames = 0

        def _gl(self, x, y):
            (bw, bh), (w, h) = self.wnd.buffer_size, self.wnd.size
            return x * bw / max(w, 1), (h - y) * bh / max(h, 1)

        def on_render(self, time, frame_time):
            self.ctx.clear(0.1, 0.1, 0.12, 1.0)
            self.renderer.draw(self.wnd.viewport)
            self.frames += 1
            if self.argv.frames is not None and self.frames >= self.argv.frames:
                if self.argv.screenshot:
                    w, h = self.wnd.buffer_size
                    data = self.wnd.fbo.read(viewport=(0, 0, w, h), components=3, alignment=1)
                    frame = np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1]
                    fpiwarp.write_image(self.argv.screenshot, frame, overwrite=True)
                self.wnd.close()

        def on_mouse_press_event(self, x, y, button):
            self.editor.press(self._gl(x, y), self.wnd.viewport)

        def on_mouse_drag_event(self, x, y, dx, dy):
            self.editor.move(self._gl(x, y), self.wnd.viewport)
            self.wnd.title = self.editor.title()

        def on_mouse_release_event(self, x, y, button):
            self.editor.release()

        def on_resize(self, width, height):
            self.renderer.fit()

    return WarpApp


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if mglw is None:
        print("mglw_embed: needs moderngl-window: pip install moderngl-window", file=sys.stderr)
        return 1
    if "--screenshot" in argv and not any(a in ("-wnd", "--window") for a in argv):
        argv += ["--window", "headless", "--backend", "egl"]
    try:
        mglw.run_window_config(make_app(), args=argv)
    except Exception as exc:  # noqa: BLE001 - no display, no GL: one line
        print(f"mglw_embed: cannot run: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
