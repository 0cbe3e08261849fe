"""The source pyramid of antialiasing on GL: levels >= 1 in one float atlas.

Levels are those of :class:`fpiwarp.sampling.pyramid.Pyramid` (ceil sizes,
clamped 2×2 means), built on the host by the reference itself (float64,
stored as float32) and uploaded once as one float32 texture, the atlas:
level 1 at (0, 0), levels 2, 3, ... stacked in a column to its right. GL's
own mipmaps cannot hold them (floor sizes). The shader reads level k's
texels at ``fpw_levels[k].xy + (col, row)`` with texelFetch
(glsl/include/antialias.glsl); level 0 is the source texture itself.

Why the host: on a software rasterizer (llvmpipe) the GPU is the same CPU
cores, and numpy's halving of a 1080p picture costs about what a render
pass would (both far below one antialiased frame); the host build is the
reference's own arithmetic, needs no render-to-float-texture support and
no feedback loop (which WebGL2 forbids), and serves the browser page too.

:class:`PyramidCache` keeps the last few sources' atlases by the rule of
every backend (:class:`~fpiwarp.sampling.pyramid.SourcePyramids`): an
antialiased warp of the same pixels (another map, the next frame of an
animation, a batch with one source) reuses one. A host array is compared
with a copy of the pixels the atlas was built from, so a writeable array
changed in place gets a new atlas, never stale levels.

The option ``hardware_filter`` with antialiasing reads no atlas: the
texture unit filters the source's own mipmaps (GL's floor sizes, built by
the driver, ``build_mipmaps``), kept by the same rule
(:meth:`PyramidCache.mipmapped`): one normalized texture with its
mipmaps, uploaded and built once per source.
"""

import moderngl
import numpy as np

from ...block.sampling_rules import AA_MAX_LEVEL
from ...sampling.pyramid import Pyramid, SourcePyramids, level_sizes
from .programs import set_uniform

#: The texture unit the atlas is bound to (the source is on unit 0).
PYRAMID_UNIT = 2


def atlas_layout(height, width):
    """((atlas width, atlas height), [(x0, y0, w, h) of levels 0 .. top]):
    level 0's entry is the source's own size at (0, 0) (not in the atlas).

    >>> atlas_layout(5, 8)
    ((6, 3), [(0, 0, 8, 5), (0, 0, 4, 3), (4, 0, 2, 2), (4, 2, 1, 1)])
    """
    sizes = level_sizes(height, width)
    rects = [(0, 0, int(width), int(height))]
    if len(sizes) == 1:
        return (1, 1), rects
    h1, w1 = sizes[1]
    rects.append((0, 0, w1, h1))
    y = 0
    for h, w in sizes[2:]:
        rects.append((w1, y, w, h))
        y += h
    aw = w1 + (sizes[2][1] if len(sizes) > 2 else 0)
    return (aw, max(h1, y)), rects


def build_atlas(image, scale=1.0):
    """(atlas (H, W, C) float32, rects) of an (h, w, c) image (see
    :func:`atlas_layout`), its values divided by ``scale`` (a display
    texture's normalization)."""
    h, w, c = image.shape
    size, rects = atlas_layout(h, w)
    atlas = np.zeros((size[1], size[0], c), np.float32)
    levels = Pyramid(image).levels
    for (x0, y0, lw, lh), level in zip(rects[1:], levels[1:], strict=True):
        atlas[y0:y0 + lh, x0:x0 + lw] = level if scale == 1.0 else level / scale
    return atlas, rects


def set_pyramid_values(prog, rects):
    """The atlas uniforms of an antialiasing program (its texture bound to
    :data:`PYRAMID_UNIT`): each level's rectangle and the top level."""
    levels = list(rects) + [(0, 0, 1, 1)] * (AA_MAX_LEVEL + 1 - len(rects))
    member = prog.get("fpw_levels", None)
    if member is not None:
        member.write(np.asarray(levels[: member.array_length], np.int32).tobytes())
    set_uniform(prog, "fpw_aa_top", len(rects) - 1)
    set_uniform(prog, "fpw_pyramid", PYRAMID_UNIT)


def upload_atlas(ctx, atlas, tex=None):
    """A float32 texture holding ``atlas`` (``tex`` reused when its size
    and components match)."""
    h, w, c = atlas.shape
    if tex is None or tex.size != (w, h) or tex.components != c:
        if tex is not None:
            tex.release()
        tex = ctx.texture((w, h), c, dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    tex.write(np.ascontiguousarray(atlas))
    return tex


class PyramidCache:
    """The atlases of the last few sources antialiased in one context: the
    host part is :class:`~fpiwarp.sampling.pyramid.SourcePyramids` (every
    backend's one rule: reused while the pixels equal the copy kept with
    them), the texture is that of the atlas used last, uploaded once."""

    def __init__(self, ctx):
        self.ctx = ctx
        # (atlas array, rects) per source; clearing them (the backend's
        # host_pyramids) forgets the hardware filter's sources too
        self.atlases = SourcePyramids(build_atlas, on_clear=self.forget)
        self._uploaded = None  # the (atlas, rects) in the texture
        self._texture = None
        #: the hardware filter's sources: (kept pixels,) per source, by the same rule
        self.sources = SourcePyramids(lambda pixels: (pixels,))
        self._mip_uploaded = None  # the entry of self.sources in the mipmapped texture
        self._mip_texture = None

    @property
    def builds(self):
        """Atlases built so far (tests: reuse)."""
        return self.atlases.builds

    def host(self, image):
        """(atlas array, rects) for ``image``, built only when no kept
        atlas's pixels (shape, dtype, values) equal its."""
        return self.atlases.get(image)

    def texture(self, image):
        """(float32 atlas texture, rects) for ``image``, uploaded once per atlas."""
        entry = self.host(image)
        if self._uploaded is not entry:
            self._texture = upload_atlas(self.ctx, entry[0], self._texture)
            self._uploaded = entry
        return self._texture, entry[1]

    def mipmapped(self, image, dtype):
        """The texture of ``image`` as moderngl ``dtype`` (the hardware
        filter's normalized format) with its mipmaps, uploaded and built by
        the driver only when no kept source's pixels equal ``image``'s (the
        rule of :meth:`host`)."""
        entry = self.sources.get(image)
        if self._mip_uploaded is not entry:
            h, w, c = image.shape
            tex = self._mip_texture
            if tex is None or (tex.size, tex.components, tex.dtype) != ((w, h), c, dtype):
                if tex is not None:
                    tex.release()
                tex = self._mip_texture = self.ctx.texture((w, h), c, dtype=dtype)
            tex.write(np.ascontiguousarray(entry[0]))
            tex.build_mipmaps()
            self._mip_uploaded = entry
        return self._mip_texture

    def forget(self):
        """Forget the kept sources of the hardware filter and which atlas and
        source the textures hold (so that nothing keeps their host arrays);
        the textures stay for the next upload (any thread may call this;
        :meth:`release` frees them, in the context's thread)."""
        self._uploaded = self._mip_uploaded = None
        self.sources.clear()

    def release(self):
        """Free the textures and forget the atlases and sources."""
        for tex in (self._texture, self._mip_texture):
            if tex is not None:
                tex.release()
        self._texture = self._uploaded = self._mip_texture = self._mip_uploaded = None
        self.atlases.clear()
        self.sources.clear()
