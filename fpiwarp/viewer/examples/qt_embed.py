"""Embed fpiwarp's preview renderer in a PySide6 ``QOpenGLWidget``.

Qt owns the window, the GL context and the event loop; in ``paintGL`` the
renderer draws the warped sample picture into the widget's framebuffer,
and mouse events drag the target points (through
:class:`fpiwarp.viewer.Editor`).

    python -m fpiwarp.viewer.examples.qt_embed                    # a window
    python -m fpiwarp.viewer.examples.qt_embed --frames 1 --screenshot out.png

Headless: ``QT_QPA_PLATFORM=offscreen`` with an X server for GLX (Xvfb);
Qt's offscreen platform has no OpenGL without one.
Needs ``pip install PySide6-Essentials``.
"""

import argparse
import sys

import numpy as np

import fpiwarp

from .. import Editor, Renderer


def _sample():
    from importlib import resources

    with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
        image = fpiwarp.read_image(path)
    h, w = image.shape[:2]
    src = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    dst = [[0.1 * w, 0.08 * h], [0.92 * w, 0.0], [0.98 * w, 0.92 * h], [0.02 * w, 0.98 * h]]
    return image, fpiwarp.FPI(src, dst)


def make_widget_class():
    import moderngl
    from PySide6.QtOpenGLWidgets import QOpenGLWidget

    class WarpWidget(QOpenGLWidget):
        """A widget showing a warp; drag the yellow points."""

        def __init__(self, image, transform, parent=None):
            super().__init__(parent)
            self.image, self.transform = image, transform
            self.ctx = self.renderer = self.editor = None
            self.error = None
            self.painted = 0

        def initializeGL(self):
            # Qt may give the widget a new context (re-parenting, grabbing on
            # some platforms): GL objects do not survive it, so build the
            # renderer again, keeping the map the user made.
            try:
                self.ctx = moderngl.create_context()  # Qt's context, current here
            except Exception as exc:  # noqa: BLE001 - reported by main()
                self.error = str(exc)
                return
            if self.editor is not None:
                self.transform = self.editor.transform
            self.renderer = Renderer(self.ctx, background=(0.15, 0.15, 0.17, 1.0))
            self.renderer.handles = self.renderer.outline = True
            self.editor = Editor(self.renderer, self.image, self.transform)

        def _viewport(self):
            r = self.devicePixelRatio()
            return (0, 0, int(self.width() * r), int(self.height() * r))

        def paintGL(self):
            if self.renderer is None:
                return
            fbo = self.ctx.detect_framebuffer(self.defaultFramebufferObject())
            fbo.use()
            self.ctx.clear(0.1, 0.1, 0.12, 1.0)
            self.renderer.draw(self._viewport())
            self.painted += 1

        def _gl(self, event):
            r = self.devicePixelRatio()
            p = event.position()
            return (p.x() * r, (self.height() - p.y()) * r)

        def mousePressEvent(self, event):
            self.editor.press(self._gl(event), self._viewport())
            self.update()

        def mouseMoveEvent(self, event):
            self.editor.move(self._gl(event), self._viewport())
            self.setWindowTitle(self.editor.title())
            self.update()

        def mouseReleaseEvent(self, event):
            self.editor.release()
            self.update()

        def resizeGL(self, w, h):
            if self.renderer is not None:
                self.renderer.fit()

    return WarpWidget


def main(argv=None):
    parser = argparse.ArgumentParser(description="fpiwarp in a PySide6 QOpenGLWidget")
    parser.add_argument("--frames", type=int, default=None, help="render N frames, then exit")
    parser.add_argument("--screenshot", help="write the last frame to this PNG")
    parser.add_argument("--size", default="960x720", help="widget size WxH")
    args = parser.parse_args(argv)
    try:
        from PySide6.QtGui import QSurfaceFormat
        from PySide6.QtWidgets import QApplication
    except ImportError:
        print("qt_embed: needs PySide6: pip install PySide6-Essentials", file=sys.stderr)
        return 1
    fmt = QSurfaceFormat()
    fmt.setVersion(3, 3)
    fmt.setProfile(QSurfaceFormat.OpenGLContextProfile.CoreProfile)
    QSurfaceFormat.setDefaultFormat(fmt)
    app = QApplication.instance() or QApplication([sys.argv[0]])
    image, transform = _sample()
    widget = make_widget_class()(image, transform)
    widget.setWindowTitle("fpiwarp in Qt")
    w, h = (int(v) for v in args.size.lower().split("x"))
    widget.resize(w, h)
    widget.show()
    if args.frames is None:
        return app.exec()
    frame = None
    for _ in range(max(args.frames, 1)):
        app.processEvents()
        qimage = widget.grabFramebuffer()  # renders a frame (paintGL) and reads it back
        if widget.error or widget.renderer is None:
            reason = widget.error or "no OpenGL context (Qt's offscreen platform needs an X server for GL)"
            print(f"qt_embed: cannot render: {' '.join(reason.split())}", file=sys.stderr)
            return 1
        frame = qimage
    if args.screenshot:
        qimage = frame.convertToFormat(frame.Format.Format_RGB888)
        width, height = qimage.width(), qimage.height()
        stride = qimage.bytesPerLine()
        buf = np.frombuffer(qimage.constBits(), np.uint8, count=stride * height).reshape(height, stride)
        rgb = buf[:, : width * 3].reshape(height, width, 3).copy()
        fpiwarp.write_image(args.screenshot, rgb, overwrite=True)
    widget.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
