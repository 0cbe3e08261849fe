"""The "gl" backend: GLSL shaders through moderngl, headless through EGL.

Three paths share one shader include (``glsl/fpiwarp_map.glsl``), which
mirrors :func:`fpiwarp.params.evaluate` and :mod:`fpiwarp._sampling`:

* ``map_points``: a vertex shader evaluates the parameter block per point,
  captured by transform feedback;
* ``warp_image``: a full-screen fragment shader evaluates the block of
  ``transform.inverse`` per output pixel and samples the source in
  software (``texelFetch`` of unfiltered texels, float weights; uint16 as
  an integer texture, uint8 as a normalized one scaled back by 255, the
  fastest format of software rasterizers), rounding in the shader into an
  integer framebuffer, so results match the numpy reference;
  ``hardware_filter=True`` lets the texture unit filter instead (GL
  quantizes the weights). What makes it fast on Mesa's llvmpipe, which
  runs it on the CPU: per-draw values reach the fragment stage as flat
  varyings rather than uniforms (:func:`forward_uniforms`), order 1 reads
  one textureGather per channel instead of a texelFetch per tap, and
  3-channel pictures come back as packed RGB32UI texels (a copy; the
  driver's RGB readback converts every pixel, very slowly on NVIDIA's);
* :func:`warp_image_mesh`: the paper's own way, a triangulated grid of the
  source deformed per vertex by the forward map and rasterized with
  texture mapping (no inverse needed).

The map's block goes into a uniform block of ``vec4`` rows; programs are
compiled once per kind (kind of map, see :func:`map_kind`; sampler type,
order, mode, output kind) and cached, so a new map of the same kind (an
FPI with moved corners) only re-uploads the block. Sources and outputs larger than the
maximum texture size are tiled: outputs by rendering one viewport-sized
tile at a time, sources by summing one pass per source tile into a float
accumulator (each tap belongs to exactly one tile), so there is no size
limit. :class:`GLWarper` takes any moderngl context, a caller's too; it
binds its own framebuffers and leaves blending, culling and clip distance
0 disabled. Output pixel centers are at integers: a fragment's output
position is ``view.xy + view.zw * (gl_FragCoord.xy - 0.5)`` (warp.frag),
and with ``view = (x0, y0, 1, 1)`` window row j is image row y0 + j, so
the readback (bottom row first) comes out top-down, no flip needed.
A GL context belongs to the thread that created it: use a warper from that
thread.
"""

import re
import sys
import threading

import moderngl  # missing: the registry reports "cannot import moderngl"
import numpy as np

from .. import params as P
from .._sampling import COORD_LIMIT, MODES, ORDERS, to_dtype
from ..resources import source

#: GLSL version of the shader files; the context must provide at least this.
GL_REQUIRE = 330
#: Points per transform-feedback draw in map_points (bounds buffer sizes).
POINT_CHUNK = 1 << 20
MAX_ROWS = 1 + P.MAX_STAGES * P.STAGE_ROWS
GL_CLIP_DISTANCE0 = 0x3000
#: The full-screen vertex shader, which forwards per-draw values to the
#: fragment stage as flat varyings (see :func:`forward_uniforms`).
FULLSCREEN = "fullscreen.vert"
#: Rows per stage a full-screen pass forwards: ROW_PRE .. ROW_L3, all an FPI reads.
HOT_ROWS = P.ROW_L3 - P.ROW_PRE + 1

# Output attachments: integer formats for integer images (exact rounding in
# the shader), float32 for float32.
_TEXTURE_DTYPES = {np.dtype(np.uint8): "u1", np.dtype(np.uint16): "u2", np.dtype(np.float32): "f4"}
# Sources for software sampling: (texture dtype, define). uint8 reads fastest
# as a normalized texture (texel v -> v / 255, scaled back in the shader);
# uint16 as an integer texture (exact); float32 as is.
_SOURCE_FORMATS = {np.dtype(np.uint8): ("f1", "FPW_UNORM_TEXTURE 255.0"),
                   np.dtype(np.uint16): ("u2", "FPW_INT_TEXTURE"),
                   np.dtype(np.float32): ("f4", None)}
# Normalized textures for the hardware-filtered option, and their scale.
_HW_DTYPES = {np.dtype(np.uint8): ("f1", 255.0), np.dtype(np.uint16): ("nu2", 65535.0),
              np.dtype(np.float32): ("f4", 1.0)}
_HW_MODES = ("constant", "edge", "wrap")


# ---------------------------------------------------------------- context
_shared = {}


def create_context():
    """A new standalone (offscreen) moderngl context: EGL first (headless,
    Mesa's llvmpipe without a GPU), then the platform's default."""
    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            return moderngl.create_standalone_context(require=GL_REQUIRE, **kwargs)
        except Exception as exc:  # noqa: BLE001 - each platform fails in its own way
            errors.append(f"{kwargs.get('backend', 'default')}: {exc}".strip())
    version = f"{GL_REQUIRE // 100}.{GL_REQUIRE % 100 // 10}"
    raise RuntimeError(f"no OpenGL {version} context: " + "; ".join(errors))


def shared_context():
    """The process-wide context of the backend, created once (an error too)."""
    if "ctx" not in _shared:
        _shared["thread"] = threading.get_ident()
        try:
            _shared["ctx"] = create_context()
        except RuntimeError as exc:
            _shared["ctx"] = None
            _shared["error"] = str(exc)
    if _shared["ctx"] is None:
        raise RuntimeError(_shared["error"])
    return _shared["ctx"]


def check_thread():
    """Raise unless called from the thread that created the shared context:
    a GL context is current in one thread only, and drawing from another
    would silently give wrong pictures."""
    owner = _shared.get("thread")
    if owner is not None and owner != threading.get_ident():
        raise RuntimeError(
            "the gl backend's OpenGL context belongs to the thread that created it; "
            "call the gl backend from that thread (e.g. the main thread)"
        )


def probe():
    """None when a GL context can be created here, else the reason."""
    try:
        ctx = shared_context()
    except RuntimeError as exc:
        return " ".join(str(exc).split())[:300]
    if ctx.version_code < GL_REQUIRE:  # pragma: no cover - require= already checks
        return f"OpenGL {ctx.version_code} is older than {GL_REQUIRE}"
    return None


# ---------------------------------------------------------------- shaders
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


def shader_source(name, defines=()):
    """The text of ``glsl/name`` with ``#include "..."`` expanded and the
    block layout constants (from :mod:`fpiwarp.params`) plus ``defines``
    inserted after the ``#version`` line."""
    text = source("glsl", name)
    for _ in range(4):  # includes may include (a few levels)
        text = _INCLUDE.sub(lambda m: source("glsl", m.group(1)), text)
    if _INCLUDE.search(text):
        raise ValueError(f"glsl/{name}: #include nested too deeply")
    consts = {
        "FPW_MAX_ROWS": MAX_ROWS,
        "FPW_STAGE_ROWS": P.STAGE_ROWS,
        "FPW_ROW_HEADER": P.ROW_HEADER,
        "FPW_ROW_PRE": P.ROW_PRE,
        "FPW_ROW_SCALE": P.ROW_SCALE,
        "FPW_ROW_POST": P.ROW_POST,
        "FPW_ROW_L12": P.ROW_L12,
        "FPW_ROW_L3": P.ROW_L3,
        "FPW_ROW_MU12": P.ROW_MU12,
        "FPW_ROW_MU3": P.ROW_MU3,
        "FPW_ROW_REGIONS": P.ROW_REGIONS,
        "FPW_ROW_CENTERS": P.ROW_CENTERS,
        "FPW_CORE_AFFINE": P.CORE_AFFINE,
        "FPW_CORE_TPS": P.CORE_TPS,
        "FPW_COORD_LIMIT": f"{COORD_LIMIT:.1f}",
        "FPW_HOT_ROWS": HOT_ROWS,
    }
    lines = [f"#define {k} {v}" for k, v in consts.items()]
    for d in defines:
        lines.append("#define " + (d if isinstance(d, str) else f"{d[0]} {d[1]}"))
    head, sep, rest = text.partition("\n")
    if not head.startswith("#version"):
        raise ValueError(f"glsl/{name} must start with a #version line")
    return head + sep + "\n".join(lines) + "\n#line 2\n" + rest


# A plain uniform of a fragment shader: scalar or vector (not a sampler, a
# block or an array), one declaration per line.
_UNIFORM_DECL = re.compile(r"^[ \t]*uniform[ \t]+(float|int|uint|[iu]?vec[234])[ \t]+(\w+)[ \t]*;.*$", re.MULTILINE)


def forward_uniforms(fragment_text):
    """Turn a fragment shader's plain uniforms into flat inputs.

    Each ``uniform T name;`` becomes ``flat in T name_fpwv;`` with
    ``#define name name_fpwv``, so the shader's code is unchanged. Returns
    the new text and the defines that make :data:`FULLSCREEN` declare the
    uniforms under their own names (the host sets them as before) and copy
    them to those outputs: ``(text, defines, n_forwarded)``. Values are
    passed exactly (flat, no interpolation).
    """
    decls = list({n: (t, n) for t, n in _UNIFORM_DECL.findall(fragment_text)}.values())  # once each (#if branches)
    text = _UNIFORM_DECL.sub(lambda m: f"flat in {m[1]} {m[2]}_fpwv;\n#define {m[2]} {m[2]}_fpwv", fragment_text)
    if not decls:
        return text, (), 0
    declare = " ".join(f"uniform {t} {n}; flat out {t} {n}_fpwv;" for t, n in decls)
    copy = " ".join(f"{n}_fpwv = {n};" for _, n in decls)
    return text, (f"FPW_FORWARD_DECLS {declare}", f"FPW_FORWARD {copy}"), len(decls)


def stage_kinds(block):
    """(core, number of regions) of each stage of a parameter block."""
    block = np.asarray(block)
    rows = [block[1 + k * P.STAGE_ROWS + P.ROW_HEADER] for k in range(P.n_stages(block))]
    return [(int(row[0]), int(row[2])) for row in rows]


def map_kind(block):
    """The ``FPW_STAGES`` define that specializes a program to the kind of
    map in ``block``: its number of stages and each stage's core and number
    of regions. Values (quad corners, TPS weights, ...) stay in the block, so
    every FPI shares one program, and moving points never recompiles."""
    calls = [f"z = fpw_stage_of(z, {1 + k * P.STAGE_ROWS}, {core}, {n_regions});"
             for k, (core, n_regions) in enumerate(stage_kinds(block))]
    return "FPW_STAGES " + " ".join(calls)


def is_short_map(block):
    """Whether every stage of the block has the affine core and no regions
    (FPIs, Möbius and R-linear maps and their compounds): a few dozen
    operations per pixel, cheap to inline several times in one shader."""
    return all(core == P.CORE_AFFINE and n_regions == 0 for core, n_regions in stage_kinds(block))


def set_uniform(prog, name, value):
    """Set a uniform if the compiler kept it (unused ones are dropped)."""
    member = prog.get(name, None)
    if member is not None:
        member.value = value


def _pixels_per_texel(dtype):
    """Pixels of 3 channels of ``dtype`` in one 12-byte RGB32UI texel."""
    return 4 // np.dtype(dtype).itemsize


def _channels_format(c):
    """Components of a renderable output attachment for c channels (RGB
    integer formats need not be renderable: use RGBA and read back 3)."""
    return 4 if c == 3 else c


def _tiles(n, size):
    return [(a, min(n, a + size)) for a in range(0, n, size)]


# ---------------------------------------------------------------- warper
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
        Compile one program per kind of map (see :func:`map_kind`), several
        times faster on software rasterizers; False: one program reads the
        kind from the block at run time and serves every map.
    gather : bool, optional
        Sample order 1 ('constant', 'edge', 'wrap') with one textureGather
        per channel instead of one texelFetch per tap: same values, fewer
        texture calls. Default: where the context has GL_ARB_gpu_shader5.
    pack_rgb : bool, optional
        Read 3-channel pictures back as packed RGB32UI texels, written by
        the warp shader itself for FPI-like maps at order <= 1 and by a
        pass (``glsl/pack_rgb.frag``) otherwise: a copy instead of the
        driver's per-pixel conversion. Default: on little-endian hosts whose
        driver renders into RGB32UI (GL does not require it; llvmpipe and
        NVIDIA's driver do).
    """

    def __init__(self, ctx=None, max_texture_size=None, ubo_binding=0, specialize=True, gather=None,
                 pack_rgb=None):
        self.ctx = ctx if ctx is not None else create_context()
        limits = [self.ctx.info["GL_MAX_TEXTURE_SIZE"], self.ctx.info.get("GL_MAX_RENDERBUFFER_SIZE") or 1 << 30]
        limits += list(self.ctx.info.get("GL_MAX_VIEWPORT_DIMS") or ())
        self.max_size = int(min(limits))
        if max_texture_size is not None:
            if int(max_texture_size) < 4:
                raise ValueError(f"max_texture_size must be >= 4, got {max_texture_size}")
            self.max_size = min(self.max_size, int(max_texture_size))
        info = self.ctx.info
        components = [info.get("GL_MAX_FRAGMENT_INPUT_COMPONENTS") or 60,
                      info.get("GL_MAX_VERTEX_OUTPUT_COMPONENTS") or 60]
        if info.get("GL_MAX_VARYING_VECTORS"):
            components.append(4 * info["GL_MAX_VARYING_VECTORS"])
        #: vec4 slots between the vertex and fragment stages
        self.varying_slots = min(components) // 4
        self.ubo_binding = ubo_binding
        self.specialize = specialize
        if gather is None:
            gather = "GL_ARB_gpu_shader5" in self.ctx.extensions  # what the #version 330 shader requires
        self.gather = bool(gather)
        if pack_rgb is None:
            pack_rgb = sys.byteorder == "little" and _renders_rgb32ui(self.ctx)
        self.pack_rgb = bool(pack_rgb)
        self.ubo = self.ctx.buffer(reserve=MAX_ROWS * 16)
        self.compile_count = 0  # programs built so far (one per kind)
        self.short_map = False  # set by set_map
        self._programs = {}
        self._cache = {}  # role -> (key, object): textures and framebuffers reused between calls
        self._vao_empty = {}
        self._dummy = self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer((1, 1))])

    # ---- resources
    def program(self, vertex, fragment=None, defines=(), varyings=()):
        """The compiled program for this kind, built on first use only."""
        defines = tuple(defines)
        key = (vertex, fragment, defines, tuple(varyings))
        prog = self._programs.get(key)
        if prog is None:
            vs_defines, fs_defines = defines, ("FPW_WITH_SAMPLER",) + defines
            fs = shader_source(fragment, fs_defines) if fragment else None
            if fragment and vertex == FULLSCREEN:
                vs, fs = self._flat_values(fragment, vs_defines, fs_defines)
            else:
                vs = shader_source(vertex, vs_defines)
            prog = self.ctx.program(vertex_shader=vs, fragment_shader=fs, varyings=list(varyings))
            block = prog.get("FpiwarpParams", None)
            if block is not None:
                block.binding = self.ubo_binding
            set_uniform(prog, "fpw_src", 0)
            self._programs[key] = prog
            self.compile_count += 1
        return prog

    def _flat_values(self, fragment, vs_defines, fs_defines):
        """Sources of a full-screen pass whose fragment stage reads its
        per-draw values as flat varyings (see glsl/fullscreen.vert): its
        uniforms, and the FPI rows of as many stages as the varying slots
        hold. Plain uniforms when even the first do not fit."""
        text, _, n = forward_uniforms(shader_source(fragment, fs_defines))
        # a slot each, at worst, counting uniforms of inactive #if branches
        # too (conservative); one for gl_Position
        free = self.varying_slots - 1 - n
        if free < 0:
            return shader_source(FULLSCREEN, vs_defines), shader_source(fragment, fs_defines)
        stages = " ".join(d for d in fs_defines if isinstance(d, str) and d.startswith("FPW_STAGES "))
        hot = min(stages.count("fpw_stage_of("), free // HOT_ROWS)
        extra = (f"FPW_HOT_STAGES {hot}",) if hot else ()
        text, forward, _ = forward_uniforms(shader_source(fragment, fs_defines + extra))
        return shader_source(FULLSCREEN, vs_defines + extra + forward), text

    def set_map(self, block):
        """Upload a parameter block (``Transform.params()``): values only.
        Returns the defines of its kind, for :meth:`program`."""
        block = np.ascontiguousarray(block, dtype=np.float32)
        if block.ndim != 2 or block.shape[1] != 4 or not 1 <= block.shape[0] <= MAX_ROWS:
            raise ValueError(f"a parameter block is (rows <= {MAX_ROWS}, 4) float32, got {block.shape}")
        if block.shape[0] != 1 + P.n_stages(block) * P.STAGE_ROWS:
            raise ValueError("parameter block rows do not match its header's number of stages")
        self.ubo.write(block.tobytes())
        self.ubo.bind_to_uniform_block(self.ubo_binding)
        #: the block just uploaded is a specialized short map (see is_short_map)
        self.short_map = self.specialize and is_short_map(block)
        return (map_kind(block),) if self.specialize else ()

    def _cached(self, role, key, make):
        old = self._cache.get(role)
        if old is not None and old[0] == key:
            return old[1]
        if old is not None:
            _release(old[1], self._dummy)
        obj = make()
        self._cache[role] = (key, obj)
        return obj

    def _texture(self, role, size, components, dtype):
        return self._cached(role, (size, components, dtype),
                            lambda: self.ctx.texture(size, components, dtype=dtype))

    def _target(self, role, size, components, dtype, cover=False):
        """A framebuffer with one color texture (and a coverage one)."""
        def make():
            tex = [self.ctx.texture(size, components, dtype=dtype)]
            if cover:
                tex.append(self.ctx.texture(size, 1, dtype="f4"))
            return self.ctx.framebuffer(color_attachments=tex)
        return self._cached(role, (size, components, dtype, cover), make)

    def _owns(self, fbo):
        """Whether ``fbo`` is one of this warper's framebuffers."""
        return fbo is self._dummy or any(fbo is obj for _, obj in self._cache.values())

    def fullscreen_vao(self, prog):
        """The attribute-less vertex array that draws ``prog`` (with
        fullscreen.vert) over the viewport: ``.render(TRIANGLES, vertices=3)``."""
        vao = self._vao_empty.get(id(prog))
        if vao is None:
            vao = self._vao_empty[id(prog)] = self.ctx.vertex_array(prog, [])
        return vao

    def release(self):
        """Free the GL objects made here (not the context). The caller's
        framebuffer stays bound; where one of these was, framebuffer 0 is
        (a deleted one left bound breaks the next framebuffer moderngl makes)."""
        bound = bound_framebuffer(self.ctx)
        if self._owns(bound):
            bound = self.ctx.detect_framebuffer(0)
        for _, obj in self._cache.values():
            _release(obj, self._dummy)
        self._cache.clear()
        for vao in self._vao_empty.values():
            vao.release()
        self._vao_empty.clear()
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
        self.ubo.release()
        bound.use()
        self._dummy.release()

    # ---- per vertex
    def map_points(self, transform, points):
        """Map float64 (..., 2) points by transform feedback; float64 out."""
        pts = np.asarray(points, dtype=np.float64)
        flat = pts.reshape(-1, 2)
        out = np.empty_like(flat)
        if flat.shape[0] == 0:
            return out.reshape(pts.shape)
        kind = self.set_map(transform.params())
        prog = self.program("map_points.vert", defines=kind, varyings=("fpw_mapped",))
        self._dummy.use()  # without a bound framebuffer (surfaceless EGL) nothing is captured
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
        return out.reshape(pts.shape)

    # ---- per pixel
    def warp_image(self, image, transform, output_shape, *, order=1, mode="constant", cval=None,
                   hardware_filter=False):
        """Backward warp of a validated (H, W, C) image (see fpiwarp.warp_image).

        ``hardware_filter=True`` lets the texture unit interpolate (orders
        0 and 1, modes constant/edge/wrap): faster, but bilinear weights are
        quantized by the hardware, so results may differ from the reference
        by a level or so. Sources above the size limit use the software path.
        """
        image, cval = _check_args(image, order, mode, cval)
        if hardware_filter:
            if order not in (0, 1):
                raise ValueError(f"hardware_filter supports order 0 or 1, got {order}")
            if mode not in _HW_MODES:
                raise ValueError(f"hardware_filter supports modes {_HW_MODES}, got {mode!r}")
        map_kind_ = self.set_map(transform.inverse.params())
        return self._render(image, output_shape, order, mode, cval, "warp", hardware_filter, map_kind_)

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
        image, cval = _check_args(image, order, mode, cval)
        verts, tris = grid_mesh(image.shape, grid_step, vertices, triangles)
        map_kind_ = self.set_map(transform.params())
        vbo = self.ctx.buffer(verts.astype(np.float32).tobytes())
        ibo = self.ctx.buffer(tris.astype(np.int32).tobytes())
        try:
            return self._render(image, output_shape, order, mode, cval, ("mesh", vbo, ibo), False, map_kind_)
        finally:
            vbo.release()
            ibo.release()

    # ---- shared rendering
    def _render(self, image, output_shape, order, mode, cval, path, hardware_filter, map_kind_):
        caller = bound_framebuffer(self.ctx)
        if self._owns(caller):
            caller = None  # ours (perhaps replaced below): nothing to give back
        try:
            return self._render_bound(image, output_shape, order, mode, cval, path, hardware_filter, map_kind_)
        finally:
            if caller is not None:
                caller.use()  # a caller drawing into its own framebuffer keeps it bound

    def _render_bound(self, image, output_shape, order, mode, cval, path, hardware_filter, map_kind_):
        h, w, c = image.shape
        oh, ow = (int(v) for v in output_shape)
        out = np.empty((oh, ow, c), dtype=image.dtype)
        tiled = h > self.max_size or w > self.max_size
        hw = hardware_filter and not tiled
        kind = [f"FPW_ORDER {order}", f"FPW_MODE {MODES.index(mode)}", *map_kind_]
        gather = self.gather and not (hw or tiled) and path == "warp" and order == 1 and mode in _HW_MODES
        if hw:
            kind.append("FPW_HW_FILTER")
        elif _SOURCE_FORMATS[image.dtype][1]:
            kind.append(_SOURCE_FORMATS[image.dtype][1])
        if gather:
            kind += ["FPW_GATHER", f"FPW_CHANNELS {c}"]
        mesh = path != "warp"
        # 3-channel pictures read back as RGB32UI texels (see glsl/pack_rgb.frag).
        # The warp shader packs its own pixels where its per-pixel code is
        # short (FPI-like maps, order <= 1), else a pass packs them: a shader
        # that inlines FPW_PACK_PIXELS copies of a TPS or cubic sampling
        # compiles for seconds on llvmpipe.
        packs = (c == 3 and self.pack_rgb and not tiled and not mesh and order <= 1
                 and self.short_map)
        if tiled:
            kind += ["FPW_TILED", "FPW_ACCUMULATE"]
        elif packs:
            kind.append(f"FPW_PACK_PIXELS {_pixels_per_texel(image.dtype)}")
        elif image.dtype.kind == "u":
            kind.append("FPW_OUT_INT")
        prog = self.program("mesh.vert", "mesh.frag", kind) if mesh else self.program(
            "fullscreen.vert", "warp.frag", kind)
        set_uniform(prog, "fpw_src_size", (w, h))
        set_uniform(prog, "fpw_cval", tuple(np.resize(cval, 4).astype(float)))
        set_uniform(prog, "fpw_top", float(np.iinfo(image.dtype).max) if image.dtype.kind == "u" else 0.0)
        set_uniform(prog, "fpw_out_scale", 1.0)
        fill = None
        if mesh:
            fill_kind = [k for k in kind if k not in ("FPW_TILED", "FPW_ACCUMULATE")
                         and not k.startswith("FPW_STAGES")] + ["FPW_FILL"]
            if "FPW_OUT_INT" not in fill_kind and image.dtype.kind == "u":
                fill_kind.append("FPW_OUT_INT")
            fill = self.program("fullscreen.vert", "warp.frag", fill_kind)
            set_uniform(fill, "fpw_cval", tuple(np.resize(cval, 4).astype(float)))
            set_uniform(fill, "fpw_top", float(np.iinfo(image.dtype).max) if image.dtype.kind == "u" else 0.0)
            set_uniform(fill, "fpw_out_scale", 1.0)
            vao = self.ctx.vertex_array(prog, [(path[1], "2f", "fpw_vertex")], index_buffer=path[2])
        else:
            vao = self.fullscreen_vao(prog)
        try:
            if tiled:
                self._render_tiled(image, out, prog, vao, fill, cval)
            else:
                src = self._upload_source(prog, image, hw, order, mode, cval)
                src.use(0)
                for y0, y1 in _tiles(oh, self.max_size):
                    for x0, x1 in _tiles(ow, self.max_size):
                        self._draw_tile(image, out, prog, vao, fill, (x0, y0, x1, y1), packs)
        finally:
            if mesh:
                vao.release()
            self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
            if hw:  # unbind the sampler object: unit 0 uses texture state again
                self._cache["sampler"][1].clear(0)
        return out

    def _upload_source(self, prog, image, hw, order, mode, cval):
        h, w, c = image.shape
        if hw:
            dt, scale = _HW_DTYPES[image.dtype]
            tex = self._texture("src_hw", (w, h), c, dt)
            tex.write(image)
            set_uniform(prog, "fpw_hw_scale", scale)
            filt = moderngl.NEAREST if order == 0 else moderngl.LINEAR
            border = tuple(np.resize(cval / scale, 4)) if mode == "constant" else None
            repeat = mode == "wrap"
            sampler = self._cached("sampler", (order, mode, border), lambda: self.ctx.sampler(
                repeat_x=repeat, repeat_y=repeat, filter=(filt, filt), border_color=border))
            sampler.use(0)
            return tex
        tex = self._texture("src", (w, h), c, _SOURCE_FORMATS[image.dtype][0])
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        # where textureGather places the taps (FPW_GATHER; texelFetch ignores it)
        tex.repeat_x = tex.repeat_y = mode == "wrap"
        tex.write(image)
        return tex

    def _draw_tile(self, image, out, prog, vao, fill, box, packs=False):
        """Render output pixels box = (x0, y0, x1, y1) and read them back;
        ``packs``: ``prog`` writes packed RGB32UI texels (FPW_PACK_PIXELS)."""
        x0, y0, x1, y1 = box
        c = image.shape[2]
        size = (x1 - x0, y1 - y0)
        dt = _TEXTURE_DTYPES[image.dtype]
        full = (min(out.shape[1], self.max_size), min(out.shape[0], self.max_size))
        dest = out[y0:y1, x0:x1]
        self._view(prog, fill, (x0, y0), size)
        if packs:
            self._read_packed(self._draw_packed(lambda: vao.render(moderngl.TRIANGLES, vertices=3), full, size,
                                                image.dtype), size, image.dtype, dest)
            return
        fbo = self._target("out", full, _channels_format(c), dt)
        fbo.viewport = (0, 0) + size
        fbo.use()
        if fill is not None:
            self.fullscreen_vao(fill).render(moderngl.TRIANGLES, vertices=3)
            self._draw_mesh(vao)
        else:
            vao.render(moderngl.TRIANGLES, vertices=3)
        if c == 3 and self.pack_rgb:
            prog = self.program(FULLSCREEN, "pack_rgb.frag", (f"FPW_PACK_PIXELS {_pixels_per_texel(image.dtype)}",)
                                + (("FPW_PACK_FLOAT",) if image.dtype.kind == "f" else ()))
            fbo.color_attachments[0].use(1)
            set_uniform(prog, "fpw_unpacked", 1)
            packed = self._draw_packed(lambda: self.fullscreen_vao(prog).render(moderngl.TRIANGLES, vertices=3),
                                       full, size, image.dtype)
            self._read_packed(packed, size, image.dtype, dest)
        elif dest.flags.c_contiguous:
            fbo.read_into(dest, viewport=(0, 0) + size, components=c, dtype=dt, alignment=1)
        else:
            data = fbo.read(viewport=(0, 0) + size, components=c, dtype=dt, alignment=1)
            dest[...] = np.frombuffer(data, dtype=image.dtype).reshape(dest.shape)

    def _draw_packed(self, draw, full, size, dtype):
        """Run ``draw`` into the RGB32UI target that holds a (w, h) picture
        of 3 channels of ``dtype`` packed (see glsl/pack.glsl); return it."""
        per = _pixels_per_texel(dtype)
        packed = self._target("packed", (-(-full[0] // per), full[1]), 3, "u4")
        packed.viewport = (0, 0, -(-size[0] // per), size[1])
        packed.use()
        draw()
        return packed

    def _read_packed(self, packed, size, dtype, dest):
        """Read a packed (w, h) picture into ``dest`` (a copy: no per-pixel
        conversion by the driver); columns past w are padding."""
        w, h = size
        per = _pixels_per_texel(dtype)
        pw = -(-w // per)
        if pw * per == w and dest.flags.c_contiguous:
            packed.read_into(dest, viewport=(0, 0, pw, h), components=3, dtype="u4", alignment=1)
        else:
            rows = np.empty((h, pw * per, 3), dtype=dtype)
            packed.read_into(rows, viewport=(0, 0, pw, h), components=3, dtype="u4", alignment=1)
            dest[...] = rows[:, :w]

    def _render_tiled(self, image, out, prog, vao, fill, cval):
        """Source above the size limit: per output tile, sum one additive
        pass per source tile into float32, then round on the host."""
        h, w, c = image.shape
        oh, ow = out.shape[:2]
        full = (min(ow, self.max_size), min(oh, self.max_size))
        fbo = self._target("acc", full, 4, "f4", cover=fill is not None)
        src_tiles = [(x0, y0, x1, y1) for y0, y1 in _tiles(h, self.max_size) for x0, x1 in _tiles(w, self.max_size)]
        dt = _SOURCE_FORMATS[image.dtype][0]
        for oy0, oy1 in _tiles(oh, self.max_size):
            for ox0, ox1 in _tiles(ow, self.max_size):
                size = (ox1 - ox0, oy1 - oy0)
                fbo.viewport = (0, 0) + size
                fbo.use()
                fbo.clear(0.0, 0.0, 0.0, 0.0)
                self._view(prog, None, (ox0, oy0), size)
                self.ctx.enable(moderngl.BLEND)
                self.ctx.blend_func = moderngl.ONE, moderngl.ONE
                self.ctx.blend_equation = moderngl.FUNC_ADD
                tex = self._texture("src_tile", (self.max_size, self.max_size), c, dt)
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
                tex.use(0)
                for i, (x0, y0, x1, y1) in enumerate(src_tiles):
                    tex.write(np.ascontiguousarray(image[y0:y1, x0:x1]), viewport=(0, 0, x1 - x0, y1 - y0))
                    set_uniform(prog, "fpw_tile", (x0, y0, x1 - x0, y1 - y0))
                    set_uniform(prog, "fpw_primary", 1 if i == 0 else 0)
                    if fill is not None:
                        self._draw_mesh(vao)
                    else:
                        vao.render(moderngl.TRIANGLES, vertices=3)
                self.ctx.disable(moderngl.BLEND)
                vp = (0, 0) + size
                acc = np.frombuffer(fbo.read(viewport=vp, components=4, dtype="f4"), np.float32)
                acc = acc.reshape(size[1], size[0], 4)[..., :c].astype(np.float64)
                if fill is not None:
                    cover = np.frombuffer(fbo.read(viewport=vp, components=1, dtype="f4", attachment=1),
                                          np.float32).reshape(size[1], size[0], 1)
                    acc = np.where(cover > 0, acc, cval)
                out[oy0:oy1, ox0:ox1] = to_dtype(acc, image.dtype)

    def _view(self, prog, fill, origin, size):
        for p in (prog, fill):
            if p is not None:
                set_uniform(p, "fpw_view", (float(origin[0]), float(origin[1]), 1.0, 1.0))
                set_uniform(p, "fpw_viewport", (float(size[0]), float(size[1])))

    def _draw_mesh(self, vao):
        """Draw the mesh with culling and clipping, then restore the state.

        Maps are orientation preserving and the mesh's triangles have
        positive area in (x, y); with view steps of equal sign that is
        counter-clockwise in window coordinates. Flipped triangles straddle
        the pole (or fold): cull them. Vertices sent to the pole clip their
        triangles away (clip distance 0, see mesh.vert).
        """
        self.ctx.front_face = "ccw"
        self.ctx.cull_face = "back"
        self.ctx.enable(moderngl.CULL_FACE)
        self.ctx.enable_direct(GL_CLIP_DISTANCE0)
        try:
            vao.render(moderngl.TRIANGLES)
        finally:
            self.ctx.disable_direct(GL_CLIP_DISTANCE0)
            self.ctx.disable(moderngl.CULL_FACE)


def bound_framebuffer(ctx):
    """The framebuffer bound in ``ctx`` (moderngl's record), or framebuffer 0
    when none is recorded or the recorded one has been released."""
    fbo = ctx.fbo
    alive = isinstance(fbo, moderngl.Framebuffer) and not isinstance(fbo.mglo, moderngl.InvalidObject)
    return fbo if alive else ctx.detect_framebuffer(0)


def _renders_rgb32ui(ctx):
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


def _release(obj, dummy):
    """Release a cached object; a framebuffer with its textures, after
    binding ``dummy`` (moderngl rebinds the current framebuffer when it
    creates the next one: a deleted one would be GL_INVALID_OPERATION)."""
    if isinstance(obj, moderngl.Framebuffer):
        dummy.use()
        attachments = obj.color_attachments
        obj.release()
        for tex in attachments:
            tex.release()
    else:
        obj.release()


def _check_args(image, order, mode, cval):
    if order not in ORDERS:
        raise ValueError(f"order must be one of {ORDERS}, got {order!r}")
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    c = image.shape[2]
    cval = np.zeros(c) if cval is None else np.broadcast_to(np.asarray(cval, np.float64), (c,))
    return np.ascontiguousarray(image), cval


def grid_mesh(shape, grid_step, vertices, triangles):
    """Source-space vertices and positively oriented triangles for the mesh
    path: the caller's (checked) or a grid over an image of ``shape`` with
    ``grid_step`` pixels between vertices."""
    if (vertices is None) != (triangles is None):
        raise ValueError("pass both vertices and triangles, or neither (default grid)")
    if vertices is None:
        h, w = shape[:2]
        if not grid_step > 0:
            raise ValueError(f"grid_step must be positive, got {grid_step!r}")
        xs = np.append(np.arange(-0.5, w - 0.5, grid_step), w - 0.5)
        ys = np.append(np.arange(-0.5, h - 0.5, grid_step), h - 0.5)
        gx, gy = np.meshgrid(xs, ys)
        verts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        nx = len(xs)
        i = (np.arange(len(ys) - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
        tris = np.concatenate([np.stack([i, i + 1, i + nx + 1], 1), np.stack([i, i + nx + 1, i + nx], 1)])
        return verts, tris
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(triangles)
    if verts.ndim != 2 or verts.shape[1] != 2 or not np.all(np.isfinite(verts)):
        raise ValueError(f"vertices must be finite (N, 2) source positions, got shape {verts.shape}")
    if tris.ndim != 2 or tris.shape[1] != 3 or not np.issubdtype(tris.dtype, np.integer):
        raise ValueError(f"triangles must be (M, 3) integer indices, got {tris.shape} {tris.dtype}")
    if tris.size and (tris.min() < 0 or tris.max() >= len(verts)):
        raise ValueError(f"triangle indices must lie in [0, {len(verts)})")
    a, b, cc = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    area = (b[:, 0] - a[:, 0]) * (cc[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (cc[:, 0] - a[:, 0])
    tris = np.where((area < 0)[:, None], tris[:, [0, 2, 1]], tris)[area != 0]
    return verts, tris


class Backend:
    """The registry's "gl" backend on the shared headless context."""

    name = "gl"

    def __init__(self, max_texture_size=None):
        self.warper = GLWarper(shared_context(), max_texture_size=max_texture_size)

    @property
    def ctx(self):
        return self.warper.ctx

    def map_points(self, transform, points):
        check_thread()
        return self.warper.map_points(transform, points)

    def warp_image(self, image, transform, output_shape, *, order, mode, cval, hardware_filter=False):
        check_thread()
        return self.warper.warp_image(image, transform, output_shape, order=order, mode=mode, cval=cval,
                                      hardware_filter=hardware_filter)


def warp_image_mesh(image, transform, output_shape=None, *, order=1, mode="constant", cval=0,
                    grid_step=4.0, vertices=None, triangles=None):
    """Warp ``image`` by ``transform`` (source -> output) on the GL backend
    by the mesh path: see :meth:`GLWarper.warp_image_mesh`.

    Accepts what :func:`fpiwarp.warp_image` accepts; returns the same
    dtype and channel layout.
    """
    from .._warp import _check_transform, check_cval, check_image, check_output_shape
    from . import get_backend

    _check_transform(transform)
    img, squeeze = check_image(image)
    cval = check_cval(cval, img.shape[2])
    shape = check_output_shape(output_shape, img)
    backend = get_backend("gl")
    check_thread()
    out = backend.warper.warp_image_mesh(
        img, transform, shape, order=order, mode=mode, cval=cval, grid_step=grid_step,
        vertices=vertices, triangles=triangles)
    return out[:, :, 0] if squeeze else out
