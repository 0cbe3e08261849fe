"""Sources and outputs larger than the maximum texture size.

Outputs are rendered one viewport-sized tile at a time (:func:`tiles`).
A source above the limit is split into texture-sized tiles, and each
output tile sums one additive pass per source tile into a float32
accumulator: each tap belongs to exactly one tile, and the primary pass
adds cval where the reference uses it, exactly once (FPW_TILED in
glsl/include/sample.glsl). The sum is rounded on the host, so there is no
size limit.
"""

import moderngl
import numpy as np

from ...sampling.sampler import to_dtype
from .programs import set_uniform
from .pyramid import PYRAMID_UNIT

#: Texture formats of the software sampler's source, by image dtype:
#: uint8 normalized (fastest on software rasterizers, scaled back by 255 in
#: the shader), uint16 as an integer texture (exact), float32 as is.
SOURCE_TEXTURE_DTYPES = {np.dtype(np.uint8): "f1", np.dtype(np.uint16): "u2", np.dtype(np.float32): "f4"}


def tiles(n, size):
    """[a, b) ranges of at most ``size`` covering range(n)."""
    return [(a, min(n, a + size)) for a in range(0, n, size)]


def _grid(h, w, size_limit):
    """(x0, y0, x1, y1) of the texture-sized tiles of an h × w picture."""
    return [(x0, y0, x1, y1) for y0, y1 in tiles(h, size_limit) for x0, x1 in tiles(w, size_limit)]


def _write_tile(tex, picture, grid, i):
    """Write tile i of ``grid`` of ``picture`` into ``tex``: its (x0, y0,
    w, h), or an empty tile past the grid's end (nothing to read)."""
    if i >= len(grid):
        return (0, 0, 0, 0)
    x0, y0, x1, y1 = grid[i]
    tex.write(np.ascontiguousarray(picture[y0:y1, x0:x1]), viewport=(0, 0, x1 - x0, y1 - y0))
    return (x0, y0, x1 - x0, y1 - y0)


def render_tiled_source(warper, image, out, prog, draw, cval, covers, atlas=None):
    """Warp a source above the size limit into ``out``: per output tile,
    sum one additive pass per source tile into float32, then round on the
    host. ``draw()`` draws ``prog`` once; ``covers``: ``prog`` marks the
    pixels it covers (the mesh path), the others get ``cval``. ``atlas``:
    the antialiasing pyramid's levels >= 1 (:mod:`.pyramid`), tiled alike:
    pass i holds source tile i and atlas tile i (either may be empty)."""
    ctx, size_limit = warper.ctx, warper.max_size
    h, w, c = image.shape
    oh, ow = out.shape[:2]
    full = (min(ow, size_limit), min(oh, size_limit))
    fbo = warper.targets.target("acc", full, 4, "f4", cover=covers)
    src_tiles = _grid(h, w, size_limit)
    atlas_tiles = [] if atlas is None else _grid(atlas.shape[0], atlas.shape[1], size_limit)
    passes = max(len(src_tiles), len(atlas_tiles))
    dt = SOURCE_TEXTURE_DTYPES[image.dtype]
    for oy0, oy1 in tiles(oh, size_limit):
        for ox0, ox1 in tiles(ow, size_limit):
            size = (ox1 - ox0, oy1 - oy0)
            fbo.viewport = (0, 0) + size
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0)
            warper.set_view((prog,), (ox0, oy0), size)
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            ctx.blend_equation = moderngl.FUNC_ADD
            tex = warper.targets.texture("src_tile", (size_limit, size_limit), c, dt)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.use(0)
            if atlas is not None:
                atlas_tex = warper.targets.texture("pyramid_tile", (size_limit, size_limit), c, "f4")
                atlas_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
                atlas_tex.use(PYRAMID_UNIT)
            for i in range(passes):
                set_uniform(prog, "fpw_tile", _write_tile(tex, image, src_tiles, i))
                if atlas is not None:
                    set_uniform(prog, "fpw_pyramid_tile", _write_tile(atlas_tex, atlas, atlas_tiles, i))
                set_uniform(prog, "fpw_primary", 1 if i == 0 else 0)
                draw()
            ctx.disable(moderngl.BLEND)
            vp = (0, 0) + size
            acc = np.frombuffer(fbo.read(viewport=vp, components=4, dtype="f4"), np.float32)
            acc = acc.reshape(size[1], size[0], 4)[..., :c].astype(np.float64)
            if covers:
                cover = np.frombuffer(fbo.read(viewport=vp, components=1, dtype="f4", attachment=1),
                                      np.float32).reshape(size[1], size[0], 1)
                acc = np.where(cover > 0, acc, cval)
            out[oy0:oy1, ox0:ox1] = to_dtype(acc, image.dtype)
