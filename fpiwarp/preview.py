"""The interactive viewer of ``fpiwarp preview`` under its historical
name: see :mod:`fpiwarp.viewer.app` (:class:`Editor`, :func:`run`)."""

from .viewer.app import INSTALL_HINT, OVERLAYS, PICK_RADIUS, Editor, max_distortion, run

__all__ = ["INSTALL_HINT", "OVERLAYS", "PICK_RADIUS", "Editor", "max_distortion", "run"]
