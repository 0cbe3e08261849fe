"""GLSL shader sources of fpiwarp, installed as ``fpiwarp.glsl``; load them
through :func:`fpiwarp.resources.source`."""
