"""Batches of point sets mapped in one transform-feedback pass per kind of map (GL).

The point sets of one kind of map go into one vertex buffer (float32, as
:meth:`GLWarper.map_points` sends one set) and their parameter blocks into
a shader storage buffer (as image batches: :mod:`.batch`); one pass of
``map_points.vert`` compiled with ``FPW_BATCH`` maps them all, vertex i
reading block ``i // P`` (or block 0 for one map shared by all). The
per-vertex code is the single set's, so each set's result equals
:meth:`GLWarper.map_points` of that set bit for bit. A pass holds at most
:data:`~.warper.POINT_CHUNK` points (at least one set) and as many blocks
as the storage buffer takes; larger groups are several passes. Drivers
without storage buffers map the sets one after the other.
"""

import moderngl
import numpy as np

from ... import glsl
from ...block.many import BlockStack
from .batch import BATCH_BINDING, kind_groups, supports_batches
from .context import bound_framebuffer
from .programs import MAX_ROWS, ProgramKey, set_uniform
from .warper import POINT_CHUNK


def sets_per_pass(warper, points_per_set):
    """How many point sets one pass maps (>= 1)."""
    storage = warper.ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE") or 1 << 24
    return max(1, min(POINT_CHUNK // max(points_per_set, 1), storage // (MAX_ROWS * 16)))


def map_points_batch(warper, blocks, points):
    """float64 (N, P, 2) point sets mapped by the maps whose parameter
    blocks are ``blocks`` (one for all, or one per set): float64 (N, P, 2)."""
    stack = BlockStack.from_blocks(blocks)
    n, p, _ = points.shape
    if n == 0 or p == 0:
        return np.empty(points.shape, np.float64)
    if not supports_batches(warper.ctx):
        blocks = stack.blocks()  # set by set
        maps = blocks * n if len(blocks) == 1 else blocks
        return np.stack([warper.map_points(_Block(b), s) for b, s in zip(maps, points, strict=True)])
    out = np.empty((n, p, 2), np.float32)
    flat = np.ascontiguousarray(points, dtype=np.float32)
    caller = bound_framebuffer(warper.ctx)
    if warper.targets.owns(caller):  # never leave a cached target bound (see GLWarper)
        caller = warper.targets.dummy
    warper.targets.dummy.use()  # without a bound framebuffer (surfaceless EGL) nothing is captured
    try:
        per = sets_per_pass(warper, p)
        for stages, _, _, idx, own in kind_groups(stack, n, warper.specialize):
            prog = warper.program(ProgramKey(glsl.MAP_POINTS_VERT, stages=stages, varyings=("fpw_mapped",),
                                             flags=("FPW_BATCH",)))
            storage = prog.get("FpiwarpBatch", None)
            if storage is not None:
                storage.binding = BATCH_BINDING
            set_uniform(prog, "fpw_batch_points", p)
            set_uniform(prog, "fpw_batch_step", 1 if own else 0)
            for a in range(0, len(idx), per):
                part = idx[a:a + per]
                _pass(warper, prog, stack.array[part] if own else stack.array[:1], flat[part], out, part)
    finally:
        caller.use()
    return out.astype(np.float64)


def _pass(warper, prog, blocks, points, out, idx):
    """One transform-feedback pass: ``points`` (m, P, 2) float32 of sets
    ``idx`` mapped into ``out[idx]`` by ``blocks`` (m or 1, rows, 4)."""
    ctx = warper.ctx
    stacked = np.zeros((len(blocks), MAX_ROWS, 4), np.float32)
    stacked[:, : blocks.shape[1]] = blocks
    ssbo = ctx.buffer(stacked.tobytes())
    vbo = ctx.buffer(points.tobytes())
    res = ctx.buffer(reserve=points.nbytes)
    vao = ctx.vertex_array(prog, [(vbo, "2f", "fpw_point")])
    try:
        ssbo.bind_to_storage_buffer(BATCH_BINDING)
        vao.transform(res, moderngl.POINTS, vertices=points.shape[0] * points.shape[1])
        out[idx] = np.frombuffer(res.read(), dtype=np.float32).reshape(points.shape)
    finally:
        for obj in (vao, vbo, res, ssbo):
            obj.release()


class _Block:
    """A parameter block as :meth:`GLWarper.map_points` takes a map."""

    def __init__(self, block):
        self.block = block

    def params(self):
        return self.block
