"""The "gl" backend: GLSL shaders through moderngl, headless through EGL.

Three paths share one shader include (``glsl/include/fpiwarp.glsl``), which
mirrors :func:`fpiwarp.block.evaluate` and :mod:`fpiwarp.sampling.sampler`:

* ``map_points``: a vertex shader evaluates the parameter block per point,
  captured by transform feedback;
* ``warp_image``: a full-screen fragment shader evaluates the block of
  ``transform.inverse`` per output pixel and samples the source in
  software (``texelFetch`` of unfiltered texels, float weights; uint16 as
  an integer texture, uint8 as a normalized one scaled back by 255, the
  fastest format of software rasterizers), rounding in the shader into an
  integer framebuffer, so results match the numpy reference;
  ``hardware_filter=True`` lets the texture unit filter instead (GL
  quantizes the weights); with ``antialias=True`` too, the texture unit
  filters the footprint, trilinear over the source's mipmaps by
  textureGrad (see :doc:`/guides/antialiasing`). What makes it fast on Mesa's llvmpipe, which
  runs it on the CPU: per-draw values reach the fragment stage as flat
  varyings rather than uniforms (listed once, in ``glsl/include/per_draw.glsl``), order 1 reads one textureGather per
  channel instead of a texelFetch per tap, and 3-channel pictures come
  back as packed RGB32UI texels;
* :func:`warp_image_mesh`: the paper's own way, a triangulated grid of the
  source deformed per vertex by the forward map and rasterized with
  texture mapping (no inverse needed).

Threads. An OpenGL context is current in one thread only, so the
backend's shared context belongs to the thread that first used the
backend (which created it); calls from other threads raise RuntimeError.
:func:`release_shared_context`, called in the owning thread, frees it:
the next thread that uses the backend then owns a new one.
:func:`claim_shared_context` makes the calling thread the owner up front.
A :class:`GLWarper` in a context of your own follows that context's rules.

Modules, one job each:

* :mod:`.context`  the shared context, its owning thread, :func:`probe`;
* :mod:`.kinds`    what a parameter block's kind of map is;
* :mod:`.programs` shader assembly, :class:`ProgramKey`, the program cache;
* :mod:`.warper`   :class:`GLWarper`: map points, warp per pixel and by mesh;
* :mod:`.tiling`   sources and outputs above the texture size limit;
* :mod:`.readback` reading pixels back, packed RGB;
* :mod:`.mesh`     the mesh path's grid and its culled, clipped draw;
* :mod:`.targets`  textures and framebuffers reused between calls;
* :mod:`.backend`  the registry's :class:`Backend`, :func:`warp_image_mesh`;
"""

from .backend import Backend, warp_image_mesh
from .context import (
    GL_REQUIRE,
    bound_framebuffer,
    check_thread,
    claim_shared_context,
    create_context,
    owner_thread,
    probe,
    release_shared_context,
    shared_context,
    usable_here,
)
from .mesh import GL_CLIP_DISTANCE0, MeshBuffers, draw_culled_mesh, grid_mesh
from .programs import (
    FULLSCREEN,
    HOT_ROWS,
    MAX_PER_DRAW,
    MAX_ROWS,
    ProgramCache,
    ProgramKey,
    flat_value_sources,
    fragment_defines,
    map_kind,
    set_uniform,
    shader_source,
    stage_kinds,
    stages_define,
)
from .readback import renders_rgb32ui
from .warper import POINT_CHUNK, GLWarper

__all__ = [
    "FULLSCREEN", "GL_CLIP_DISTANCE0", "GL_REQUIRE", "HOT_ROWS", "MAX_PER_DRAW", "MAX_ROWS", "POINT_CHUNK",
    "Backend", "GLWarper", "MeshBuffers", "ProgramCache", "ProgramKey",
    "bound_framebuffer", "check_thread", "claim_shared_context",
    "create_context", "draw_culled_mesh", "flat_value_sources", "fragment_defines",
    "grid_mesh", "map_kind", "owner_thread", "probe", "release_shared_context",
    "renders_rgb32ui", "set_uniform", "shader_source", "shared_context", "stage_kinds", "stages_define",
    "usable_here", "warp_image_mesh",
]
