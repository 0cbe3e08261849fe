"""The page's WebGL2 programs, assembled from the files in ``glsl/``.

The browser compiles the desktop preview's own shaders
(``glsl/backend/fullscreen.vert`` and ``glsl/viewer/preview.frag``, which
include the map, the sampler and the output of ``glsl/include/``) in the
GLSL ES 3.00 dialect of :func:`fpiwarp.glsl.assemble`: its ``#version 300
es`` preamble, then the block contract's constants from
:mod:`fpiwarp.block.codegen`, then the defines of the program's
:class:`~fpiwarp.backends.gl.ProgramKey`, the same key the desktop
renderer compiles. The page carries no shader text of its own.
"""

import functools

from .. import glsl
from ..backends.gl import FULLSCREEN, ProgramKey, fragment_defines, stage_kinds
from ..resources import digest

#: The dialect of the page's programs.
DIALECT = "es300"


def preview_key(block, *, order, mode, alpha, antialias=False):
    """The desktop renderer's per-pixel preview program for ``block``:
    specialised to its kind of map (a moved point changes values only);
    ``antialias``: over the display texture's pyramid (FPW_ANTIALIAS)."""
    flags = (("PV_ALPHA",) if alpha else ()) + (("FPW_ANTIALIAS",) if antialias else ())
    return ProgramKey(FULLSCREEN, glsl.PREVIEW_FRAG, stages=stage_kinds(block), order=order, mode=mode,
                      flags=flags)


def program_sources(key):
    """(vertex, fragment) GLSL ES 3.00 texts of ``key``: uniforms, not the
    flat varyings of the desktop's full-screen passes (GLSL ES 3.00 has no
    interface blocks between stages)."""
    return (glsl.assemble(key.vertex, key.defines(), dialect=DIALECT),
            glsl.assemble(key.fragment, fragment_defines(key), dialect=DIALECT))


@functools.lru_cache(maxsize=64)
def _program(key):
    vertex, fragment = program_sources(key)
    return {"key": digest(vertex, fragment), "vertex": vertex, "fragment": fragment}


def preview_program(block, *, order, mode, alpha, antialias=False):
    """{"key", "vertex", "fragment"} of the page's program for ``block``;
    "key" (a digest of the texts) names it: the page compiles each once."""
    return _program(preview_key(block, order=order, mode=mode, alpha=alpha, antialias=antialias))
