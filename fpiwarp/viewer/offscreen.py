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

    Parameters
    ----------
    image : ndarray, uint8, uint16 or float32, shape (H, W) or (H, W, C)
        The source picture.
    transform : Transform
        The map from source to output coordinates (x = column, y = row).
    overlays : sequence of str, optional
        Names among "handles", "outline", "checkerboard", "heatmap" (the
        :class:`~fpiwarp.viewer.Renderer` attributes of those names).
    ctx : moderngl.Context, optional
        Default the "gl" backend's headless context (EGL), the one context
        of the process: moderngl contexts in one thread would otherwise
        take "current" from each other.
    order, mode, cval
        Sampling as in :func:`fpiwarp.warp_image`.
    size : tuple of int (width, height), optional
        The frame's size; default the source's.
    view : tuple of float (x0, y0, x1, y1), optional
        The output region shown; default the source's extent.
    renderer_options : dict, optional
        Renderer attributes to set (e.g. ``{"method": "mesh"}``).

    Returns
    -------
    ndarray
        With no ``overlays`` and the default size and view, the warped image
        at the source's size: the picture :func:`fpiwarp.warp_image` makes,
        of the same dtype and channels (up to the rounding of the display
        path: a level at most). With ``overlays``, RGB (RGBA for images with
        alpha) of the image's dtype.

    Raises
    ------
    BackendUnavailableError
        No ``ctx`` and the "gl" backend cannot run here.
    ValueError
        An unknown overlay name, or an image larger than one texture.

    Examples
    --------
    >>> import numpy as np
    >>> import fpiwarp
    >>> from fpiwarp.viewer import render_image
    >>> img = np.full((48, 64, 3), 200, np.uint8)
    >>> f = fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 3], [60, -2], [66, 50], [-3, 44]])
    >>> frame = render_image(img, f)
    >>> frame.shape, int(np.abs(frame.astype(int) - fpiwarp.warp_image(img, f)).max()) <= 1
    ((48, 64, 3), True)
    >>> render_image(img, f, overlays=("outline", "handles")).shape
    (48, 64, 3)
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
