"""The coarse pass of a per-pixel warp or preview of a map with a Newton
core, on GL (the reference: :mod:`fpiwarp.block.coarse`).

Before a per-pixel draw whose program has the ``FPW_COARSE`` flag
(glsl/include/map.glsl) :func:`prepare` renders glsl/backend/coarse.frag
into two RGBA32F targets of one texel per node (x and a; b), nodes
``COARSE_STEP`` window pixels apart from the draw's viewport corner, and
binds them for the draw (texture units :data:`UNITS`). Each fragment of
the draw then seeds the block's first Newton stage from its four nodes.
A warp_image output of one tile has the reference's nodes exactly; a
tiled output's nodes start again at each tile's corner (tiles are the
driver's size limit apart). A batch's instanced draw (:mod:`.batch`) is
preceded by one instanced draw of the nodes of all its images (image k's
in texel rows [k ny, (k + 1) ny) of targets ny times as tall), so each
image is seeded as its single warp is. Antialiased programs solve per
pixel, as the OpenCL backend does.
"""

import moderngl

from ... import glsl
from ...block.coarse import coarse_shape
from ...block.coarse_choice import takes_coarse_pass
from .context import bound_framebuffer
from .programs import FULLSCREEN, ProgramKey, set_uniform

#: False: every pixel solves alone (read per draw: benchmarks compare the two);
#: True: a warp takes the pass where the block's rule picks it
#: (:func:`picks`, fpiwarp/block/coarse_choice.py).
COARSE_PASS = True
#: The define of a per-pixel program seeded by the pass.
FLAG = "FPW_COARSE"
#: Texture units of the node records (x and a; b): clear of the source
#: (0), the packing pass's input (1) and the antialiasing pyramid's.
UNITS = (6, 7)


def flags(newton_map, antialias=False):
    """The program flags of a per-pixel draw: (FLAG,) for a map with a
    Newton core (``newton_map``), without antialiasing, while COARSE_PASS."""
    return (FLAG,) if COARSE_PASS and newton_map and not antialias else ()


def picks(block, output_shape, batch=False):
    """Whether a warp of ``block`` (a Newton map's float32 block) to
    ``output_shape`` (rows, cols) takes the pass, by the block's rule for
    this backend (``takes_coarse_pass``): :func:`flags`' ``newton_map``
    is its answer and the map's having a Newton core. The preview
    (fpiwarp.viewer) does not ask: its nodes lie in window pixels under a
    view that zooms. ``batch``: for a batch's draw, which is not split
    (:mod:`.band`), by the rule's "gl batch" break-even."""
    return takes_coarse_pass(block, output_shape[1], output_shape[0], "gl batch" if batch else "gl")


def chosen(warper, output_shape):
    """Whether a warp of the block last uploaded to ``warper`` (its
    ``set_map``) to ``output_shape`` takes the pass: a Newton map, while
    COARSE_PASS, where :func:`picks` chooses it (asked only then: the
    choice estimates on the host)."""
    return warper.newton_map and COARSE_PASS and picks(warper.block, output_shape)


def node_key(stages):
    """The program key of the nodes' pass for a block of kind ``stages``."""
    return ProgramKey(FULLSCREEN, glsl.COARSE_FRAG, stages=stages, samples=False, flags=("FPW_COARSE_PASS",))


def prepare(warper, prog, stages, view, viewport, batch=None):
    """Render the nodes of a draw by ``prog`` (a program with FLAG) over
    ``viewport`` (x, y, w, h window pixels) with ``fpw_view`` ``view``, for
    a block of kind ``stages`` uploaded to ``warper``; bind them for the
    draw. The caller's framebuffer and viewport are bound again after.
    ``batch``: (the nodes' program compiled for batches, the draw's image
    count, its block step) of an instanced batch draw (:mod:`.batch`)
    whose images are ``viewport``'s size each, blocks in its storage buffer."""
    ctx = warper.ctx
    x0, y0, w, h = (int(v) for v in viewport)
    ny, nx = coarse_shape(w, h)
    node, count, step = batch or (warper.program(node_key(stages)), 1, 0)
    caller, caller_viewport = bound_framebuffer(ctx), ctx.viewport
    fbo = warper.targets.cached("coarse", (nx, ny * count), lambda: ctx.framebuffer(
        color_attachments=[ctx.texture((nx, ny * count), 4, dtype="f4") for _ in UNITS]))
    vx, vy, vz, vw = (float(v) for v in view)
    set_uniform(node, "fpw_view", (vx + vz * x0, vy + vw * y0, vz, vw))
    fbo.use()  # its viewport: (0, 0, nx, ny * count)
    if batch is None:
        warper.fullscreen_vao(node).render(moderngl.TRIANGLES, vertices=3)
    else:  # instance k: image k's rows of nodes, block k * step (fullscreen.vert)
        set_uniform(node, "fpw_batch_rows", ny)
        set_uniform(node, "fpw_batch_count", count)
        set_uniform(node, "fpw_batch_step", step)
        set_uniform(prog, "fpw_coarse_rows", ny)
        warper.fullscreen_vao(node).render(moderngl.TRIANGLES, vertices=6, instances=count)
    caller.use()
    ctx.viewport = caller_viewport
    for unit, tex in zip(UNITS, fbo.color_attachments):
        tex.use(unit)
    set_uniform(prog, "fpw_coarse_xa", UNITS[0])
    set_uniform(prog, "fpw_coarse_b", UNITS[1])
    set_uniform(prog, "fpw_coarse_origin", (x0, y0))


def seeded_draw(warper, prog, stages, draw, batch=None):
    """``draw`` (a warp_image tile's draw by ``prog``) preceded by the
    coarse pass of the tile: its view read back from ``prog``, its size the
    viewport the caller set (``batch``, as :func:`prepare` takes it: the
    viewport holds its images one above the other)."""
    def run():
        w, h = warper.ctx.viewport[2:]
        prepare(warper, prog, stages, prog["fpw_view"].value, (0, 0, w, h // (batch[1] if batch else 1)), batch)
        draw()
    return run
