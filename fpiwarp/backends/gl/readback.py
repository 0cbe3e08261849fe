"""Reading rendered pixels back into numpy arrays, and the RGB packing.

Reading 3 channels out of an RGBA target makes the driver convert every
pixel on the CPU (a 4K uint8 frame: ~107 ms on NVIDIA's driver, ~15 ms on
llvmpipe). An RGB32UI target holding 3-channel pixels packed into 12-byte
texels (4 pixels of uint8, 2 of uint16, 1 of float32; see glsl/include/pack.glsl)
reads back as a plain copy. The warp shader packs its own pixels where it
is short (FPW_PACK_PIXELS); other passes are packed by glsl/backend/pack_rgb.frag.
"""

import moderngl
import numpy as np

from .context import bound_framebuffer

#: Output attachment formats: integer formats for integer images (exact
#: rounding in the shader), float32 for float32.
TEXTURE_DTYPES = {np.dtype(np.uint8): "u1", np.dtype(np.uint16): "u2", np.dtype(np.float32): "f4"}


def pixels_per_texel(dtype):
    """Pixels of 3 channels of ``dtype`` in one 12-byte RGB32UI texel."""
    return 4 // np.dtype(dtype).itemsize


def channels_format(c):
    """Components of a renderable output attachment for c channels (RGB
    integer formats need not be renderable: use RGBA and read back 3)."""
    return 4 if c == 3 else c


def renders_rgb32ui(ctx):
    """Whether ``ctx`` can draw into an RGB32UI texture (an optional
    color-renderable format in GL); leaves the bound framebuffer bound."""
    bound = bound_framebuffer(ctx)
    tex = ctx.texture((1, 1), 3, dtype="u4")
    try:
        ctx.framebuffer(color_attachments=[tex]).release()
        return True
    except moderngl.Error:
        return False
    finally:
        bound.use()
        tex.release()
        ctx.error  # noqa: B018 - clear the error an incomplete framebuffer may leave


def draw_packed(targets, draw, full, size, dtype):
    """Run ``draw`` into the RGB32UI target (of ``targets``, role "packed")
    that holds a (w, h) = ``size`` picture of 3 channels of ``dtype``
    packed, in a target for pictures up to ``full``; return the target."""
    per = pixels_per_texel(dtype)
    packed = targets.target("packed", (-(-full[0] // per), full[1]), 3, "u4")
    packed.viewport = (0, 0, -(-size[0] // per), size[1])
    packed.use()
    draw()
    return packed


def read_packed(packed, size, dtype, dest):
    """Read a packed (w, h) picture into ``dest`` (a copy: no per-pixel
    conversion by the driver); columns past w are padding."""
    w, h = size
    per = pixels_per_texel(dtype)
    pw = -(-w // per)
    if pw * per == w and dest.flags.c_contiguous:
        packed.read_into(dest, viewport=(0, 0, pw, h), components=3, dtype="u4", alignment=1)
    else:
        rows = np.empty((h, pw * per, 3), dtype=dtype)
        packed.read_into(rows, viewport=(0, 0, pw, h), components=3, dtype="u4", alignment=1)
        dest[...] = rows[:, :w]


def read_direct(fbo, size, dest):
    """Read the first ``dest.shape[2]`` channels of a (w, h) picture from
    ``fbo`` into ``dest`` (the driver converts the format)."""
    c = dest.shape[2]
    dt = TEXTURE_DTYPES[dest.dtype]
    if dest.flags.c_contiguous:
        fbo.read_into(dest, viewport=(0, 0) + size, components=c, dtype=dt, alignment=1)
    else:
        data = fbo.read(viewport=(0, 0) + size, components=c, dtype=dt, alignment=1)
        dest[...] = np.frombuffer(data, dtype=dest.dtype).reshape(dest.shape)
