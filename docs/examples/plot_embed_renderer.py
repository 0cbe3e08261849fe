"""
Embedding the renderer in a Qt or moderngl-window app
=====================================================

:class:`fpiwarp.viewer.Renderer` draws the warp, with optional handles,
outline, checkerboard and distortion heat map, into *your* OpenGL
context: you own the window and the loop, and call ``set_image``,
``set_transform`` (values only, no recompilation when points move) and
``draw(viewport)``. Two complete applications ship with fpiwarp:

* ``python -m fpiwarp.viewer.examples.qt_embed``: a PySide6 ``QOpenGLWidget``
  (``pip install 'fpiwarp[preview,qt]'``);
* ``python -m fpiwarp.viewer.examples.mglw_embed``: a moderngl-window app
  (``pip install 'fpiwarp[preview]'``).

This page renders static screenshots headless (EGL), with no display.
"""

import subprocess
import sys
import tempfile
from importlib import resources
from pathlib import Path

import matplotlib.pyplot as plt

import fpiwarp
from fpiwarp.viewer import render_image
from fpiwarp.viewer.examples.mglw_embed import sample_map

with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    image = fpiwarp.read_image(path)

# %%
# The heart of both applications is a few calls on the renderer inside
# the toolkit's callbacks. In Qt, ``fpiwarp/viewer/examples/qt_embed.py``
# creates the renderer once the widget's context exists and draws it into
# the widget's framebuffer in ``paintGL``:
#
# .. literalinclude:: /../fpiwarp/viewer/examples/qt_embed.py
#    :language: python
#    :start-at: def initializeGL(self):
#    :end-before: def _gl(self, event):
#    :dedent: 8
#
# In moderngl-window, ``fpiwarp/viewer/examples/mglw_embed.py`` does the same in
# its ``WindowConfig``'s ``__init__`` and ``on_render``; the mouse goes to
# :class:`fpiwarp.viewer.Editor`, which moves the handles:
#
# .. literalinclude:: /../fpiwarp/viewer/examples/mglw_embed.py
#    :language: python
#    :start-at: def __init__(self, **kwargs):
#    :end-before: def _gl(self, x, y):
#    :dedent: 8
#
# .. literalinclude:: /../fpiwarp/viewer/examples/mglw_embed.py
#    :language: python
#    :start-at: def on_render(self, time, frame_time):
#    :end-before: def on_mouse_press_event
#    :dedent: 8
#
# A frame with the overlays, rendered offscreen by the same renderer on
# the "gl" backend's headless context:
f = sample_map(image)
frame = render_image(image, f, overlays=("handles", "outline", "heatmap"))

# %%
# The moderngl-window application itself, run headless for one frame
# (moderngl-window's EGL window) and its screenshot read back:
shot = Path(tempfile.mkdtemp()) / "mglw.png"
subprocess.run([sys.executable, "-m", "fpiwarp.viewer.examples.mglw_embed", "--frames", "1", "--screenshot", str(shot)],
               check=True, capture_output=True)
app_frame = fpiwarp.read_image(shot)

fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
axes[0].imshow(frame)
axes[0].set_title("Renderer with handles, outline, heat map")
axes[1].imshow(app_frame)
axes[1].set_title("fpiwarp.viewer.examples.mglw_embed, one frame")
for ax in axes:
    ax.set_axis_off()
fig.tight_layout()
plt.show()
