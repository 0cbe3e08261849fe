"""One preview frame rendered offscreen and read back as an image."""

import numpy as np

from ..backends.gl import bound_framebuffer, check_thread
from ..validation import check_image
from .renderer import DISPLAY_FORMATS, Renderer

#: Framebuffer channels that hold the image's channels (display swizzle).
READ_CHANNELS = {1: [0], 2: [0, 3], 3: [0, 1, 2], 4: [0, 1, 2, 3]}
#: Overlay names :func:`render_image` accepts (Renderer attributes).
OVERLAY_NAMES = ("handles", "outline", "checkerboard", "heatmap")


def render_image(image, transform, *, overlays=(), ctx=None, order=1, mode="constant", cval=0.0, size=None,
                 view=None, renderer_options=None):
    """Render one preview frame offscreen and read it back (top row first).

    With no ``overlays`` and the default size and view, the frame is the
    warped image at the source's size: the picture
    :func:`fpiwarp.warp_image` makes, of the same dtype and channels (up
    to the rounding of the display path: a level at most). With
    ``overlays`` (names among "handles", "outline", "checkerboard",
    "heatmap") the frame is RGB (RGBA for images with alpha) of the image's
    dtype. ``ctx`` defaults to the "gl" backend's headless context (EGL),
    the one context of the process: moderngl contexts in one thread would
    otherwise take "current" from each other.
    """
    img, squeeze = check_image(image)
    warper = None
    if ctx is None:  # the backend's context and warper: its programs are compiled once
        from ..backends import get_backend

        backend = get_backend("gl")
        check_thread()
        warper = backend.warper
        ctx = warper.ctx
    renderer = Renderer(ctx, order=order, mode=mode, cval=cval, warper=warper)
    try:
        renderer.set_image(img)
        renderer.set_transform(transform)
        for name, value in (renderer_options or {}).items():
            setattr(renderer, name, value)
        for name in overlays:
            if name not in OVERLAY_NAMES:
                raise ValueError(f"unknown overlay {name!r} (handles, outline, checkerboard, heatmap)")
            setattr(renderer, name, True)
        if view is not None:
            renderer.view = tuple(view)
        h, w, c = img.shape
        size = (w, h) if size is None else tuple(int(v) for v in size)
        channels = READ_CHANNELS[c] if not overlays else READ_CHANNELS[4 if c in (2, 4) else 3]
        fmt = DISPLAY_FORMATS[img.dtype][0]
        previous = bound_framebuffer(ctx)
        tex = ctx.texture(size, 4, dtype=fmt)
        fbo = ctx.framebuffer(color_attachments=[tex])
        try:
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0)
            renderer.draw((0, 0) + size, y_down=True)
            read_dtype = fmt
            data = fbo.read(viewport=(0, 0) + size, components=4, dtype=read_dtype, alignment=1)
            frame = np.frombuffer(data, dtype=img.dtype).reshape(size[1], size[0], 4)[..., channels].copy()
        finally:
            previous.use()  # never leave a deleted framebuffer bound
            fbo.release()
            tex.release()
    finally:
        renderer.release()
    return frame[:, :, 0] if (squeeze and not overlays) else frame
