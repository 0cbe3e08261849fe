"""GLWarper: map points, warp images per pixel and by mesh, in one context.

A warper keeps, per moderngl context, the uniform buffer that holds the
parameter block, the compiled programs (:mod:`.programs`) and the
textures and framebuffers it reuses between calls (:mod:`.targets`). It
binds its own framebuffers, gives the caller's back when done (its 1×1
dummy where one of its own was bound: never a target that a later call
may release), and leaves blending, culling and clip distance 0 disabled. Output pixel centers are
at integers: a fragment's output position is
``view.xy + view.zw * (gl_FragCoord.xy - 0.5)`` (warp.frag), and with
``view = (x0, y0, 1, 1)`` window row j is image row y0 + j, so the
readback (bottom row first) comes out top-down, no flip needed.
"""

import sys

import moderngl
import numpy as np

from ... import block as P
from ... import glsl
from ...block import describe
from ...block.coarse import newton_stage
from ...validation import check_mode, check_order
from . import band, coarse, readback
from .context import bound_framebuffer, create_context
from .mesh import MeshBuffers, draw_culled_mesh, grid_mesh
from .programs import FULLSCREEN, MAX_ROWS, ProgramCache, ProgramKey, set_uniform
from .pyramid import PYRAMID_UNIT, PyramidCache, atlas_layout, set_pyramid_values
from .targets import TargetCache
from .tiling import SOURCE_TEXTURE_DTYPES, render_tiled_source, tiles

#: Points per transform-feedback draw in map_points (bounds buffer sizes).
POINT_CHUNK = 1 << 20
#: The software sampler's source format (see ProgramKey.source) by dtype.
SOURCE_KINDS = {np.dtype(np.uint8): "unorm", np.dtype(np.uint16): "int", np.dtype(np.float32): "float"}
#: Normalized textures for the hardware-filtered option, and their scale.
HW_DTYPES = {np.dtype(np.uint8): ("f1", 255.0), np.dtype(np.uint16): ("nu2", 65535.0),
             np.dtype(np.float32): ("f4", 1.0)}
HW_MODES = ("constant", "edge", "wrap")


def check_sampling(image, order, mode, cval):
    """The image as a contiguous array and cval as (C,) float64, after
    checking order and mode."""
    check_order(order), check_mode(mode)
    c = image.shape[2]
    cval = np.zeros(c) if cval is None else np.broadcast_to(np.asarray(cval, np.float64), (c,))
    return np.ascontiguousarray(image), cval


def _varying_slots(info):
    """vec4 slots between the vertex and fragment stages of a context."""
    components = [info.get("GL_MAX_FRAGMENT_INPUT_COMPONENTS") or 60,
                  info.get("GL_MAX_VERTEX_OUTPUT_COMPONENTS") or 60]
    if info.get("GL_MAX_VARYING_VECTORS"):
        components.append(4 * info["GL_MAX_VARYING_VECTORS"])
    return min(components) // 4


class GLWarper:
    """Warps and maps points with shaders in one moderngl context.

    Parameters
    ----------
    ctx : moderngl.Context, optional
        The context to draw in (a caller's, e.g. a window's); default a new
        headless one.
    max_texture_size : int, optional
        Largest texture/viewport side to use; default the driver's limit.
        Smaller values force tiling (used by the tests).
    ubo_binding : int
        Uniform-block binding point used for the parameter block.
    specialize : bool
        Compile one program per kind of map (see :class:`ProgramKey`),
        several times faster on software rasterizers; False: one program
        reads the kind from the block at run time and serves every map.
    gather : bool, optional
        Sample order 1 ('constant', 'edge', 'wrap') with one textureGather
        per channel instead of one texelFetch per tap: same values, fewer
        texture calls. Default: where the context has GL_ARB_gpu_shader5.
    pack_rgb : bool, optional
        Read 3-channel pictures back as packed RGB32UI texels (see
        :mod:`.readback`). Default: on little-endian hosts whose driver
        renders into RGB32UI (GL does not require it; llvmpipe and NVIDIA's
        driver do).
    anisotropy : float, optional
        The largest anisotropy of the texture unit's minification where
        ``hardware_filter`` and ``antialias`` are both set (1: trilinear
        only; at most the driver's GL_MAX_TEXTURE_MAX_ANISOTROPY). Default:
        the driver's largest where its anisotropic filter passes
        :meth:`checked_anisotropy`, else 1 (Mesa 22.3's llvmpipe reports 16
        but fails: it ignores textureGrad's gradients and blurs pixels
        that are not minified).
    """

    def __init__(self, ctx=None, max_texture_size=None, ubo_binding=0, specialize=True, gather=None,
                 pack_rgb=None, anisotropy=None):
        self.ctx = ctx if ctx is not None else create_context()
        info = self.ctx.info
        limits = [info["GL_MAX_TEXTURE_SIZE"], info.get("GL_MAX_RENDERBUFFER_SIZE") or 1 << 30]
        limits += list(info.get("GL_MAX_VIEWPORT_DIMS") or ())
        self.max_size = int(min(limits))
        if max_texture_size is not None:
            if int(max_texture_size) < 4:
                raise ValueError(f"max_texture_size must be >= 4, got {max_texture_size}")
            self.max_size = min(self.max_size, int(max_texture_size))
        self.ubo_binding = ubo_binding
        self.specialize = specialize
        if gather is None:
            gather = "GL_ARB_gpu_shader5" in self.ctx.extensions  # what the #version 330 shader requires
        self.gather = bool(gather)
        if pack_rgb is None:
            pack_rgb = sys.byteorder == "little" and readback.renders_rgb32ui(self.ctx)
        self.pack_rgb = bool(pack_rgb)
        self._anisotropy = None if anisotropy is None else self._clamped_anisotropy(anisotropy)
        self.ubo = self.ctx.buffer(reserve=MAX_ROWS * 16)
        self.programs = ProgramCache(self.ctx, ubo_binding, _varying_slots(info))
        self.targets = TargetCache(self.ctx)
        #: the antialiasing pyramid of the last source (reused while its pixels stay)
        self.pyramids = PyramidCache(self.ctx)
        self.short_map = False  # set by set_map
        self.newton_map = False  # set by set_map
        self.block, self.block_kind = None, None  # set by set_map

    # ---- the texture unit's anisotropic filter (hardware_filter with antialias)
    def _clamped_anisotropy(self, value):
        most = float(getattr(self.ctx, "max_anisotropy", 1.0) or 1.0)
        return min(max(1.0, float(value)), max(1.0, most))

    @property
    def anisotropy(self):
        """The anisotropy of the hardware-filtered antialiasing's sampler
        (see the class docstring; checked on first use, settable)."""
        if self._anisotropy is None:
            self._anisotropy = 1.0  # the check below draws with trilinear as its reference
            self._anisotropy = self.checked_anisotropy()
        return self._anisotropy

    @anisotropy.setter
    def anisotropy(self, value):
        self._anisotropy = self._clamped_anisotropy(value)

    def checked_anisotropy(self):
        """The driver's largest anisotropy if its filter passes two checks
        on a small texture, else 1: read through it, the identity gives
        what ``hardware_filter`` alone gives (level 0), and an isotropic
        shrink by 4 what trilinear filtering gives within a level (GL:
        anisotropy changes nothing where the footprint is isotropic)."""
        most = self._clamped_anisotropy(float("inf"))
        if most <= 1.0:
            return 1.0
        img = (np.arange(32 * 32 * 3).reshape(32, 32, 3) * 37 % 251).astype(np.uint8)
        from ...maps import RLinear  # noqa: PLC0415 - the maps load after the backends

        identity, shrink = RLinear(1, 0, 0).params(), RLinear(4, 0, 0).params()
        saved = self._anisotropy
        try:
            plain = self.warp_block(img, identity, (32, 32), hardware_filter=True)
            trilinear = self.warp_block(img, shrink, (8, 8), hardware_filter=True, antialias=True)
            self._anisotropy = most
            aniso_plain = self.warp_block(img, identity, (32, 32), hardware_filter=True, antialias=True)
            aniso = self.warp_block(img, shrink, (8, 8), hardware_filter=True, antialias=True)
        finally:
            self._anisotropy = saved
        same = np.array_equal(plain, aniso_plain) and np.abs(aniso.astype(int) - trilinear).max() <= 1
        return most if same else 1.0

    # ---- programs and per-draw values
    @property
    def compile_count(self):
        """Programs compiled so far (one per key)."""
        return self.programs.compile_count

    @property
    def varying_slots(self):
        """vec4 slots between the vertex and fragment stages."""
        return self.programs.varying_slots

    @varying_slots.setter
    def varying_slots(self, value):
        self.programs.varying_slots = value

    def program(self, key):
        """The compiled program of a :class:`ProgramKey`, built on first use only."""
        return self.programs.get(key)

    def fullscreen_vao(self, prog):
        """The attribute-less vertex array that draws ``prog`` (with
        fullscreen.vert) over the viewport: ``.render(TRIANGLES, vertices=3)``."""
        return self.programs.fullscreen_vao(prog)

    def set_map(self, block):
        """Upload a parameter block (``Transform.params()``): values only.
        Returns its kind, the ``stages`` of a :class:`ProgramKey` (None
        when not specializing)."""
        block = np.ascontiguousarray(block, dtype=np.float32)
        if block.ndim != 2 or block.shape[1] != 4 or not 1 <= block.shape[0] <= MAX_ROWS:
            raise ValueError(f"a parameter block is (rows <= {MAX_ROWS}, 4) float32, got {block.shape}")
        if block.shape[0] != 1 + P.n_stages(block) * P.STAGE_ROWS:
            raise ValueError("parameter block rows do not match its header's number of stages")
        kind = describe(block)  # refuses unknown cores before anything is uploaded
        self.ubo.write(block.tobytes())
        #: the block just uploaded (float32) and its kind (the band's split draw
        #: reads its regions, the coarse pass's choice coarse.picks the block)
        self.block, self.block_kind = block, kind
        self.ubo.bind_to_uniform_block(self.ubo_binding)
        #: the block just uploaded is a specialized short map (see BlockKind.is_short)
        self.short_map = self.specialize and kind.is_short
        #: the block just uploaded has a Newton core (a per-pixel draw may take the coarse pass)
        self.newton_map = newton_stage(kind) is not None
        return tuple((s.core, s.n_regions) for s in kind.stages) if self.specialize else None

    def set_view(self, progs, origin, size):
        """Set the output rectangle of one tile in each program of ``progs``."""
        for p in progs:
            if p is not None:
                set_uniform(p, "fpw_view", (float(origin[0]), float(origin[1]), 1.0, 1.0))
                set_uniform(p, "fpw_viewport", (float(size[0]), float(size[1])))

    def release(self):
        """Free the GL objects made here (not the context). The caller's
        framebuffer stays bound; where one of these was, framebuffer 0 is
        (a deleted one left bound breaks the next framebuffer moderngl makes)."""
        bound = bound_framebuffer(self.ctx)
        if self.targets.owns(bound):
            bound = self.ctx.detect_framebuffer(0)
        self.programs.release()
        self.pyramids.release()
        self.ubo.release()
        self.targets.release(rebind=bound)

    # ---- per vertex
    def map_points(self, transform, points):
        """Map float64 (..., 2) points by transform feedback; float64 out."""
        pts = np.asarray(points, dtype=np.float64)
        flat = pts.reshape(-1, 2)
        out = np.empty_like(flat)
        if flat.shape[0] == 0:
            return out.reshape(pts.shape)
        stages = self.set_map(transform.params())
        prog = self.program(ProgramKey(glsl.MAP_POINTS_VERT, stages=stages, varyings=("fpw_mapped",)))
        caller = self._caller_framebuffer()
        self.targets.dummy.use()  # without a bound framebuffer (surfaceless EGL) nothing is captured
        try:
            for a in range(0, flat.shape[0], POINT_CHUNK):
                chunk = np.ascontiguousarray(flat[a:a + POINT_CHUNK], dtype=np.float32)
                n = chunk.shape[0]
                vbo = self.ctx.buffer(chunk.tobytes())
                res = self.ctx.buffer(reserve=n * 8)
                vao = self.ctx.vertex_array(prog, [(vbo, "2f", "fpw_point")])
                try:
                    vao.transform(res, moderngl.POINTS, vertices=n)
                    out[a:a + n] = np.frombuffer(res.read(), dtype=np.float32).reshape(n, 2)
                finally:
                    vao.release()
                    vbo.release()
                    res.release()
        finally:
            caller.use()
        return out.reshape(pts.shape)

    # ---- per pixel
    def warp_image(self, image, transform, output_shape, *, order=1, mode="constant", cval=None,
                   hardware_filter=False, antialias=False):
        """Backward warp of a validated (H, W, C) image (see fpiwarp.warp_image).

        ``hardware_filter=True`` lets the texture unit interpolate (orders
        0 and 1, modes constant/edge/wrap): faster, but bilinear weights are
        quantized by the hardware, so results may differ from the reference
        by a level or so. Sources above the size limit use the software path.
        ``antialias=True`` averages each pixel's footprint over the source's
        pyramid (fpiwarp.sampling.antialias; software sampling, FPW_ANTIALIAS
        in glsl/include/antialias.glsl); the pyramid is built once per
        source pixels and reused (:class:`.pyramid.PyramidCache`). Both
        set: the texture unit filters the footprint itself, by textureGrad
        over the source's mipmaps (built by the driver once per source
        pixels, :meth:`.pyramid.PyramidCache.mipmapped`) with trilinear and
        anisotropic minification (up to :attr:`anisotropy`); pixels that do
        not shrink are exactly those of ``hardware_filter`` alone.
        """
        return self.warp_block(image, transform.inverse.params(), output_shape, order=order, mode=mode, cval=cval,
                               hardware_filter=hardware_filter, antialias=antialias)

    def warp_block(self, image, block, output_shape, *, order=1, mode="constant", cval=None, hardware_filter=False,
                   antialias=False, out=None):
        """:meth:`warp_image` by the map from output to source whose
        parameter block is ``block`` (``transform.inverse.params()``, packed
        once by a bound map). ``out``: a C-contiguous (rows, cols, C) array
        of the image's dtype to write into (a batch's image), else a new one."""
        image, cval = check_sampling(image, order, mode, cval)
        if hardware_filter:
            if order not in (0, 1):
                raise ValueError(f"hardware_filter supports order 0 or 1, got {order}")
            if mode not in HW_MODES:
                raise ValueError(f"hardware_filter supports modes {HW_MODES}, got {mode!r}")
            if antialias:
                _ = self.anisotropy  # checked (by drawing) before this call binds its map and textures
        stages = self.set_map(block)
        return self._render(image, output_shape, order, mode, cval, None, hardware_filter, stages, antialias, out)

    # ---- per vertex, rasterized
    def warp_image_mesh(self, image, transform, output_shape, *, order=1, mode="constant", cval=None,
                        grid_step=4.0, vertices=None, triangles=None):
        """Warp by deforming a triangulated mesh of the source with the
        forward map and rasterizing it with texture mapping (paper §5).

        The default mesh is a grid with ``grid_step`` pixels between
        vertices over the source's extent [-0.5, W - 0.5] × [-0.5, H - 0.5];
        or pass ``vertices`` (N, 2) source positions and ``triangles`` (M, 3)
        indices. Inside a triangle the source position is interpolated
        linearly (the mesh approximates the map); pixels no triangle covers
        get ``cval``. Triangles that touch a vertex sent to the pole or that
        come out flipped (they straddle the pole) are dropped.
        """
        image, cval = check_sampling(image, order, mode, cval)
        verts, tris = grid_mesh(image.shape, grid_step, vertices, triangles)
        stages = self.set_map(transform.params())
        mesh = MeshBuffers(self.ctx, verts, tris)
        try:
            return self._render(image, output_shape, order, mode, cval, mesh, False, stages)
        finally:
            mesh.release()

    # ---- shared rendering
    def _caller_framebuffer(self):
        """The framebuffer to bind again after a call: the caller's, or our
        1×1 dummy where one of ours is bound. Never a cached target: the
        next call with another size releases it, and a caller that binds
        again what it found bound (Renderer.warp_full, render_image) would
        then bind a released framebuffer."""
        caller = bound_framebuffer(self.ctx)
        return self.targets.dummy if self.targets.owns(caller) else caller

    def _render(self, image, output_shape, order, mode, cval, mesh, hardware_filter, stages, antialias=False,
                out=None):
        caller = self._caller_framebuffer()
        try:
            return self._render_bound(image, output_shape, order, mode, cval, mesh, hardware_filter, stages,
                                      antialias, out)
        finally:
            caller.use()  # a caller drawing into its own framebuffer keeps it bound

    def _program_keys(self, image, order, mode, mesh, hw, tiled, stages, antialias=False, seeded=True):
        """(key of the warp or mesh program, key of the mesh's fill pass or
        None, whether the warp program packs its RGB pixels). Antialiased
        programs (FPW_ANTIALIAS) gather as plain ones do (a pixel that does
        not shrink runs the plain warp's sampling code) but do not pack (four
        inlined footprint averages per fragment compile slowly on llvmpipe).
        ``seeded``: an untiled per-pixel warp of a Newton map takes the coarse
        pass (its draw: :func:`.coarse.seeded_draw`)."""
        c = image.shape[2]
        gather = (self.gather and not (hw or tiled) and mesh is None and order == 1
                  and mode in HW_MODES)
        # 3-channel pictures read back as RGB32UI texels (see readback). The
        # warp shader packs its own pixels where its per-pixel code is short
        # (FPI-like maps, order <= 1), else a pass packs them: a shader that
        # inlines FPW_PACK_PIXELS copies of a TPS or cubic sampling compiles
        # for seconds on llvmpipe.
        packs = (c == 3 and self.pack_rgb and not tiled and mesh is None and order <= 1 and self.short_map
                 and not antialias)
        integer = image.dtype.kind == "u"
        if tiled:
            output = "accumulate"
        elif packs:
            output = None
        else:
            output = "int" if integer else "float"
        key = ProgramKey(FULLSCREEN, glsl.WARP_FRAG, stages=stages, order=order, mode=mode,
                         source="hw" if hw else SOURCE_KINDS[image.dtype], gather_channels=c if gather else 0,
                         output=output, pack_pixels=readback.pixels_per_texel(image.dtype) if packs else 0,
                         flags=(("FPW_ANTIALIAS",) if antialias else ())
                         + coarse.flags(seeded and self.newton_map and mesh is None and not tiled, antialias))
        if mesh is None:
            return key, None, packs
        fill = key.with_changes(stages=None, output="fill_int" if integer else "fill")
        return key.with_changes(vertex=glsl.MESH_VERT, fragment=glsl.MESH_FRAG), fill, False

    def _render_bound(self, image, output_shape, order, mode, cval, mesh, hardware_filter, stages, antialias=False,
                      out=None):
        h, w, c = image.shape
        oh, ow = (int(v) for v in output_shape)
        if out is None:
            out = np.empty((oh, ow, c), dtype=image.dtype)
        elif out.shape != (oh, ow, c) or out.dtype != image.dtype or not out.flags.c_contiguous:
            raise ValueError(f"out must be a C-contiguous {(oh, ow, c)} {image.dtype} array, "
                             f"got {out.shape} {out.dtype}")
        tiled = h > self.max_size or w > self.max_size or antialias and max(atlas_layout(h, w)[0]) > self.max_size
        hw = hardware_filter and not tiled
        seeded = coarse.chosen(self, (oh, ow))
        key, fill_key, packs = self._program_keys(image, order, mode, mesh, hw, tiled, stages, antialias, seeded)
        prog = self.program(key)
        top = float(np.iinfo(image.dtype).max) if image.dtype.kind == "u" else 0.0
        cval4 = tuple(np.resize(cval, 4).astype(float))
        set_uniform(prog, "fpw_src_size", (w, h))
        set_uniform(prog, "fpw_cval", cval4)
        set_uniform(prog, "fpw_top", top)
        set_uniform(prog, "fpw_out_scale", 1.0)
        fill = None
        if mesh is not None:
            fill = self.program(fill_key)
            set_uniform(fill, "fpw_cval", cval4)
            set_uniform(fill, "fpw_top", top)
            set_uniform(fill, "fpw_out_scale", 1.0)
            vao = mesh.vao(prog)

            def draw():
                draw_culled_mesh(self.ctx, vao)
        else:
            vao = self.fullscreen_vao(prog)

            def draw():
                vao.render(moderngl.TRIANGLES, vertices=3)
            if coarse.FLAG in key.flags:
                draw = coarse.seeded_draw(self, prog, stages, band.split(self, key, prog, draw))
        try:
            if tiled:
                atlas = None
                if antialias:
                    atlas, rects = self.pyramids.host(image)
                    set_pyramid_values(prog, rects)
                render_tiled_source(self, image, out, prog, draw, cval, covers=mesh is not None, atlas=atlas)
            else:
                src = self._upload_source(prog, image, hw, order, mode, cval, antialias)
                src.use(0)
                if antialias and not hw:
                    self.bind_pyramid(prog, image)
                for y0, y1 in tiles(oh, self.max_size):
                    for x0, x1 in tiles(ow, self.max_size):
                        self._draw_tile(image, out, (prog, fill), draw, (x0, y0, x1, y1), packs)
        finally:
            self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
            if hw:  # unbind the sampler object: unit 0 uses texture state again
                self.targets.get("sampler").clear(0)
        return out

    def bind_pyramid(self, prog, image):
        """Bind the antialiasing pyramid of ``image`` (built once per its
        pixels) for ``prog``."""
        tex, rects = self.pyramids.texture(image)
        tex.use(PYRAMID_UNIT)
        set_pyramid_values(prog, rects)

    # ---- for batches (fpiwarp.backends.gl.batch)
    def warp_program_key(self, image, order, mode, stages, antialias=False, seeded=False):
        """(key, packs) of the per-pixel warp program that :meth:`warp_block`
        uses for an untiled ``image`` with software sampling, after
        :meth:`set_map` (or ``short_map`` and ``newton_map`` set) for a block
        of kind ``stages``; ``seeded``: with the coarse pass where it takes it."""
        key, _, packs = self._program_keys(image, order, mode, None, False, False, stages, antialias, seeded=seeded)
        return key, packs

    def draw_tile(self, image, out, prog, draw, box, packs=False, full=None):
        """Render output pixels box = (x0, y0, x1, y1) of ``out`` by ``draw``
        (the warp program ``prog``) and read them back (see :meth:`warp_block`),
        in targets of (w, h) = ``full`` (default: ``out``'s, up to the size limit)."""
        self._draw_tile(image, out, (prog, None), draw, box, packs, full)

    def _upload_source(self, prog, image, hw, order, mode, cval, mipmaps=False):
        """The source texture (bound by the caller to unit 0); for the
        hardware filter also its sampler object, bound here. ``mipmaps``
        (hardware filter with antialiasing): the source's mipmapped
        texture, kept across calls, sampled trilinearly and anisotropically
        below level 0 and by the plain filter (``order``) at level 0."""
        h, w, c = image.shape
        if hw:
            dt, scale = HW_DTYPES[image.dtype]
            if mipmaps:
                tex = self.pyramids.mipmapped(image, dt)
            else:
                tex = self.targets.texture("src_hw", (w, h), c, dt)
                tex.write(image)
            set_uniform(prog, "fpw_hw_scale", scale)
            filt = moderngl.NEAREST if order == 0 else moderngl.LINEAR
            border = tuple(np.resize(cval / scale, 4)) if mode == "constant" else None
            repeat = mode == "wrap"
            minify = moderngl.LINEAR_MIPMAP_LINEAR if mipmaps else filt
            aniso = self.anisotropy if mipmaps else 1.0

            def make():
                sampler = self.ctx.sampler(repeat_x=repeat, repeat_y=repeat, filter=(minify, filt),
                                           border_color=border)
                sampler.anisotropy = aniso
                return sampler
            sampler = self.targets.cached("sampler", (order, mode, border, mipmaps, aniso), make)
            sampler.use(0)
            return tex
        tex = self.targets.texture("src", (w, h), c, SOURCE_TEXTURE_DTYPES[image.dtype])
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        # where textureGather places the taps (FPW_GATHER; texelFetch ignores it)
        tex.repeat_x = tex.repeat_y = mode == "wrap"
        tex.write(image)
        return tex

    def _draw_tile(self, image, out, progs, draw, box, packs=False, full=None):
        """Render output pixels box = (x0, y0, x1, y1) and read them back.
        ``progs``: (the warp or mesh program, the mesh's fill pass or None);
        ``packs``: the warp program writes packed RGB32UI texels."""
        x0, y0, x1, y1 = box
        c = image.shape[2]
        size = (x1 - x0, y1 - y0)
        if full is None:
            full = (min(out.shape[1], self.max_size), min(out.shape[0], self.max_size))
        dest = out[y0:y1, x0:x1]
        self.set_view(progs, (x0, y0), size)
        if packs:
            packed = readback.draw_packed(self.targets, draw, full, size, image.dtype)
            readback.read_packed(packed, size, image.dtype, dest)
            return
        fbo = self.targets.target("out", full, readback.channels_format(c), readback.TEXTURE_DTYPES[image.dtype])
        fbo.viewport = (0, 0) + size
        fbo.use()
        fill = progs[1]
        if fill is not None:
            self.fullscreen_vao(fill).render(moderngl.TRIANGLES, vertices=3)
        draw()
        if c == 3 and self.pack_rgb:
            pack = self.program(ProgramKey(FULLSCREEN, glsl.PACK_RGB_FRAG,
                                           pack_pixels=readback.pixels_per_texel(image.dtype),
                                           flags=("FPW_PACK_FLOAT",) if image.dtype.kind == "f" else (),
                                           samples=False))
            fbo.color_attachments[0].use(1)
            set_uniform(pack, "fpw_unpacked", 1)
            vao = self.fullscreen_vao(pack)
            packed = readback.draw_packed(self.targets, lambda: vao.render(moderngl.TRIANGLES, vertices=3),
                                          full, size, image.dtype)
            readback.read_packed(packed, size, image.dtype, dest)
        else:
            readback.read_direct(fbo, size, dest)
