"""The split draw of a seeded per-pixel warp or preview (:mod:`.coarse`)
whose first stage has the Newton core and regions: a region pass over
the whole viewport, then the full program over the band only.

Mesa's llvmpipe runs the body of an ``if`` for every SIMD group of
fragments, under a mask, even where no fragment of the group takes it (a
loop's body at least once): every pixel that a region takes (80 % of the
benchmark's 1080p local deformation) ran the band's Newton code masked. So
the region pass is the same program with ``FPW_REGION_PASS``
(glsl/include/map.glsl), which returns at once where the seeded stage's
regions leave a pixel (it holds none of the Newton code), and the full
program is then drawn again, scissored to :func:`band_spans`: strips of
:data:`STRIP_ROWS` window rows, each over the columns where a pixel of the
strip may lie in no region. The spans are found on the host from the
block's regions (half-planes of the stage's input, which is the output
position, an affine function of the window pixel), widened by
:data:`MARGIN` of the depths so that every pixel outside them is in a
region in the shader's float32 arithmetic too; there both programs run the
same code (the region's similarity, then the later stages), so the output
is that of the single draw, bit for bit.
"""

import math

import moderngl
import numpy as np

from ... import block as P
from ...block.layout import NEWTON_CORES
from .programs import set_uniform

#: The define of the region pass.
FLAG = "FPW_REGION_PASS"
#: Window rows per span of the band's draw (one scissored draw each).
STRIP_ROWS = 32
#: Relative margin of a region's depth (float32 rounding of the output
#: position and the depth is below 1e-6 of these magnitudes).
MARGIN = 1e-4


def applies(kind):
    """Whether a draw of a block of kind ``kind`` (a
    :class:`fpiwarp.block.describe.BlockKind`) splits: its first stage has
    a Newton core and at least one region."""
    stages = kind.stages
    return bool(stages) and stages[0].core in NEWTON_CORES and stages[0].n_regions > 0


def split(warper, key, prog, draw):
    """``draw`` (a draw by ``prog``, the program of ``key``, of the block
    last uploaded to ``warper``) as a split draw (:func:`split_draw`) where
    the block's kind splits and ``key`` is specialized to it; else ``draw``."""
    if key.stages is None or not applies(warper.block_kind):
        return draw
    regions = warper.program(key.with_changes(flags=key.flags + (FLAG,)))
    block, kind = warper.block, warper.block_kind
    return lambda: split_draw(warper, regions, prog, block, kind, draw)


def band_spans(block, kind, view, viewport, strip=STRIP_ROWS):
    """Window rectangles (x, y, w, h) covering every pixel of ``viewport``
    (x, y, w, h) that the first stage's regions of ``block`` (of kind
    ``kind``, where :func:`applies`) may leave,
    for a draw whose output position is ``view.xy + view.zw * (pixel -
    0.5)`` (``fpw_view``, pixel centers at +0.5): one per strip of
    ``strip`` rows that has such pixels. None where the view or the
    regions are not finite (then nothing is split)."""
    x0, y0, w, h = (int(v) for v in viewport)
    vx, vy, vz, vw = (float(v) for v in view)
    rows = np.asarray(block, dtype=np.float64)[1 + P.ROW_REGIONS:][: 2 * kind.stages[0].n_regions:2]
    if not (np.isfinite(rows).all() and all(map(math.isfinite, (vx, vy, vz, vw)))):
        return None
    # output positions of pixel (i, j): (vx + vz i, vy + vw j), i, j window pixels
    reach = max(abs(vx), abs(vx + vz * (x0 + w)), abs(vy), abs(vy + vw * (y0 + h)))
    j = np.arange(y0, y0 + h, dtype=np.float64)
    lo = np.full(h, float(x0))
    hi = np.full(h, float(x0 + w - 1))
    for ox, oy, nx, ny in rows:
        # depth = a i + b_j; the pixel may be outside the region where depth <= m
        m = MARGIN * (reach + math.hypot(ox, oy) + 1.0) * math.hypot(nx, ny)
        a = vz * nx
        b = (vx - ox) * nx + (vy + vw * j - oy) * ny
        if a > 0:
            hi = np.minimum(hi, np.floor((m - b) / a) + 1)
        elif a < 0:
            lo = np.maximum(lo, np.ceil((m - b) / a) - 1)
        else:
            hi = np.where(b > m, -np.inf, hi)
    lo, hi = np.maximum(lo, x0), np.minimum(hi, x0 + w - 1)
    spans = []
    for k in range(0, h, strip):
        keep = lo[k:k + strip] <= hi[k:k + strip]
        if keep.any():
            a, b = int(lo[k:k + strip][keep].min()), int(hi[k:k + strip][keep].max())
            spans.append((a, y0 + k, b - a + 1, min(strip, h - k)))
    return spans


def copy_uniforms(src, dst):
    """Set each uniform of ``dst`` that ``src`` has to ``src``'s value."""
    for name in src:
        member = src[name]
        if isinstance(member, moderngl.Uniform) and dst.get(name, None) is not None:
            set_uniform(dst, name, member.value)


def split_draw(warper, regions, prog, block, kind, draw):
    """A draw by ``prog`` (a seeded program over the bound viewport, its
    uniforms set) made of the region pass ``regions`` (its program with
    :data:`FLAG`) over the viewport and ``draw`` scissored to the band's
    spans (within the caller's scissor box, which is set again after); the
    plain ``draw`` where there are none to find."""
    ctx = warper.ctx
    spans = band_spans(block, kind, prog["fpw_view"].value, ctx.viewport)
    if spans is None:
        draw()
        return
    copy_uniforms(prog, regions)
    warper.fullscreen_vao(regions).render(moderngl.TRIANGLES, vertices=3)
    caller = tuple(ctx.scissor)  # the framebuffer's box where the test is off
    cx0, cy0, cx1, cy1 = caller[0], caller[1], caller[0] + caller[2], caller[1] + caller[3]
    try:
        for x, y, w, h in spans:
            x1, y1 = min(x + w, cx1), min(y + h, cy1)
            x, y = max(x, cx0), max(y, cy0)
            if x < x1 and y < y1:
                ctx.scissor = (x, y, x1 - x, y1 - y)
                draw()
    finally:
        ctx.scissor = None if caller == (0, 0) + tuple(ctx.fbo.size) else caller
