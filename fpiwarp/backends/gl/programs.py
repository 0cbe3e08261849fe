"""GLSL program assembly and the program cache.

A program is described by a :class:`ProgramKey`: its shader files and the
choices that specialize it (kind of map, sampling order and border mode,
source texture format, output kind, ...). The key is the cache key, and
:meth:`ProgramKey.defines` turns it into the ``#define`` lines that the
shader files test, so one key always gives one text. :class:`ProgramCache`
compiles each key once per context.

Full-screen passes (:data:`FULLSCREEN`) hand the fragment stage its
per-draw values as flat varyings rather than uniforms: Mesa's llvmpipe
loads a uniform again for every pixel, a flat varying once per triangle.
Which values a program has is listed once, in glsl/include/per_draw.glsl; the
host only chooses whether they are forwarded (:func:`flat_value_sources`).
"""

from dataclasses import dataclass, replace

from ... import block as P
from ... import glsl
from ...block import MAX_ROWS as MAX_BLOCK_ROWS
from ...block import describe
from ...block.sampling_rules import MODES

#: The full-screen vertex shader, which forwards per-draw values to the
#: fragment stage as flat varyings (see :func:`flat_value_sources`).
FULLSCREEN = glsl.FULLSCREEN_VERT
#: Rows of the parameter block (header and the largest number of stages).
MAX_ROWS = MAX_BLOCK_ROWS
#: Rows per stage a full-screen pass forwards: ROW_PRE .. ROW_L3, all an FPI reads.
HOT_ROWS = P.ROW_L3 - P.ROW_PRE + 1
#: Varying slots budgeted for the per-draw values of a full-screen pass:
#: at least as many as any list of glsl/include/per_draw.glsl holds (the shader
#: checks it: FPW_MAX_PER_DRAW).
MAX_PER_DRAW = 10

#: Source texture formats of the software sampler and the hardware filter
#: (the ``source`` of a :class:`ProgramKey`) and their defines.
SOURCE_DEFINES = {"unorm": ("FPW_UNORM_TEXTURE 255.0",), "int": ("FPW_INT_TEXTURE",), "float": (),
                  "hw": ("FPW_HW_FILTER",)}
#: Fragment output kinds (see fpw_emit in glsl/include/output.glsl) and their defines.
OUTPUT_DEFINES = {"float": (), "int": ("FPW_OUT_INT",), "accumulate": ("FPW_TILED", "FPW_ACCUMULATE"),
                  "fill": ("FPW_FILL",), "fill_int": ("FPW_FILL", "FPW_OUT_INT")}


def stages_define(kinds):
    """The ``FPW_STAGES`` define of a program specialized to a kind of map:
    ``kinds`` lists each stage's (core, number of regions). Values (quad
    corners, TPS weights, ...) stay in the block, so every FPI shares one
    program, and moving points never recompiles."""
    calls = [f"FPW_STAGE({1 + k * P.STAGE_ROWS}, {core}, {n_regions})" for k, (core, n_regions) in enumerate(kinds)]
    return "FPW_STAGES " + " ".join(calls)


def stage_kinds(block):
    """(core, number of regions) of each stage of a parameter block: what a
    program is specialised to (from :func:`fpiwarp.block.describe`)."""
    return tuple((s.core, s.n_regions) for s in describe(block).stages)


def map_kind(block):
    """The ``FPW_STAGES`` define that specializes a program to the kind of
    map in ``block`` (see :func:`stages_define`)."""
    return stages_define(stage_kinds(block))


@dataclass(frozen=True)
class ProgramKey:
    """One program: its shader files and what specializes them.

    vertex, fragment
        Files in ``glsl/``, named by the constants of :mod:`fpiwarp.glsl`
        (fragment None: transform feedback only).
    stages
        Each stage's (core, number of regions) for a program specialized to
        one kind of map; None: the kind is read from the block at run time.
    order, mode
        Sampling order (0, 1, 3) and border mode (a name of
        :data:`fpiwarp.sampling.sampler.MODES`), for programs that sample.
    source
        The source texture's format for the sampler: "unorm" (uint8 read
        normalized), "int" (uint16), "float", "hw" (the texture unit
        filters), or None (no sampler define).
    gather_channels
        Order 1 by textureGather for a source of this many channels; 0: off.
    output
        The fragment output kind: "float", "int", "accumulate" (float sums
        of a tiled source), "fill" / "fill_int" (cval everywhere), or None.
    pack_pixels
        Pixels of 3 channels per packed RGB32UI texel written by the warp
        shader itself (4, 2, 1); 0: not packed.
    flags
        Further defines the shader files test (e.g. "PV_ALPHA").
    samples
        Whether the fragment stage samples the source (FPW_WITH_SAMPLER:
        include/fpiwarp.glsl's sampler, output and per-draw values).
    varyings
        Outputs captured by transform feedback.
    """

    vertex: str
    fragment: str | None = None
    stages: tuple | None = None
    order: int | None = None
    mode: str | None = None
    source: str | None = None
    gather_channels: int = 0
    output: str | None = None
    pack_pixels: int = 0
    flags: tuple = ()
    samples: bool = True
    varyings: tuple = ()

    def with_changes(self, **changes):
        """A copy of the key with some fields changed."""
        return replace(self, **changes)

    def defines(self):
        """The ``#define`` bodies (name and value) the shader files see
        (the fragment stage adds FPW_WITH_SAMPLER: :func:`fragment_defines`).
        ``FPW_FRAGMENT_<NAME>`` names the fragment file (warp.frag:
        FPW_FRAGMENT_WARP) for the per-draw list of glsl/include/per_draw.glsl."""
        out = []
        if self.fragment:
            out.append(glsl.fragment_name(self.fragment))
        if self.order is not None:
            out.append(f"FPW_ORDER {self.order}")
        if self.mode is not None:
            out.append(f"FPW_MODE {MODES.index(self.mode)}")
        if self.stages is not None:
            out.append(stages_define(self.stages))
        if self.source is not None:
            out += SOURCE_DEFINES[self.source]
        if self.gather_channels:
            out += ["FPW_GATHER", f"FPW_CHANNELS {self.gather_channels}"]
        if self.pack_pixels:
            out.append(f"FPW_PACK_PIXELS {self.pack_pixels}")
        if self.output is not None:
            out += OUTPUT_DEFINES[self.output]
        out += self.flags
        return tuple(out)


def shader_source(name, defines=()):
    """The desktop GL text of ``glsl/name`` (assembled by
    :func:`fpiwarp.glsl.assemble`: includes expanded, the block contract's
    constants first), with the GL program's own budget numbers and
    ``defines``."""
    budget = (f"FPW_HOT_ROWS {HOT_ROWS}", f"FPW_MAX_PER_DRAW {MAX_PER_DRAW}")
    return glsl.assemble(name, budget + tuple(defines))


def fragment_defines(key):
    """The defines of ``key``'s fragment stage: FPW_WITH_SAMPLER where it
    samples (include/fpiwarp.glsl's sampler and output), then the key's."""
    return (("FPW_WITH_SAMPLER",) if key.samples else ()) + key.defines()


def flat_value_sources(key, varying_slots):
    """(vertex, fragment) texts of a full-screen pass whose fragment stage
    reads its per-draw values (the list in glsl/include/per_draw.glsl) as flat
    varyings written once by glsl/backend/fullscreen.vert, and the FPI rows of as
    many stages as ``varying_slots`` (vec4 slots between the stages) hold
    beside them. Plain uniforms when even the per-draw values do not fit."""
    fs_defines = fragment_defines(key)
    # MAX_PER_DRAW slots for the per-draw values, one for gl_Position (and
    # one for a batch's instance values, glsl/include/batch.glsl)
    free = varying_slots - 1 - MAX_PER_DRAW - ("FPW_BATCH" in key.flags)
    if free < 0:
        return shader_source(FULLSCREEN, key.defines()), shader_source(key.fragment, fs_defines)
    hot = min(len(key.stages or ()), free // HOT_ROWS)
    extra = ("FPW_FLAT_PER_DRAW",) + ((f"FPW_HOT_STAGES {hot}",) if hot else ())
    # both stages see the fragment's defines: they choose the per-draw list
    return shader_source(FULLSCREEN, fs_defines + extra), shader_source(key.fragment, fs_defines + extra)


def set_uniform(prog, name, value):
    """Set a uniform if the compiler kept it (unused ones are dropped)."""
    member = prog.get(name, None)
    if member is not None:
        member.value = value


class ProgramCache:
    """The programs of one moderngl context, compiled once per key.

    Programs that read the parameter block get its uniform block bound to
    ``ubo_binding``, and their source sampler ``fpw_src`` set to unit 0.
    """

    def __init__(self, ctx, ubo_binding, varying_slots):
        self.ctx = ctx
        self.ubo_binding = ubo_binding
        #: vec4 slots between the vertex and fragment stages (settable: tests)
        self.varying_slots = varying_slots
        self.compile_count = 0  # programs built so far
        self.programs = {}  # ProgramKey -> moderngl.Program
        self._vaos = {}  # id(program) -> attribute-less vertex array

    def get(self, key):
        """The compiled program for ``key``, built on first use only."""
        prog = self.programs.get(key)
        if prog is None:
            prog = self._build(key)
            self.programs[key] = prog
            self.compile_count += 1
        return prog

    def _build(self, key):
        defines = key.defines()
        if key.fragment and key.vertex == FULLSCREEN:
            vs, fs = flat_value_sources(key, self.varying_slots)
        else:
            vs = shader_source(key.vertex, defines)
            fs = shader_source(key.fragment, fragment_defines(key)) if key.fragment else None
        prog = self.ctx.program(vertex_shader=vs, fragment_shader=fs, varyings=list(key.varyings))
        block = prog.get("FpiwarpParams", None)
        if block is not None:
            block.binding = self.ubo_binding
        set_uniform(prog, "fpw_src", 0)
        return prog

    def fullscreen_vao(self, prog):
        """The attribute-less vertex array that draws ``prog`` (with
        fullscreen.vert) over the viewport: ``.render(TRIANGLES, vertices=3)``."""
        vao = self._vaos.get(id(prog))
        if vao is None:
            vao = self._vaos[id(prog)] = self.ctx.vertex_array(prog, [])
        return vao

    def release(self):
        """Free the vertex arrays and programs."""
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        for prog in self.programs.values():
            prog.release()
        self.programs.clear()
