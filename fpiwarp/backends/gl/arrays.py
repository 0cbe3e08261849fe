"""warp_image on ``moderngl.Texture`` s: texture in, texture out, rendered.

The source texture is sampled where it is and the output is rendered
straight into a texture of the same format, in the same context: nothing
is uploaded or read back. Textures of the gl backend's shared context use
its warper; a texture of any other context (a window's, say) gets a
:class:`~fpiwarp.backends.gl.GLWarper` of its own in that context, made
once (call from the thread where that context is current: a GL call
never switches contexts).

Formats, as :func:`fpiwarp.warp_image` takes them: ``"f1"`` (normalized
uint8, the gl backend's own source format), ``"u2"`` (uint16 integer) and
``"f4"`` (float32) with 1 to 4 components. Row ``r`` of the texture
(as ``texture.read()`` returns it) is image row ``r``. Sampling is the
software sampler of warp_image, so results equal the gl backend's on
numpy images; the output is rounded in the shader (uint8: written as
``k / 255`` into the normalized target, which stores ``k`` exactly).
"""

import weakref

import moderngl
import numpy as np

from ... import glsl
from ...arrays.kinds import array_info
from ...errors import ArgumentError, DeviceMismatchError
from . import band, coarse
from .pyramid import PYRAMID_UNIT, build_atlas, set_pyramid_values, upload_atlas

#: Texture dtype -> (image dtype, sampler source kind, fragment output, output scale).
FORMATS = {"f1": (np.dtype(np.uint8), "unorm", "float", 1.0 / 255.0),
           "u2": (np.dtype(np.uint16), "int", "int", 1.0),
           "f4": (np.dtype(np.float32), "float", "float", 1.0)}
_warpers = weakref.WeakKeyDictionary()  # a caller's context -> its GLWarper


def warper_for(ctx):
    """The GLWarper that draws in ``ctx``: the gl backend's for its shared
    context, else one of its own, made once per context."""
    from .. import get_backend  # noqa: PLC0415
    from . import GLWarper, check_thread, shared_context  # noqa: PLC0415

    if ctx is shared_context():
        check_thread()
        return get_backend("gl").warper
    if ctx not in _warpers:
        _warpers[ctx] = GLWarper(ctx)
    return _warpers[ctx]


def texture_format(tex, what="image"):
    """(dtype, (h, w, c)) of a texture fpiwarp can warp, else ArgumentError."""
    if isinstance(tex.mglo, moderngl.InvalidObject):
        raise ArgumentError(f"{what} is a released texture")
    if tex.dtype not in FORMATS:
        raise ArgumentError(f"{what} texture dtype must be one of {sorted(FORMATS)} (uint8 normalized, uint16, "
                            f"float32), got {tex.dtype!r}")
    w, h = tex.size
    return FORMATS[tex.dtype][0], (h, w, tex.components)


def output_texture(src, out, output_shape):
    """``out`` checked, or a new texture like ``src`` of ``output_shape``."""
    oh, ow = output_shape
    if out is None:
        return src.ctx.texture((ow, oh), src.components, dtype=src.dtype)
    if array_info(out).kind != "texture":
        raise DeviceMismatchError(f"out= is a {type(out).__name__}; for a texture image pass a moderngl.Texture")
    texture_format(out, "out")
    if out.ctx is not src.ctx:
        raise DeviceMismatchError("out= is a texture of another GL context than the image's; make it in the "
                                  "image's context")
    if out.glo == src.glo:
        raise ArgumentError("out= is the image's own texture; render into another texture")
    if (out.size, out.components, out.dtype) != ((ow, oh), src.components, src.dtype):
        raise ArgumentError(f"out= must be a {ow}x{oh} texture of {src.components} {src.dtype!r} components, got "
                            f"{out.size[0]}x{out.size[1]} of {out.components} {out.dtype!r}")
    return out


def warp_texture(src, transform, output_shape, out, *, order, mode, cval, antialias=False):
    """Render ``src`` warped by ``transform`` into ``out`` (or a new texture);
    arguments as :func:`fpiwarp.warp_image` checked them. Returns the texture.
    The texture's context must be current in the calling thread."""
    from . import FULLSCREEN, ProgramKey, bound_framebuffer, set_uniform  # noqa: PLC0415

    warper = warper_for(src.ctx)
    ctx = warper.ctx
    dtype, (h, w, c) = texture_format(src)
    oh, ow = output_shape
    if max(h, w, oh, ow) > warper.max_size:
        raise ArgumentError(f"textures above {warper.max_size} px a side cannot be warped in place here")
    target = output_texture(src, out, output_shape)
    _, source, output, scale = FORMATS[src.dtype]
    stages = warper.set_map(transform.inverse.params())
    gather = warper.gather and order == 1 and mode in ("constant", "edge", "wrap")
    flags = (("FPW_ANTIALIAS",) if antialias else ()) + coarse.flags(coarse.chosen(warper, (oh, ow)), antialias)
    key = ProgramKey(FULLSCREEN, glsl.WARP_FRAG, stages=stages, order=order, mode=mode, source=source,
                     gather_channels=c if gather else 0, output=output,
                     flags=flags + (("FPW_OUT_ROUNDED",) if scale != 1.0 else ()))
    prog = warper.program(key)
    top = float(np.iinfo(dtype).max) if dtype.kind == "u" else 0.0
    set_uniform(prog, "fpw_src_size", (w, h))
    set_uniform(prog, "fpw_cval", tuple(np.resize(np.asarray(cval, float), 4)))
    set_uniform(prog, "fpw_top", top)
    set_uniform(prog, "fpw_out_scale", scale)
    warper.set_view([prog], (0, 0), (ow, oh))
    caller = bound_framebuffer(ctx)
    saved = (src.filter, src.repeat_x, src.repeat_y)
    fbo = ctx.framebuffer(color_attachments=[target])
    pyramid = None
    if antialias:  # the texture may have changed unseen since any earlier call: its pyramid is built anew
        pixels = np.frombuffer(src.read(alignment=1), dtype).reshape(h, w, c)
        atlas, rects = build_atlas(pixels)
        pyramid = upload_atlas(ctx, atlas)
        pyramid.use(PYRAMID_UNIT)
        set_pyramid_values(prog, rects)
    try:
        src.filter = (moderngl.NEAREST, moderngl.NEAREST)
        src.repeat_x = src.repeat_y = mode == "wrap"  # where textureGather places its taps
        src.use(0)
        fbo.viewport = (0, 0, ow, oh)
        fbo.use()
        vao = warper.fullscreen_vao(prog)
        draw = lambda: vao.render(moderngl.TRIANGLES, vertices=3)  # noqa: E731
        if coarse.FLAG in key.flags:  # a Newton map: seeded and split as the host warp's draw is
            coarse.prepare(warper, prog, stages, (0.0, 0.0, 1.0, 1.0), (0, 0, ow, oh))
            draw = band.split(warper, key, prog, draw)
        draw()
    finally:
        src.filter, src.repeat_x, src.repeat_y = saved
        warper.targets.dummy.use()
        fbo.release()
        if pyramid is not None:
            pyramid.release()
        if not warper.targets.owns(caller):
            caller.use()
    return target


# --- The registry's array calls of the gl backend (its entry's ``arrays``): textures are images,
# warped one at a time (no stacks, no points).


def writes_host_out():
    """Whether warp_image writes a numpy ``out=`` in place: no (host calls copy into it)."""
    return False


def warp_image(image, info, transform, call):
    """warp_image on a texture, into a texture (``call``: :class:`fpiwarp.arrays.dispatch.WarpCall`)."""
    from ...arrays.dispatch import check_device_warp  # noqa: PLC0415

    out = call.out
    if call.channels != "last" or out is not None and array_info(out).kind != "texture":
        raise ArgumentError("a texture is warped into a texture of its channels: leave channels='last' and "
                            "give a moderngl.Texture as out=")
    dtype, shape = texture_format(image)
    oshape, order, mode, cval, options, inverted = check_device_warp(shape, dtype, transform, call, "gl")
    if options.get("hardware_filter"):
        raise ArgumentError("hardware_filter is not available for textures warped in place")
    return warp_texture(image, inverted, oshape, out, order=order, mode=mode, cval=cval,
                        antialias=bool(options.get("antialias")))
