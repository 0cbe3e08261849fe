"""The benchmark harness: its quick run, and the comparison methods it
implements itself (BIL, MVC, MLS-SIM), each against its defining property."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from support import ROOT
from support.requirements import required_backends, use_backend
from support.strategies import quads

sys.path.insert(0, str(ROOT))  # benchmarks/ lives beside the package, not in it

from benchmarks import batch_loop, methods, speed  # noqa: E402 (needs the path above)

finite = st.floats(-2.0, 2.0, allow_nan=False)


def _affine(draw_matrix, draw_offset):
    m = np.array(draw_matrix, dtype=np.float64).reshape(2, 2)
    return m, np.array(draw_offset, dtype=np.float64)


def _convex(q):
    d = np.roll(q, -1, axis=0) - q
    cross = d[:, 0] * np.roll(d, -1, axis=0)[:, 1] - d[:, 1] * np.roll(d, -1, axis=0)[:, 0]
    return np.all(cross > 0) or np.all(cross < 0)


def _inside_points(q, rng, n=64):
    """Points of the bilinear patch of q at (s, t) in [0.02, 0.98]²."""
    s, t = rng.uniform(0.02, 0.98, (2, n))
    return methods.Bilinear._patch(q, s, t)


# ------------------------------------------------------------------ BIL


@settings(max_examples=40, deadline=None)
@given(quads(max_scale=1e3), quads(max_scale=1e3))
def test_bilinear_interpolates_the_corners(src, dst):
    assume(_convex(src))
    f = methods.Bilinear(src, dst)
    scale = np.abs(dst).max() + np.ptp(dst)
    assert np.abs(f(src) - dst).max() <= 1e-9 * scale


@settings(max_examples=40, deadline=None)
@given(
    st.tuples(finite, finite, finite, finite),  # parallelogram edge vectors
    st.tuples(finite, finite),  # its first corner
    st.tuples(finite, finite, finite, finite),  # affine matrix
    st.tuples(finite, finite),  # affine offset
    st.integers(0, 2**32 - 1),
)
def test_bilinear_reproduces_affine_maps_on_parallelograms(edges, origin, matrix, offset, seed):
    a, b = np.array(edges[:2]), np.array(edges[2:])
    assume(abs(a[0] * b[1] - a[1] * b[0]) > 0.05)
    m, c = _affine(matrix, offset)
    assume(abs(np.linalg.det(m)) > 0.05)
    p0 = np.array(origin)
    src = np.array([p0, p0 + a, p0 + a + b, p0 + b])
    dst = src @ m.T + c
    f = methods.Bilinear(src, dst)
    rng = np.random.default_rng(seed)
    pts = p0 + rng.uniform(-0.5, 1.5, (50, 1)) * a + rng.uniform(-0.5, 1.5, (50, 1)) * b  # inside and out
    expect = pts @ m.T + c
    assert np.abs(f(pts) - expect).max() <= 1e-9 * (1 + np.abs(expect).max())
    assert np.abs(f.jacobian(pts) - m).max() <= 1e-9 * (1 + np.abs(m).max())


def test_bilinear_analytic_jacobian_matches_finite_differences(rng):
    src = np.array([[0, 0], [1, 0.1], [1.2, 0.9], [-0.1, 1.1]])
    dst = np.array([[0.2, 0], [1.5, 0.3], [1.0, 1.4], [0, 0.8]])
    f = methods.Bilinear(src, dst)
    pts = _inside_points(src, rng)
    fd = methods.finite_difference_jacobian(f, pts)
    assert np.abs(f.jacobian(pts) - fd).max() < 1e-8


# ------------------------------------------------------------------ MVC


@settings(max_examples=40, deadline=None)
@given(quads(max_scale=1e3), quads(max_scale=1e3))
def test_mean_value_interpolates_the_corners(src, dst):
    f = methods.MeanValue(src, dst)
    assert np.abs(f(src) - dst).max() <= 1e-12 * (np.abs(dst).max() + 1)


def _distance_to_boundary(q, p):
    a, b = q, np.roll(q, -1, axis=0)
    d = b - a
    t = np.clip(np.einsum("...ij,ij->...i", p[..., None, :] - a, d) / np.sum(d * d, axis=1), 0, 1)
    closest = a + t[..., None] * d
    return np.min(np.linalg.norm(p[..., None, :] - closest, axis=-1), axis=-1)


@settings(max_examples=40, deadline=None)
@given(
    quads(max_scale=1e3),
    st.tuples(finite, finite, finite, finite),
    st.tuples(finite, finite),
    st.integers(0, 2**32 - 1),
)
def test_mean_value_reproduces_linear_functions(src, matrix, offset, seed):
    """sum_i lambda_i = 1 and sum_i lambda_i v_i = p (linear precision), so
    MVC reproduces any affine map; this holds inside and outside non-convex
    polygons alike (Hormann & Floater 2006), away from the boundary."""
    m, c = _affine(matrix, offset)
    scale = np.ptp(src, axis=0).max()
    c = c * scale
    rng = np.random.default_rng(seed)
    lo, hi = src.min(axis=0), src.max(axis=0)
    pts = rng.uniform(lo - 0.2 * scale, hi + 0.2 * scale, (200, 2))
    pts = pts[_distance_to_boundary(src, pts) > 1e-3 * scale]
    f = methods.MeanValue(src, src @ m.T + c)
    lam = f.coordinates(pts)
    assert np.abs(lam.sum(axis=1) - 1).max() < 1e-9
    expect = pts @ m.T + c
    # lambda can be large near the boundary outside a non-convex polygon:
    # the error bound is relative to sum |lambda_i| |v_i|
    bound = 1e-11 * (np.abs(lam).sum(axis=1) * (np.abs(src).max() * (1 + np.abs(m).max()) + np.abs(c).max()) + 1)
    assert np.all(np.abs(f(pts) - expect).max(axis=1) <= bound)


def test_mean_value_is_linear_on_the_edges():
    sq = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], dtype=float)
    dst = np.array([[0, 0], [4, 1], [3, 5], [-1, 2]], dtype=float)
    f = methods.MeanValue(sq, dst)
    np.testing.assert_allclose(
        f([[0.5, 0.0], [2.0, 1.5]]), [0.75 * dst[0] + 0.25 * dst[1], 0.25 * dst[1] + 0.75 * dst[2]], atol=1e-14
    )


# ------------------------------------------------------------------ MLS-SIM


@settings(max_examples=40, deadline=None)
@given(quads(max_scale=1e3), quads(max_scale=1e3))
def test_mls_similarity_interpolates_the_control_points(src, dst):
    f = methods.MLSSimilarity(src, dst)
    assert np.abs(f(src) - dst).max() == 0


@settings(max_examples=40, deadline=None)
@given(
    quads(max_scale=1e3),
    st.complex_numbers(min_magnitude=0.1, max_magnitude=10),
    st.complex_numbers(max_magnitude=100),
    st.integers(0, 2**32 - 1),
)
def test_mls_similarity_reproduces_a_similarity_exactly(src, a, b, seed):
    z = src[:, 0] + 1j * src[:, 1]
    w = a * z + b
    f = methods.MLSSimilarity(src, np.c_[w.real, w.imag])
    rng = np.random.default_rng(seed)
    scale = np.ptp(src, axis=0).max()
    pts = src.mean(axis=0) + rng.uniform(-scale, scale, (100, 2))
    v = pts[:, 0] + 1j * pts[:, 1]
    expect = a * v + b
    got = f(pts)
    assert np.abs(got[:, 0] + 1j * got[:, 1] - expect).max() <= 1e-11 * (np.abs(expect).max() + abs(b) + 1)


def test_mls_similarity_is_not_affine_in_general(rng):
    """Guard against a degenerate implementation: with non-similar quads the
    map must bend (differ from every affine map)."""
    src = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    dst = np.array([[0, 0], [1, 0], [1.6, 1.5], [0, 1]], dtype=float)
    f = methods.MLSSimilarity(src, dst)
    jac = f.jacobian(rng.uniform(0.1, 0.9, (20, 2)))
    assert np.ptp(jac, axis=0).max() > 0.05


# ------------------------------------------------------------------ library methods


def test_projective_and_tps_interpolate_the_corners():
    pytest.importorskip("skimage")
    src = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    dst = np.array([[0, 0], [1, 0.1], [1.5, 1.2], [0.1, 0.9]])
    np.testing.assert_allclose(methods.projective(src, dst)(src), dst, atol=1e-9)
    tps, provider = methods.thin_plate_spline(src, dst)
    assert provider
    np.testing.assert_allclose(tps(src), dst, atol=1e-8)


def test_fpi_dilation_is_constant_on_every_quality_configuration():
    from benchmarks import quality

    pts = quality.inner_grid(30)
    for cfg in quality.CONFIGS:
        row = quality.measure(quality.build("FPI", cfg.src, cfg.target), pts)
        assert row["std_dilation"] < 1e-9 * max(row["mean_dilation"], 1e-3)
        assert abs(row["max_dilation"] - row["mean_dilation"]) < 1e-9
        assert row["foldover_fraction"] == 0


# ------------------------------------------------------------------ the quick run


def _png_size(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name} is not a PNG"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    for module in ("cv2", "skimage", "matplotlib"):
        pytest.importorskip(module)
    out = tmp_path_factory.mktemp("bench")
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks", "--quick", "--out", str(out)],
        check=False,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))},
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    return out


def test_quick_run_writes_every_output(quick_run):
    names = {p.name for p in quick_run.iterdir()}
    expected = {
        "machine.json",
        "speed.md",
        "speed.json",
        "speed_scaling.png",
        "quality.md",
        "quality.json",
        "quality_fig8.png",
        "antialias.md",
        "antialias.json",
        "antialias_crops.png",
        "batch.md",
        "batch.json",
    }
    assert expected <= names
    assert not any(n.endswith(".tmp") for n in names)
    for name in names:
        if name.endswith(".png"):
            w, h = _png_size(quick_run / name)
            assert w > 200 and h > 200


def test_quick_run_speed_results_are_well_formed(quick_run):
    import fpiwarp

    data = json.loads((quick_run / "speed.json").read_text())
    assert data["machine"]["cores"] >= 1 and data["machine"]["libraries"]["numpy"]
    assert data["machine"]["cpu"] and data["machine"]["isa"] and data["machine"]["pocl_device"]
    rows = data["results"]
    impls = {r["impl"] for r in rows}
    for name in set(fpiwarp.available_backends()) | required_backends():
        assert f"fpiwarp {name}" in impls
    assert {speed.IMAGE_BASELINE, "numpy maps + cv2.remap", speed.POINTS_BASELINE} <= impls
    errors = [(r["impl"], r["size"], r["note"]) for r in rows if r["note"].startswith("error")]
    assert not errors
    for r in rows:
        if r["seconds"] is not None:
            assert r["seconds"] > 0 and r["repeats"] >= 1 and r["ratio"] > 0
        if r["impl"] in (speed.IMAGE_BASELINE, speed.POINTS_BASELINE, speed.TPS_BASELINE):
            assert r["ratio"] == 1.0
    assert {r["dtype"] for r in rows if r["workload"] == "warp_image"} == {"uint8", "float32"}
    md = (quick_run / "speed.md").read_text()
    assert "| fpiwarp numpy |" in md and "## warp_image, uint8 RGB" in md


def test_every_quick_run_table_names_the_machine_kind(quick_run):
    """CPU model, ISA and PoCL device head every results table: figures of an
    AVX2 and an AVX-512 machine must not be mixed unawares."""
    facts = json.loads((quick_run / "machine.json").read_text())
    for name in ("speed.md", "quality.md", "antialias.md", "batch.md", "arrays.md"):
        text = (quick_run / name).read_text()
        assert f"{facts['cpu']} ({facts['isa']}), PoCL device {facts['pocl_device']}" in text, name


def test_quick_run_quality_table_has_constant_fpi_dilation(quick_run):
    data = json.loads((quick_run / "quality.json").read_text())
    assert data["configs"]
    for cfg in data["configs"]:
        assert set(cfg["rows"]) == {"FPI", "BIL", "PROJ", "MVC", "MLS-SIM", "TPS"}
        fpi = cfg["rows"]["FPI"]
        assert fpi["std_dilation"] < 1e-9 and fpi["area_distortion"] is not None
        others = [r["max_dilation"] for m, r in cfg["rows"].items() if m != "FPI" and "error" not in r]
        assert all(fpi["max_dilation"] <= d + 1e-9 for d in others)  # as in the paper's table
    md = (quick_run / "quality.md").read_text()
    assert "| FPI |" in md and "| MLS-SIM |" in md


def test_quick_run_antialias_section_is_well_formed(quick_run):
    data = json.loads((quick_run / "antialias.json").read_text())
    assert data["reference_subsamples"] >= 8
    kinds = {row["kind"] for row in data["psnr_db"]}
    assert {"uniform", "fpi", "aniso", "identity", "magnify"} <= kinds
    for row in data["psnr_db"]:
        plain, smooth = row["fpiwarp order 1"], row["fpiwarp order 1 antialias"]
        if row["kind"] in ("identity", "magnify"):
            assert smooth == plain  # antialiasing changes nothing where nothing shrinks
        elif row["kind"] in ("fpi", "aniso"):
            assert smooth > plain + 3
    assert {r["backend"] for r in data["cost"]} >= {"numpy"}
    assert "## Cost" in (quick_run / "antialias.md").read_text()


def test_quick_run_batch_section_is_well_formed(quick_run):
    """Every backend's batch equals its loop; times and ratios are positive."""
    data = json.loads((quick_run / "batch.json").read_text())
    assert data["maps"] and all(r["equal"] for r in data["maps"])
    assert all(r["loop_s"] > 0 and r["batch_s"] > 0 and r["speedup"] > 0 for r in data["maps"])
    assert all(r["loop_fps"] > 0 and r["batch_fps"] > 0 for r in data["frames"])
    assert "batch == loop" in (quick_run / "batch.md").read_text()


def test_batch_loop_before_is_the_old_selection_and_equal():
    """batch_loop's --before builds the opencl batch from the source with the
    old get_global_id(2) selection (the current source has the new one),
    and every batch of the run, old or new, equals its loop bit for bit."""
    use_backend("opencl")
    from fpiwarp.backends import get_backend

    backend = get_backend("opencl")
    assert batch_loop.SELECT_AFTER in backend._source and batch_loop.SELECT_BEFORE not in backend._source
    result = batch_loop.run(("opencl",), quick=True, rounds=1, before=True, log=lambda _: None)
    rows = {(r["backend"], r["part"]): r for r in result["rows"]}
    assert set(rows) == {("opencl", "loop"), ("opencl", "batch"), (batch_loop.BEFORE, "batch")}
    assert all(r["equal"] and r["wall_s"] > 0 for r in rows.values())
    built = batch_loop._BUILT_BEFORE[id(backend)]  # the old programs the --before batch ran
    assert built and all("-DFW_BATCH=1" in options for options in built)
    assert batch_loop.BEFORE in batch_loop.markdown(result)


def test_local_speed_batch_section_replaces_only_itself(tmp_path):
    """local_speed.py --batch rewrites its own section of local_speed.md, the rest kept."""
    pytest.importorskip("moderngl")
    from benchmarks import local_speed

    path = tmp_path / "local_speed.md"
    path.write_text("# The coarse pass\n\nrows\n", encoding="utf-8")
    a, b = f"{local_speed.BATCH_TITLE}, 2", f"{local_speed.BATCH_TITLE}, 3"
    local_speed.write_batch_section(path, f"{a}\n\nfirst\n")
    local_speed.write_batch_section(path, f"{b}\n\nother\n")
    local_speed.write_batch_section(path, f"{a}\n\nsecond\n")
    assert path.read_text(encoding="utf-8") == f"# The coarse pass\n\nrows\n\n{b}\n\nother\n\n{a}\n\nsecond\n"


def test_antialias_rules_patch_the_reference_only_inside_and_the_first_is_the_library_rule():
    """benchmarks/antialias_rules.py: its first rule leaves the reference's
    output unchanged, another changes it (fewer sub-samples at 1/8), and the
    reference is itself again after each, also after an error inside."""
    import fpiwarp
    from benchmarks import antialias, antialias_rules
    from fpiwarp.sampling import antialias as aa

    image = np.random.default_rng(3).random((96, 128, 1)).astype(np.float32)
    transform, shape = antialias.fpi_shrink(96, 128, 8)

    def warp():
        return fpiwarp.warp_image(image, transform, shape, mode="edge", antialias=True, backend="numpy")

    library = warp()
    (span, one_tap, spacing, _), *others = antialias_rules.RULES.values()
    with antialias_rules.rule(span, one_tap, spacing):
        np.testing.assert_array_equal(warp(), library)
    with antialias_rules.rule(*others[0][:3]):
        assert not np.array_equal(warp(), library)
    with pytest.raises(RuntimeError), antialias_rules.rule(*others[-1][:3]):
        raise RuntimeError
    assert aa.level_taps.__module__ == aa.__name__
    np.testing.assert_array_equal(warp(), library)
