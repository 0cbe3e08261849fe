"""The real-time preview: a renderer for a caller's OpenGL context and
the interactive viewer of ``fpiwarp preview``.

* :mod:`.renderer`  :class:`Renderer`, the warp drawn into a caller's
  framebuffer (per pixel or by the backend's mesh path), with overlays;
* :mod:`.overlays`  handles and outlines as flat-coloured triangles;
* :mod:`.offscreen` :func:`render_image`, one frame read back as an image;
* :mod:`.app`       :class:`Editor` (the viewer's logic, no window) and
  :func:`run` (the window).

Built on the "gl" backend (:mod:`fpiwarp.backends.gl`), whose programs,
mesh path and thread rules it shares. :mod:`.examples` embeds the
renderer in a Qt and a moderngl-window application.
"""

from .app import Editor, max_distortion, run
from .offscreen import render_image
from .overlays import ACTIVE_COLOR, CONSTRAINED_COLOR, EDGE_COLOR, HANDLE_COLOR, RING_COLOR
from .renderer import METHODS, Renderer

__all__ = [
    "ACTIVE_COLOR", "CONSTRAINED_COLOR", "EDGE_COLOR", "HANDLE_COLOR", "METHODS", "RING_COLOR",
    "Editor", "Renderer", "max_distortion", "render_image", "run",
]
