"""The parameter block as a leaf layer: named stage parts, one decoder
(describe), host-side refusal of blocks no kernel knows, and the contract's
numbers generated from one module into every kernel language."""

import ast
import dataclasses
import pathlib
import re
from importlib import resources

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, ConstrainedFPI, LocalDeformation, Mobius, RLinear, ThinPlateSpline
from fpiwarp import block as B
from fpiwarp.block import codegen
from fpiwarp.resources import PACKAGES, source

ROOT = pathlib.Path(fpiwarp.__file__).parent
SRC = [[10, 8], [50, 6], [54, 40], [8, 42]]
DST = [[12, 9], [49, 4], [58, 44], [6, 40]]


def _imports(path):
    """(module, level, inside a function) for every import statement of a file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
            if isinstance(child, ast.ImportFrom):
                found.append((child.module or "", child.level, in_function))
            elif isinstance(child, ast.Import):
                found.extend((alias.name, 0, in_function) for alias in child.names)
            visit(child, inner)

    visit(tree, False)
    return found


def test_the_block_layer_imports_nothing_but_numpy_and_itself():
    for path in sorted((ROOT / "block").glob("*.py")):
        for module, level, _ in _imports(path):
            assert level == 1 or module in ("numpy", "dataclasses"), f"{path.name} imports {module!r}"


def test_map_modules_import_the_block_at_top_level():
    for name in ("rlinear", "mobius", "fpi", "thin_plate_spline", "constrained", "local", "transform"):
        for module, level, in_function in _imports(ROOT / "maps" / f"{name}.py"):
            if level == 2 and module.split(".")[0] == "block":
                assert not in_function, f"maps/{name}.py imports ..{module} inside a function"


# --- Stage: named parts, checked when packed ----------------------------------------


def test_stage_parts_are_named_and_positional_tuples_are_refused():
    with pytest.raises(TypeError, match="pre must be a MobiusPart"):
        B.Stage(pre=(0j, 0j, 1 + 0j))
    with pytest.raises(TypeError, match="linear must be a LinearPart"):
        B.Stage(linear=(1, 0, 0))
    with pytest.raises(ValueError, match="pre-Möbius has no offset"):
        B.pack([B.Stage(pre=B.MobiusPart(offset=1j))])
    with pytest.raises(ValueError, match="post-Möbius is centered at 0"):
        B.pack([B.Stage(post=B.MobiusPart(center=1j))])
    with pytest.raises(ValueError, match="unknown core 7"):
        B.pack([B.Stage(core=7)])


def test_pack_writes_each_named_field_to_its_row():
    st = B.Stage(
        pre=B.MobiusPart(center=1 + 2j, inverse_pole=3 + 4j, scale=5 + 6j),
        linear=B.LinearPart(2 + 0j, 0.5j, 7 + 8j),
        post=B.MobiusPart(inverse_pole=9 + 10j, scale=11 + 12j, offset=13 + 14j),
        newton_tol=0.25,
    )
    rows = B.stage_rows(B.pack([st]), 0)
    assert rows[B.ROW_PRE].tolist() == [1, 2, 3, 4]
    assert rows[B.ROW_SCALE].tolist() == [5, 6, 11, 12]
    assert rows[B.ROW_POST].tolist() == [9, 10, 13, 14]
    assert rows[B.ROW_L12].tolist() == [2, 0, 0, 0.5]
    assert rows[B.ROW_L3].tolist() == [7, 8, 0.25, 0]


def test_newton_seed_is_the_rlinear_inverse_bit_for_bit(rng):
    for _ in range(200):
        l1, l2, l3 = rng.normal(size=3) + 1j * rng.normal(size=3)
        if abs(abs(l1) - abs(l2)) < 1e-3:
            continue
        want = RLinear(l1, l2, l3).inverse
        got = B.rlinear_inverse(B.LinearPart(l1, l2, l3))
        assert (got.l1, got.l2, got.l3) == (want.l1, want.l2, want.l3)
    with pytest.raises(ValueError, match="singular"):
        B.rlinear_inverse(B.LinearPart(1, 1j, 0))


# --- describe: the one decoder of a block's kind ---------------------------------------


def test_describe_names_the_kind_of_every_map_family():
    fpi = FPI(SRC, DST)
    kind = B.describe(fpi.params())
    assert kind.n_stages == 1 and kind.is_short
    assert kind.stages[0] == B.StageKind(core=B.CORE_AFFINE, n_centers=0, n_regions=0, newton_iters=0)
    assert kind.constant_dilation == pytest.approx(fpi.dilation, rel=1e-6)
    compound = B.describe((RLinear(2, 0.1, 1) @ fpi @ Mobius(1, 2, 0.01, 1)).params())
    assert compound.is_short and compound.n_stages == 3 and compound.constant_dilation is None
    c = ConstrainedFPI(SRC, DST, edges=(3, 1))
    tps, inv = B.describe(c.params()), B.describe(c.inverse.params())
    # its edge points and their offset copies travel as pairs: two rows each
    assert tps.stages[0].core == B.CORE_TPS_PAIRS and tps.stages[0].n_centers == 4 * c.points_per_edge
    assert not tps.is_short
    assert inv.stages[0].core == B.CORE_TPS_PAIRS_INVERSE and inv.stages[0].newton_iters > 0
    assert tps.constant_dilation is None
    local = B.describe(LocalDeformation(SRC, DST, edges=(3, 1)).params())
    assert local.stages[0].n_regions == 2 and not local.is_short and local.constant_dilation is None
    spline = ThinPlateSpline(np.array([0j, 1, 1j]), np.zeros(3), (1, 0, 0))
    assert B.describe(spline.params()).stages[0].header == (B.CORE_TPS, 3, 0, 0)


def _with_header(block, k, column, value):
    block = block.copy()
    block[1 + k * B.STAGE_ROWS + B.ROW_HEADER, column] = value
    return block


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda b: _with_header(b, 0, 0, 7), "unknown core 7"),
        (lambda b: _with_header(b, 0, 1, B.MAX_CENTERS + 1), "centers"),
        (lambda b: _with_header(b, 0, 2, B.MAX_REGIONS + 1), "regions"),
        (lambda b: np.concatenate([[[1, B.LAYOUT_VERSION + 1, 0, 0]], b[1:]]).astype(np.float32), "layout version"),
        (lambda b: np.concatenate([[[2, B.LAYOUT_VERSION, 0, 0]], b[1:]]).astype(np.float32), "declares 2 stages"),
        (lambda b: b[:, :3], "shape"),
    ],
)
def test_a_block_no_kernel_knows_is_refused_before_any_evaluation(change, message):
    bad = change(FPI(SRC, DST).params())
    with pytest.raises(ValueError, match=message):
        B.describe(bad)
    with pytest.raises(ValueError, match=message):
        B.evaluate(bad, np.zeros((3, 2)))


def test_describe_reads_float32_and_float64_blocks_alike():
    block = ConstrainedFPI(SRC, DST, edges=(3, 1)).params()
    assert B.describe(block) == B.describe(block.astype(np.float64))


# --- the contract's numbers: generated, never written in a kernel -------------------


def test_generated_constants_are_the_contract():
    from fpiwarp.sampling import sampler as _sampling

    for name, value in codegen.KERNEL_CONSTANTS.items():
        owner = B.layout if hasattr(B.layout, name) else B.sampling_rules
        assert getattr(owner, name) == value, name
    assert _sampling.COORD_LIMIT == codegen.KERNEL_CONSTANTS["COORD_LIMIT"]
    for core, number in B.CORES.items():  # a new core reaches every kernel by name
        assert codegen.KERNEL_CONSTANTS[f"CORE_{core.upper()}"] == number, core
    assert [_sampling.MODES.index(m) for m in _sampling.MODES] == [
        codegen.KERNEL_CONSTANTS[f"MODE_{m.upper()}"] for m in _sampling.MODES
    ]
    preamble = codegen.opencl_preamble()
    assert "#define FW_STAGE_ROWS 109\n" in preamble and "#define FW_COORD_LIMIT 16777216.0f\n" in preamble
    assert codegen.glsl_defines()["FPW_COORD_LIMIT"] == "16777216.0"
    assert codegen.glsl_defines()["FPW_CORE_TPS_INVERSE"] == str(B.CORE_TPS_INVERSE)


def _kernel_texts():
    """(name, text) of every OpenCL and GLSL source file that ships."""
    for kind, package in PACKAGES.items():
        yield from ((f"{kind}/{name}", source(kind, name)) for name in _source_names(resources.files(package)))


def _source_names(folder, prefix=""):
    """Paths (from the package) of the kernel and shader files under ``folder``."""
    for entry in sorted(folder.iterdir(), key=lambda e: e.name):
        if entry.is_dir() and entry.name != "__pycache__":
            yield from _source_names(entry, f"{prefix}{entry.name}/")
        elif entry.name.endswith((".h", ".cl", ".glsl", ".vert", ".frag")):
            yield prefix + entry.name


def test_no_kernel_source_hand_defines_a_contract_constant():
    texts = dict(_kernel_texts())
    assert "kernels/opencl/fpiwarp_map.h" in texts and "glsl/include/map.glsl" in texts
    contract = "|".join(codegen.KERNEL_CONSTANTS)
    hand = re.compile(rf"^\s*#\s*define\s+(?:FW_|FPW_)({contract})\b", re.M)
    for name, text in texts.items():
        found = hand.findall(text)
        assert not found, f"{name} defines contract constants by hand: {found}"
        assert "16777216" not in text, f"{name} writes COORD_LIMIT by hand"


def test_warp_kernels_bind_every_contract_number_from_the_table():
    text = source("kernels", "nvwarp/contract.py")
    calls = re.findall(r"wp\.constant\(([^)]*)\)", text)
    assert calls, "the Warp kernels' contract module binds its constants with wp.constant"
    for arg in calls:
        assert re.fullmatch(r'CONTRACT\["(\w+)"\]', arg), f"wp.constant({arg}) is not taken from the contract"
        name = re.fullmatch(r'CONTRACT\["(\w+)"\]', arg)[1]
        assert re.search(rf"^{name} = wp\.constant\(CONTRACT\[\"{name}\"\]\)$", text, re.M), name


def test_opencl_sources_use_only_generated_contract_names():
    """Every FW_<contract-like> name the OpenCL sources use is generated."""
    used, local = set(), set()
    for kind, name in (("kernels", "opencl/fpiwarp_map.h"), ("kernels", "opencl/fpiwarp.cl")):
        text = source(kind, name)
        used |= set(re.findall(r"\bFW_((?:ROW|CORE|MODE)_[A-Z0-9_]+|STAGE_ROWS|MAX_\w+|COORD_LIMIT)\b", text))
        local |= set(re.findall(r"#\s*define\s+FW_(\w+)", text))  # the kernels' own macros (FW_ROW_TAPS)
    missing = used - local - set(codegen.KERNEL_CONSTANTS)
    assert used and not missing, f"contract names the preamble does not generate: {missing}"


def test_every_core_has_its_own_branch_in_every_kernel():
    """No core is an implicit `else`: each kernel names every core of the
    contract and gives anything else NaN ("outside")."""
    for kind, name, prefix in (("kernels", "opencl/fpiwarp_map.h", "FW_"), ("kernels", "nvwarp/stage.py", ""),
                               ("glsl", "include/map.glsl", "FPW_"), ("glsl", "include/antialias.glsl", "FPW_")):
        text = source(kind, name)
        for core in ("CORE_AFFINE", "CORE_TPS", "CORE_TPS_INVERSE", "CORE_TPS_PAIRS", "CORE_TPS_PAIRS_INVERSE"):
            assert re.search(rf"core == {prefix}{core}\b", text), f"{name}: no branch for {core}"
    assert set(B.CORES.values()) == {B.CORE_AFFINE, B.CORE_TPS, B.CORE_TPS_INVERSE, B.CORE_TPS_PAIRS,
                                     B.CORE_TPS_PAIRS_INVERSE}


def test_reference_refuses_a_stage_kind_it_does_not_know():
    rows = B.stage_rows(FPI(SRC, DST).params().astype(np.float64), 0)
    unknown = dataclasses.replace(B.describe(FPI(SRC, DST).params()).stages[0], core=7)
    with pytest.raises(ValueError, match="unknown core 7"):
        B.reference.evaluate_stage(rows, unknown, np.zeros(2, complex), np.float64)
