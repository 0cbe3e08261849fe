"""Real-time preview: draw a warped image into a caller's OpenGL context.

:class:`Renderer` draws the warp of an image by an fpiwarp map into the
framebuffer bound in a caller's moderngl context, inside a viewport: a
Qt ``QOpenGLWidget``, a moderngl-window or glfw window, or an offscreen
framebuffer. The caller owns the window and the event loop::

    renderer = fpiwarp.viewer.Renderer(ctx)         # once, with the context current
    renderer.set_image(image)                    # texture upload
    renderer.set_transform(fpiwarp.FPI(src, dst))  # uniform upload only
    renderer.draw(viewport=(0, 0, width, height))  # every frame

It is built on the "gl" backend (:mod:`fpiwarp.backends.gl`): the
same shader include evaluates the parameter block and samples the source
per pixel (software bilinear or cubic, like :func:`fpiwarp.warp_image`),
and the same program cache compiles one program per kind of map. Moving a
point of an FPI changes values in the block, never its kind: a new map is
one uniform-buffer upload, with no shader compilation
(:attr:`Renderer.compile_count` counts the programs built).

Two ways to draw (``method``): "pixel" evaluates the inverse map at every
output pixel, the exact picture of :func:`fpiwarp.warp_image`; "mesh"
moves a grid of the source by the forward map and rasterizes it (paper
§5, the backend's mesh path), which spares the Newton steps that invert a
thin-plate spline per pixel: several times faster for local deformations,
exact at the grid points and linear between them ("auto" picks it for
maps of non-constant distortion; the viewer uses it while dragging).

Overlays (attributes, all off by default): ``handles`` (the target points),
``outline`` (the image of the source quad's edges; constrained edges in
orange), ``checkerboard`` (a checkerboard of the source, deformed with it)
and ``heatmap`` (the conformal dilation |f_zbar| / |f_z| coloured from
dark blue for 0 to dark red for :attr:`Renderer.heat_max`, like the
paper's Figure 8). An FPI has a constant dilation, taken from its block on
the host; any other map's is computed per pixel in the shader, by finite
differences of the block evaluation between neighbouring fragments
(``dFdx``/``dFdy``, no extra evaluation).

Coordinates. The output image has pixel centers at integers (x = column,
y = row, y down). The renderer shows the rectangle :attr:`Renderer.view`
of output space (default the image's extent), scaled to fit the viewport
with its aspect ratio kept and centered. Window coordinates are GL's:
pixels from the bottom-left corner of the framebuffer, y up; a toolkit's
mouse position (mx, my) with y down becomes (mx, height - my).

State. :meth:`Renderer.draw` binds texture unit 0 and the uniform-buffer
binding of the renderer, sets the viewport, and leaves blending, culling
and clip distance 0 disabled (front face counter-clockwise); it does not
bind framebuffers or clear. A GL context belongs to the thread
that made it: call the renderer from that thread, with the context current.
"""

import moderngl
import numpy as np

from .. import glsl
from ..backends.capabilities import GL
from ..backends.gl import (
    FULLSCREEN,
    GLWarper,
    MeshBuffers,
    ProgramKey,
    band,
    bound_framebuffer,
    coarse,
    draw_culled_mesh,
    grid_mesh,
    set_uniform,
)
from ..backends.gl.pyramid import PYRAMID_UNIT, build_atlas, set_pyramid_values, upload_atlas
from ..block import describe
from ..validation import check_antialias, check_cval, check_image, check_mode, check_order, check_transform
from .overlays import OverlayLayer, edge_curves, handle_triangles, outline_triangles

METHODS = ("pixel", "mesh", "auto")

#: Display textures: normalized where the dtype is an integer, so one
#: floating-point program shows every dtype; value = texel * scale.
DISPLAY_FORMATS = {np.dtype(np.uint8): ("f1", 255.0), np.dtype(np.uint16): ("nu2", 65535.0),
                   np.dtype(np.float32): ("f4", 1.0)}
_SWIZZLE = {1: "RRR1", 2: "RRRG", 3: "RGB1", 4: "RGBA"}


def _last_step(transform):
    steps = getattr(transform, "steps", None)
    return steps[-1] if steps else transform


def _handles_of(transform):
    dst = getattr(_last_step(transform), "dst", None)
    return None if dst is None else np.asarray(dst, dtype=np.float64).reshape(4, 2)


def display_rgba(values):
    """Per-channel values (C,) as the RGBA the display swizzle shows."""
    v = [float(x) for x in values]
    return np.array({1: v * 3 + [1.0], 2: v[:1] * 3 + v[1:], 3: v + [1.0], 4: v}[len(v)])
class Renderer:
    """Draws a warped image, with optional overlays, in a moderngl context.

    Parameters
    ----------
    ctx : moderngl.Context
        The caller's context (current, GL 3.3 core or later).
    order, mode, cval
        Sampling as in :func:`fpiwarp.warp_image` (cval in the image's
        units, e.g. 0..255 for uint8).
    background : color, optional
        What shows where the source is not, for images without an alpha
        channel (RGBA 0..1); default ``cval`` (the exact warped picture).
    warper : GLWarper, optional
        Share a backend warper (program cache, uniform buffer) of ``ctx``.
    method : {"pixel", "mesh", "auto"}
        "pixel": every output pixel evaluates the inverse map (exact, the
        picture of :func:`fpiwarp.warp_image`); "mesh": a grid of the
        source, :attr:`mesh_step` pixels apart, is moved by the forward map
        and rasterized (the paper's way: no Newton steps for the inverse of
        a thin-plate spline, so much faster for local deformations, and
        piecewise linear between grid points); "auto": "pixel" for maps of
        constant dilation (an FPI), "mesh" for the others.
    antialias : bool
        Whether the picture is antialiased (see :func:`fpiwarp.warp_image`):
        ``warp_full`` (the full-resolution export) as ``warp_image`` with
        ``antialias=True``, and :meth:`draw` per screen pixel, over the
        pixel's footprint in the source: the inverse map's Jacobian times
        the view's scale ("pixel" method; "mesh": the mesh's own
        derivatives per screen pixel). A zoomed-out view, or a map that
        shrinks, is filtered instead of aliasing; where a screen pixel
        covers at most a source pixel (zoomed in, no shrinking) the draw
        is the plain one, bit for bit. Costs up to AA_MAX_TAPS² samples
        per screen pixel where it shrinks.

    Notes
    -----
    Overlays are switched on by attributes: ``handles``, ``outline``,
    ``checkerboard``, ``heatmap`` (booleans), with ``checker_size``,
    ``heat_max``, ``handle_radius``, ``line_width`` for their looks.
    ``set_transform`` uploads values only: moving points compiles nothing.
    Programs are compiled once per kind of map (:attr:`compile_count`).
    In an application, call ``draw`` from the toolkit's paint callback
    with the context current (see ``fpiwarp/viewer/examples/qt_embed.py`` and
    ``mglw_embed.py``).

    Examples
    --------
    Drawing into a framebuffer of the "gl" backend's headless context (an
    application passes its own context):

    >>> import numpy as np
    >>> import fpiwarp
    >>> from fpiwarp.backends import get_backend
    >>> from fpiwarp.viewer import Renderer
    >>> ctx = get_backend("gl").warper.ctx
    >>> renderer = Renderer(ctx)
    >>> renderer.set_image(np.full((48, 64, 3), 255, np.uint8))
    >>> renderer.set_transform(fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]],
    ...                                    [[4, 3], [60, -2], [66, 50], [-3, 44]]))
    >>> renderer.outline = True
    >>> fbo = ctx.simple_framebuffer((64, 48))
    >>> fbo.use()
    >>> renderer.draw((0, 0, 64, 48))
    >>> pixels = np.frombuffer(fbo.read(components=3), np.uint8).reshape(48, 64, 3)
    >>> bool(pixels.max() == 255)
    True
    >>> fbo.release(); renderer.release()
    """

    def __init__(self, ctx, *, order=1, mode="constant", cval=0.0, background=None, warper=None, method="pixel",
                 antialias=False):
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        order, mode = check_order(order), check_mode(mode)
        self.ctx = ctx
        self._owns_warper = warper is None
        self.warper = warper if warper is not None else GLWarper(ctx)
        self.order, self.mode = order, mode
        self.antialias = check_antialias(antialias, GL, "gl")
        self.method = method
        self.mesh_step = None  # source pixels between mesh vertices; default max(2, longer side / 256)
        self._cval = cval
        self.background = background
        self.handles = self.outline = self.checkerboard = self.heatmap = False
        self.checker_size = 32.0  # source pixels per checkerboard cell
        self.checker_mix = 0.35
        self.heat_max = 0.5  # dilation shown dark red ((K - 1) / (K + 1) = 0.5: K = 3)
        self.heat_mix = 0.6
        self.handle_radius = 6.0  # screen pixels
        self.line_width = 2.0
        self.active_handle = None  # index drawn in ACTIVE_COLOR
        self.invalid = False  # draw the handles in ACTIVE_COLOR (e.g. a degenerate quad)
        self.view = None
        self.image = None
        self.transform = None
        self.edges = ()
        self._points = None
        self._curves = None
        self._overlays = OverlayLayer(ctx, self.warper.programs)
        self._blocks = {}
        self._dilation = None
        self._texture = None
        self._pyramid = None  # (atlas texture, rects) of the image's pyramid, made on the first antialiased draw
        self._mesh = None  # (key, MeshBuffers)
        self.uploads = 0  # maps set (set_transform calls), each one block upload
        self.pyramid_builds = 0  # image pyramids built (one per set_image, on the first antialiased draw)

    # ---- state
    @property
    def compile_count(self):
        """Programs compiled so far (one per kind of map and image format)."""
        return self.warper.compile_count

    def set_image(self, image):
        """Upload the source image ((H, W) or (H, W, C), uint8, uint16 or
        float32) as a texture; the view resets to its extent."""
        img, _ = check_image(image)
        h, w, c = img.shape
        limit = self.warper.max_size
        if h > limit or w > limit:
            raise ValueError(f"a preview image must fit one texture: {w}x{h} is above {limit} px per side "
                             "(downscale it for the preview; export still warps the full image)")
        fmt, scale = DISPLAY_FORMATS[img.dtype]
        if self._texture is not None:
            self._texture.release()
        self._release_pyramid()
        tex = self.ctx.texture((w, h), c, np.ascontiguousarray(img).tobytes(), dtype=fmt, alignment=1)
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # texelFetch: no mipmaps needed
        tex.swizzle = _SWIZZLE[c]
        self._texture = tex
        self._scale = scale
        self.image = img
        self.cval = self._cval
        self.view = (-0.5, -0.5, w - 0.5, h - 0.5)

    @property
    def cval(self):
        return self._cval

    @cval.setter
    def cval(self, value):
        c = self.image.shape[2] if self.image is not None else 4
        dtype = self.image.dtype if self.image is not None else None
        self._cval = check_cval(value, c, dtype) if np.ndim(value) else float(value)

    def set_transform(self, transform, *, handles=None, edges=None):
        """Show the warp by ``transform`` (source -> output): the parameter
        block of its inverse (the mesh path: of the map itself) goes to the
        uniform buffer, values only: a map of a kind drawn before compiles
        nothing. ``handles`` (4, 2) default the target points of the map
        (its last step's for a compound); ``edges`` its constrained edges."""
        check_transform(transform)
        forward = transform.params()
        self._blocks = {"mesh": forward}
        self._dilation = describe(forward).constant_dilation
        self.transform = transform
        self._upload(self._method())
        self.uploads += 1
        step = _last_step(transform)
        self._points = _handles_of(transform) if handles is None else np.asarray(handles, np.float64).reshape(-1, 2)
        self.edges = tuple(getattr(step, "edges", ()) or ()) if edges is None else tuple(edges)
        self._curves = edge_curves(step)

    @property
    def edge_curves(self):
        """The images of the four edges of the shown map's source quad
        ((4, n, 2) output points, the outline overlay), or None."""
        return self._curves

    def _method(self):
        if self.method == "auto":
            return "pixel" if self._dilation is not None else "mesh"
        return self.method

    def _upload(self, method):
        """Write the block the method evaluates; returns its kind (ProgramKey.stages)."""
        if method not in self._blocks:
            self._blocks[method] = self.transform.inverse.params()
        return self.warper.set_map(self._blocks[method])

    def fit(self, margin=0.05):
        """Set :attr:`view` to the image's extent and the handles, plus a
        margin (a fraction of the larger side)."""
        h, w = self.image.shape[:2]
        pts = [[-0.5, -0.5], [w - 0.5, h - 0.5]]
        if self._points is not None:
            pts += [p for p in self._points.tolist() if np.all(np.isfinite(p))]
        pts = np.array(pts)
        lo, hi = pts.min(0), pts.max(0)
        pad = margin * float(max(hi - lo))
        self.view = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)

    # ---- coordinates
    def view_params(self, viewport, y_down=False):
        """The shaders' ``fpw_view`` for a viewport (x, y, w, h): output
        position = view.xy + view.zw * (window - 0.5). ``y_down`` puts output
        row 0 at window row 0 (a framebuffer read back as an image)."""
        vx, vy, vw, vh = (float(v) for v in viewport)
        x0, y0, x1, y1 = self.view
        s = max((x1 - x0) / vw, (y1 - y0) / vh)
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        if y_down:
            return (cx + s * (0.5 - vx - 0.5 * vw), cy + s * (0.5 - vy - 0.5 * vh), s, s)
        return (cx + s * (0.5 - vx - 0.5 * vw), cy + s * (vy + 0.5 * vh - 0.5), s, -s)

    def window_to_output(self, xy, viewport, y_down=False):
        """Output coordinates of window positions (..., 2) (GL's, y up;
        a pixel's center is at +0.5, like gl_FragCoord)."""
        v = self.view_params(viewport, y_down)
        xy = np.asarray(xy, dtype=np.float64) - 0.5
        return np.stack([v[0] + v[2] * xy[..., 0], v[1] + v[3] * xy[..., 1]], axis=-1)

    def output_to_window(self, pts, viewport, y_down=False):
        """Window positions (GL's, y up) of output points (..., 2)."""
        v = self.view_params(viewport, y_down)
        pts = np.asarray(pts, dtype=np.float64)
        return np.stack([(pts[..., 0] - v[0]) / v[2], (pts[..., 1] - v[1]) / v[3]], axis=-1) + 0.5

    # ---- drawing
    def draw(self, viewport=None, *, y_down=False):
        """Draw into the bound framebuffer.

        Parameters
        ----------
        viewport : tuple of int (x, y, w, h), optional
            Where in the framebuffer; default the bound framebuffer's
            viewport.
        y_down : bool, optional
            True when row 0 of the framebuffer is read as the top of the
            picture (offscreen read-back); False (GL's convention) for
            windows.

        Raises
        ------
        RuntimeError
            Before :meth:`set_image` and :meth:`set_transform`.
        """
        if self.image is None or self.transform is None:
            raise RuntimeError("set_image and set_transform before draw")
        ctx = self.ctx
        if viewport is None:
            viewport = tuple(bound_framebuffer(ctx).viewport)
        viewport = tuple(int(v) for v in viewport)
        ctx.viewport = viewport
        method = self._method()
        kind = self._upload(method)  # the block again: the buffer may have served another map
        flags = ("PV_ALPHA",) if self.image.shape[2] in (2, 4) else ()
        shading = dict(stages=kind, order=self.order, mode=self.mode,
                       flags=flags + (("FPW_ANTIALIAS",) if self.antialias else ()))
        seeded = coarse.flags(method == "pixel" and self.warper.newton_map, self.antialias)
        h, w, c = self.image.shape
        cval4 = display_rgba(np.broadcast_to(np.asarray(self._cval, np.float64), (c,)) / self._scale)
        bg = cval4 if self.background is None else np.resize(np.asarray(self.background, np.float64), 4)
        if method == "mesh":
            prog = self.warper.program(ProgramKey(glsl.MESH_VERT, glsl.PREVIEW_MESH_FRAG, **shading))
            # mesh.vert maps to the viewport from its corner: view of (0, 0, w, h)
            set_uniform(prog, "fpw_view", tuple(float(v) for v in self.view_params((0, 0) + viewport[2:], y_down)))
            set_uniform(prog, "fpw_viewport", (float(viewport[2]), float(viewport[3])))
        else:
            shading["flags"] += seeded
            key = ProgramKey(FULLSCREEN, glsl.PREVIEW_FRAG, **shading)
            prog = self.warper.program(key)
            set_uniform(prog, "fpw_view", tuple(float(v) for v in self.view_params(viewport, y_down)))
            if seeded:  # a Newton map's coarse pass (fpiwarp.backends.gl.coarse)
                coarse.prepare(self.warper, prog, kind, self.view_params(viewport, y_down), viewport)
        set_uniform(prog, "fpw_src_size", (w, h))
        set_uniform(prog, "fpw_cval", tuple(float(v) for v in cval4) if c in (2, 4) else (0.0, 0.0, 0.0, 0.0))
        set_uniform(prog, "pv_background", tuple(float(v) for v in bg))
        set_uniform(prog, "pv_checker", float(self.checker_size) if self.checkerboard else 0.0)
        set_uniform(prog, "pv_checker_mix", float(self.checker_mix))
        set_uniform(prog, "pv_heat", float(self.heat_mix) if self.heatmap else 0.0)
        set_uniform(prog, "pv_heat_max", float(self.heat_max))
        set_uniform(prog, "pv_dilation", -1.0 if self._dilation is None else self._dilation)
        self._texture.use(0)
        if self.antialias:
            self._bind_pyramid(prog)
        ctx.disable(moderngl.BLEND)
        if method == "mesh":
            self._draw_mesh(prog, cval4 if c in (2, 4) else bg, y_down)
        else:
            vao = self.warper.fullscreen_vao(prog)
            draw = lambda: vao.render(moderngl.TRIANGLES, vertices=3)  # noqa: E731
            if seeded:  # the band's split draw (fpiwarp.backends.gl.band)
                draw = band.split(self.warper, key, prog, draw)
            draw()
        if self.handles or self.outline:
            self._draw_overlays(viewport, y_down)

    def _draw_mesh(self, prog, outside, y_down):
        """Fill the viewport with what shows outside the source, then draw
        the grid of the source moved by the forward map (mesh.vert), with
        the culling and clipping of GLWarper's mesh path: triangles that
        come out flipped straddle the pole, vertices at the pole clip."""
        ctx = self.ctx
        fill = self.warper.program(ProgramKey(FULLSCREEN, glsl.WARP_FRAG, order=self.order, mode=self.mode,
                                              output="fill"))
        set_uniform(fill, "fpw_cval", tuple(float(v) for v in outside))
        set_uniform(fill, "fpw_out_scale", 1.0)
        self.warper.fullscreen_vao(fill).render(moderngl.TRIANGLES, vertices=3)
        h, w = self.image.shape[:2]
        step = float(self.mesh_step or max(2.0, max(h, w) / 256.0))
        key = (h, w, step)
        if self._mesh is None or self._mesh[0] != key:
            self._release_mesh()
            self._mesh = (key, MeshBuffers(ctx, *grid_mesh(self.image.shape, step, None, None)))
        # Maps keep orientation; a y-up view mirrors it on the screen.
        draw_culled_mesh(ctx, self._mesh[1].vao(prog), front_face="ccw" if y_down else "cw")

    def _bind_pyramid(self, prog):
        """Bind the image's pyramid (built on the first antialiased draw
        after set_image, kept across frames) in the display texture's
        units and swizzle."""
        if self._pyramid is None:
            atlas, rects = build_atlas(self.image, self._scale)
            tex = upload_atlas(self.ctx, atlas)
            tex.swizzle = _SWIZZLE[self.image.shape[2]]
            self._pyramid = (tex, rects)
            self.pyramid_builds += 1
        tex, rects = self._pyramid
        tex.use(PYRAMID_UNIT)
        set_pyramid_values(prog, rects)

    def _release_pyramid(self):
        if self._pyramid is not None:
            self._pyramid[0].release()
            self._pyramid = None

    def _release_mesh(self):
        if self._mesh is not None:
            self._mesh[1].release()
            self._mesh = None

    def _draw_overlays(self, viewport, y_down):
        def to_window(points):
            return self.output_to_window(points, viewport, y_down)

        tris = []
        if self.outline and self._curves is not None:
            tris += outline_triangles(self._curves, self.edges, to_window, self.line_width)
        if self.handles and self._points is not None:
            tris += handle_triangles(self._points, to_window, self.handle_radius, self.active_handle, self.invalid)
        self._overlays.draw(tris, viewport)

    def warp_full(self, output_shape=None):
        """The warped image at full resolution, the picture
        :func:`fpiwarp.warp_image` makes (same dtype and channels), computed
        in this context; the framebuffer bound before is bound again."""
        if self.image is None or self.transform is None:
            raise RuntimeError("set_image and set_transform before warp_full")
        previous = bound_framebuffer(self.ctx)
        cval = np.broadcast_to(np.asarray(self._cval, np.float64), (self.image.shape[2],))
        try:
            out = self.warper.warp_image(self.image, self.transform, output_shape or self.image.shape[:2],
                                         order=self.order, mode=self.mode, cval=cval,
                                         antialias=self.antialias)
        finally:
            self.set_transform(self.transform, handles=self._points, edges=self.edges)
            previous.use()
        return out

    def release(self):
        """Free the GL objects of the renderer, and of its warper when the
        renderer made it (a warper passed in stays usable)."""
        self._overlays.release()
        if self._texture is not None:
            self._texture.release()
        self._texture = None
        self._release_pyramid()
        self._release_mesh()
        if self._owns_warper:
            self.warper.release()  # leaves the caller's framebuffer bound


