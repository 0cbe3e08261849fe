"""The preview renderer under its historical name ``fpiwarp.gl``: see
:mod:`fpiwarp.viewer.renderer` (:class:`Renderer`) and
:mod:`fpiwarp.viewer.offscreen` (:func:`render_image`)."""

from .backends.gl.kinds import constant_dilation
from .viewer.offscreen import render_image
from .viewer.overlays import ACTIVE_COLOR, CONSTRAINED_COLOR, EDGE_COLOR, HANDLE_COLOR, RING_COLOR
from .viewer.renderer import METHODS, Renderer

__all__ = ["Renderer", "constant_dilation", "render_image",
           "ACTIVE_COLOR", "CONSTRAINED_COLOR", "EDGE_COLOR", "HANDLE_COLOR", "METHODS", "RING_COLOR"]
