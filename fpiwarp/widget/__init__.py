"""The editor in the browser: a notebook widget and a local page.

* :class:`WarpWidget` (:mod:`.notebook`)  the anywidget of JupyterLab,
  Notebook 7, VS Code and marimo;
* :mod:`.server`   the page of ``fpiwarp preview IMAGE --web``, served on
  127.0.0.1 with a token;
* :mod:`.session`  the Python half of both: the map built from the handles
  and edges with the desktop viewer's :class:`~fpiwarp.viewer.Editor`, the
  parameter block and the display texture;
* :mod:`.shaders`  the page's WebGL2 programs, assembled from ``glsl/``;
* :mod:`.browser`  headless Chromium (screenshots, tests, benchmarks);
* ``static/``      the page's script (WebGL2 plumbing, overlays, input;
  no map and no sampler), its HTML and style.
"""

__all__ = ["WarpWidget"]


def __getattr__(name):
    if name == "WarpWidget":  # anywidget only when the widget is asked for
        from .notebook import WarpWidget

        return WarpWidget
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
