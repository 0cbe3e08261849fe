"""A stack of images warped in one instanced draw per kind of map (GL).

The N sources go into a 2D texture array (one layer each) and the N
parameter blocks into a shader storage buffer, one block per
:data:`MAX_ROWS` vec4 rows (N blocks do not fit one uniform block). One
instanced draw of the warp program compiled with ``FPW_BATCH`` renders
all N outputs into one tall framebuffer: instance k covers rows
[k * rows, (k + 1) * rows), samples layer k and evaluates block k (or
block 0 for one map shared by all; glsl/include/batch.glsl). The per-pixel code
is the single image's, line for line (only the accessor of the block and
the texture coordinates differ), so the batch equals the loop of
:meth:`GLWarper.warp_block` bit for bit, and the atlas reads back as
consecutive (rows, cols, C) images.

Programs are specialised per kind of map (as for one image), so maps are
grouped by kind: a group is one draw (N FPIs: one draw; k kinds: k draws).
A draw holds at most as many images as fit the size limit of the target
(``max_size // rows``), the texture array's layers, the storage buffer's
size and :data:`CHUNK_BYTES` (:data:`SOFTWARE_CHUNK_BYTES` on a software
rasterizer such as llvmpipe, where a draw that exceeds the caches is slower
than single warps); larger groups are several draws, never refused.
A draw of one image samples a 2D texture, as the single image does, not a
layer of an array (FPW_BATCH_SINGLE, glsl/include/sample.glsl): llvmpipe
samples arrays about 13% slower per pixel, which made batches of draws of
one image (512² RGB uint8 and up) slower than the loop. So a software
rasterizer draws each image alone from :data:`SOFTWARE_ALONE_BYTES` of
source and output on (about 157² RGB uint8), where the 2D texture gains
more than fewer draws would.
Outputs wider than the size limit are drawn in column tiles, as for one
image. Sources beyond the size limit (the single-image path
tiles those) and drivers without shader storage buffers go image by
image.

Maps with a Newton core take the coarse pass as their single warps do
(:mod:`.coarse`): before each draw (and column tile) one instanced draw
solves the nodes of all its images, image k's from block k, and the
warp's instance k seeds its pixels from them; the maps are grouped by
whether they have a Newton core (without specializing too).
"""

import moderngl
import numpy as np

from ...block import describe
from ...block.coarse import coarse_shape, newton_stage
from ...block.many import BlockStack
from . import band, coarse
from .context import bound_framebuffer, software_rasterizer
from .programs import MAX_ROWS, set_uniform
from .tiling import SOURCE_TEXTURE_DTYPES, tiles

#: Bytes of source and output pixels in one draw, at most (at least one image).
CHUNK_BYTES = 256 << 20
#: Bytes of one draw on a software rasterizer (Mesa llvmpipe, softpipe,
#: SwiftShader), at most (at least one image): the CPU renders, and a
#: draw whose sources and target exceed the caches runs slower. 64 x 512²
#: RGB uint8, 64 FPIs, llvmpipe 22.3 on 2 busy cores, best of 5
#: interleaved (draws held arrays then): the loop 151 ms, draws of 2 MiB
#: 163 ms, 4 MiB 187 ms, 16 MiB 243 ms, 64 MiB 270 ms, 256 MiB 192 ms. From
#: 64 x 128² (16 images a draw): 2 MiB 10.4 ms CPU, 1 MiB 10.9, 512 KiB
#: 11.0, one image a draw 12.3, the loop 17.1.
SOFTWARE_CHUNK_BYTES = 2 << 20
#: Bytes of one image's source and output (counted as for the chunks) from
#: which a software rasterizer draws each image alone, its source in a 2D
#: texture, not a layer of an array (see the module's docstring). CPU time,
#: 64 images RGB uint8, 64 FPIs, best of 9 interleaved, same llvmpipe:
#: 144² (162 KiB) 2 MiB draws 13.3 ms, alone 14.7; 160² (200 KiB) 17.6,
#: 17.3; 181² (256 KiB) 27.7, 23.0; 256² (512 KiB) 39.1, 34.0.
SOFTWARE_ALONE_BYTES = 192 << 10
#: Shader storage binding point of the stacked blocks.
BATCH_BINDING = 0
#: A draw of one image samples a 2D texture (FPW_BATCH_SINGLE), not a
#: layer of a texture array (read per call: False for benchmarks comparing the two).
SINGLE_SOURCE_TEXTURE = True


def supports_batches(ctx):
    """Whether the context reads storage buffers in both shader stages."""
    info = ctx.info
    return ("GL_ARB_shader_storage_buffer_object" in ctx.extensions
            and (info.get("GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS") or 0) > 0
            and (info.get("GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS") or 0) > 0)


def kind_groups(stack, n, specialize, by_newton=False):
    """[(stages, is_short, has a Newton core, indices of the images,
    whether each has its own block)]: the images grouped by the kind of
    their map (when not specializing: one group, or by whether the map has
    a Newton core where ``by_newton``, else that is None; one group for
    one map shared by all ``n`` images).
    ``stack``: a :class:`~fpiwarp.block.many.BlockStack`, each distinct kind
    described once."""
    def key(kind):  # (each stage's core and region count, short map, Newton) when specializing
        return (tuple((s.core, s.n_regions) for s in kind.stages) if specialize else None,
                specialize and kind.is_short, newton_stage(kind) is not None if specialize or by_newton else None)

    if len(stack) == 1:
        return [(*key(describe(stack.array[0, : stack.rows[0]])), np.arange(n), False)]
    return [(*k, idx.astype(np.intp), True) for k, idx in stack.groups(key)]


def by_choice(groups, stack, output_shape):
    """:func:`kind_groups`' groups split by whether their maps take the
    coarse pass to ``output_shape`` (:func:`.coarse.picks`, per map as
    their single warps): (..., own, seeded), the maps taking it first."""
    for stages, short, newton, idx, own in groups:
        if not (newton and coarse.COARSE_PASS):
            yield stages, short, newton, idx, own, False
            continue
        blocks = [stack.array[k, : stack.rows[k]] for k in (idx if own else [0])]
        picked = np.array([coarse.picks(b, output_shape, batch=True) for b in blocks], bool)
        if not own:
            yield stages, short, newton, idx, own, bool(picked[0])
            continue
        for choice in (True, False):
            if (picked == choice).any():
                yield stages, short, newton, idx[picked == choice], own, choice


def batch_program(warper, key, single=False):
    """The program of ``key`` compiled for batches (FPW_BATCH), its blocks'
    storage buffer at :data:`BATCH_BINDING`; ``single``: for draws of one
    image, its source a 2D texture (FPW_BATCH_SINGLE)."""
    flags = ("FPW_BATCH",) + (("FPW_BATCH_SINGLE",) if single else ())
    prog = warper.program(key.with_changes(flags=key.flags + flags))
    storage = prog.get("FpiwarpBatch", None)
    if storage is not None:
        storage.binding = BATCH_BINDING
    return prog


def images_per_draw(warper, image_shape, output_shape, itemsize, seeded=False):
    """How many images one draw holds (>= 1; see the module's docstring);
    ``seeded``: the draw takes the coarse pass (its nodes' targets are
    within the size limit too)."""
    (h, w, _), (oh, ow) = image_shape, output_shape
    info = warper.ctx.info
    per_image = (h * w + oh * ow) * 4 * itemsize
    software = software_rasterizer(warper.ctx)
    if software and per_image >= SOFTWARE_ALONE_BYTES:
        return 1
    chunk = SOFTWARE_CHUNK_BYTES if software else CHUNK_BYTES
    limits = [warper.max_size // oh, info.get("GL_MAX_ARRAY_TEXTURE_LAYERS") or 256, chunk // per_image,
              (info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE") or 1 << 24) // (MAX_ROWS * 16)]
    if seeded:
        limits.append(warper.max_size // coarse_shape(min(ow, warper.max_size), oh)[0])
    return max(1, min(limits))


def warp_batch(warper, stack, blocks, output_shape, *, order, mode, cval, antialias=False):
    """An (N, H, W, C) stack warped by the maps from output to source
    whose parameter blocks are ``blocks`` (one for all or one per image, a
    list or a :class:`~fpiwarp.block.many.BlockStack`):
    (N, rows, cols, C), equal to the loop of ``warper.warp_block``."""
    stack = np.ascontiguousarray(stack)
    n, h, w, c = stack.shape
    oh, ow = (int(v) for v in output_shape)
    stack_of_blocks = BlockStack.from_blocks(blocks)
    cval = np.zeros(c) if cval is None else np.broadcast_to(np.asarray(cval, np.float64), (c,))
    if (h > warper.max_size or w > warper.max_size or oh > warper.max_size or not supports_batches(warper.ctx)
            or antialias):
        # image by image (antialiased too: each source's pyramid is built once, see GLWarper.pyramids)
        blocks = stack_of_blocks.blocks()
        maps = blocks * n if len(blocks) == 1 else blocks
        return np.stack([warper.warp_block(stack[i], maps[i], (oh, ow), order=order, mode=mode, cval=cval,
                                           antialias=antialias) for i in range(n)])
    out = np.empty((n, oh, ow, c), dtype=stack.dtype)
    caller = bound_framebuffer(warper.ctx)
    if warper.targets.owns(caller):  # never leave a cached target bound (see GLWarper)
        caller = warper.targets.dummy
    try:
        groups = kind_groups(stack_of_blocks, n, warper.specialize, by_newton=True)
        single = stack_of_blocks.blocks()  # each map's block alone (views), for the maps drawn image by image
        for stages, short, newton, idx, own, seeded in by_choice(groups, stack_of_blocks, (oh, ow)):
            if seeded and splits(single[idx[0] if own else 0]):
                # the single warp's split draw (band.py), which the instanced draw lacks: image by image
                for i in idx:
                    warper.warp_block(stack[i], single[i if own else 0], (oh, ow), order=order, mode=mode, cval=cval,
                                      out=out[i])
                continue
            warper.short_map, warper.newton_map = short, newton  # as set_map sets them for one of the maps
            key, packs = warper.warp_program_key(stack[0], order, mode, stages, antialias, seeded=seeded)
            seeded = coarse.FLAG in key.flags
            per_draw = images_per_draw(warper, (h, w, c), (oh, ow), stack.dtype.itemsize, seeded)
            draws = -(-len(idx) // per_draw)
            size = -(-len(idx) // draws)  # draws of equal size: one texture and target for all
            prog = batch_program(warper, key, single=size == 1 and SINGLE_SOURCE_TEXTURE)
            nodes = (batch_program(warper, coarse.node_key(stages)), stages) if seeded else None
            set_sampling_values(prog, stack, (oh, ow), cval, own)
            for a in range(0, len(idx), size):
                draw_group(warper, prog, stack, stack_of_blocks.array, idx[a:a + size], out, mode, packs, own,
                           size, nodes)
    finally:
        warper.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        caller.use()
    return out


def splits(block):
    """Whether the single warp of ``block`` (one map's, as
    :meth:`~fpiwarp.block.many.BlockStack.blocks` gives it), seeded, draws its band apart
    (:func:`.band.applies`). A batch draws those maps image by image: the
    instanced draw has no region pass, and on llvmpipe it ran every pixel
    through the band's Newton code, 1.4-2x the loop's time for local
    deformations (16 x 512², 8 x 1080p; benchmarks/local_speed.py --batch)."""
    return band.applies(describe(block))


def set_sampling_values(prog, stack, output_shape, cval, own):
    """The per-draw values of a batch program (as warp_block sets them)."""
    top = float(np.iinfo(stack.dtype).max) if stack.dtype.kind == "u" else 0.0
    set_uniform(prog, "fpw_src_size", (stack.shape[2], stack.shape[1]))
    set_uniform(prog, "fpw_cval", tuple(np.resize(cval, 4).astype(float)))
    set_uniform(prog, "fpw_top", top)
    set_uniform(prog, "fpw_out_scale", 1.0)
    set_uniform(prog, "fpw_batch_rows", int(output_shape[0]))
    set_uniform(prog, "fpw_batch_step", 1 if own else 0)


def draw_group(warper, prog, stack, blocks, idx, out, mode, packs, own, size, nodes=None):
    """One instanced draw: images ``idx`` of ``stack`` into ``out[idx]``
    (``blocks``: the (N or 1, rows, 4) stacked blocks),
    in a texture array (a 2D texture where ``size`` is 1 and
    :data:`SINGLE_SOURCE_TEXTURE`) and a target for ``size`` images (several
    draws only where the output is wider than the size limit). ``nodes``: (the
    nodes' batch program, the kind's stages) of a draw taking the coarse
    pass, each draw then preceded by its nodes' (:func:`.coarse.seeded_draw`)."""
    _, h, w, c = stack.shape
    m, (oh, ow) = len(idx), out.shape[1:3]
    targets = warper.targets
    contiguous = idx[-1] - idx[0] == m - 1
    if size == 1 and SINGLE_SOURCE_TEXTURE:  # the single image's texture (the loop's, reused)
        layers = targets.texture("src", (w, h), c, SOURCE_TEXTURE_DTYPES[stack.dtype])
        layers.write(stack[idx[0]])
    else:
        layers = targets.cached("batch_src", (w, h, size, c, stack.dtype), lambda: warper.ctx.texture_array(
            (w, h, size), c, dtype=SOURCE_TEXTURE_DTYPES[stack.dtype]))
        layers.write(stack[idx[0]:idx[0] + m] if contiguous else stack[idx], viewport=(0, 0, 0, w, h, m))
    layers.filter = (moderngl.NEAREST, moderngl.NEAREST)
    layers.repeat_x = layers.repeat_y = mode == "wrap"  # where textureGather places the taps
    mine = blocks[idx] if own else blocks[:1]  # (k, rows, 4), zero rows past each block
    stacked = np.zeros((len(mine), MAX_ROWS, 4), np.float32)
    stacked[:, : mine.shape[1]] = mine
    ssbo = targets.cached("batch_blocks", stacked.nbytes, lambda: warper.ctx.buffer(reserve=stacked.nbytes))
    ssbo.write(stacked.tobytes())
    ssbo.bind_to_storage_buffer(BATCH_BINDING)
    layers.use(0)
    set_uniform(prog, "fpw_batch_count", m)
    vao = warper.fullscreen_vao(prog)
    tall = out[idx[0]:idx[0] + m] if contiguous else np.empty((m, oh, ow, c), out.dtype)
    atlas = tall.reshape(m * oh, ow, c)  # a view: the draw reads back in place

    def draw():
        vao.render(moderngl.TRIANGLES, vertices=6, instances=m)
    if nodes is not None:
        draw = coarse.seeded_draw(warper, prog, nodes[1], draw, (nodes[0], m, 1 if own else 0))

    full = (min(ow, warper.max_size), size * oh)
    for x0, x1 in tiles(ow, warper.max_size):
        warper.draw_tile(stack[0], atlas, prog, draw, (x0, 0, x1, m * oh), packs, full)
    if not contiguous:
        out[idx] = tall
