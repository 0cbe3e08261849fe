"""Examples of embedding :class:`fpiwarp.viewer.Renderer` in an application's
window: ``python -m fpiwarp.viewer.examples.qt_embed`` (PySide6 QOpenGLWidget)
and ``python -m fpiwarp.viewer.examples.mglw_embed`` (moderngl-window). Each
takes ``--frames N --screenshot OUT.png`` to render N frames, write the
last one and exit."""
