"""The GL backend (moderngl, headless EGL) against the numpy reference.

map_points: within 1e-5 relative of the float64 reference away from the
pole. warp_image: within one uint8 level (257 for uint16, 1/255 for float32
images in [0, 1]) of the numpy backend on at least 99.8% of pixels. The GL
error state is checked before and after every test that draws.
"""

import numpy as np
import pytest
from support.kernel_cases import (
    DTYPES,
    MAPS,
    MODES,
    ORDERS,
    Staged,
    assert_close_relative,
    assert_images_agree,
    compare_warp,
    frame_points,
    make_image,
    newton_atol,
    reference,
    region_map,
    sample_fpi,
    tps_inverse_stage,
    tps_map,
)

import fpiwarp
from fpiwarp import FPI, Mobius, RLinear, glsl
from fpiwarp.block import Region, Stage, evaluate

_small = {}


def _check_gl(ctx):
    assert ctx.error == "GL_NO_ERROR"


@pytest.fixture
def gl(gl_backend):
    """The registry's "gl" backend object; GL errors fail the test."""
    from fpiwarp.backends import get_backend

    backend = get_backend(gl_backend)
    _check_gl(backend.ctx)
    yield backend
    _check_gl(backend.ctx)


@pytest.fixture
def gl_small(gl):
    """A GL backend limited to 16-pixel textures: every image here is tiled."""
    from fpiwarp.backends.gl import Backend

    if "b" not in _small:
        _small["b"] = Backend(max_texture_size=16)
    return _small["b"]




# --- map_points (transform feedback) -------------------------------------------


@pytest.mark.parametrize("specialize", [True, False], ids=["per-kind", "generic"])
def test_map_points_matches_float64_reference(gl, specialize, rng):
    """Both the programs specialized per kind of map and the one generic
    program (kind read from the block) mirror ``evaluate``."""
    from fpiwarp.backends.gl import GLWarper

    warper = gl.warper if specialize else GLWarper(gl.ctx, specialize=False)
    for name, make in sorted(MAPS.items()):
        transform = make()
        pts = frame_points(rng)
        want = evaluate(transform.params(), pts, np.float64)
        assert np.all(np.isfinite(want)), name
        assert_close_relative(warper.map_points(transform, pts), want, atol=newton_atol(transform))
        if not isinstance(transform, Staged):  # and the map's own float64 formulas
            assert_close_relative(warper.map_points(transform, pts), transform(pts))
    if not specialize:
        assert warper.compile_count == 1
        warper.release()


def test_newton_inverse_undoes_the_tps_and_failure_is_nan(gl, rng):
    pts = frame_points(rng, 1000, margin=0)
    forward = gl.map_points(tps_map(), pts)
    assert_close_relative(gl.map_points(tps_map().inverse, forward), pts, rtol=3e-5)
    stuck = gl.map_points(Staged([tps_inverse_stage(iters=1, tol=0.0)]), pts[:100])
    assert np.all(np.isnan(stuck))


def test_map_points_keeps_shape_and_passes_non_finite(gl, rng):
    transform = sample_fpi()
    pts = frame_points(rng, 30).reshape(3, 5, 2, 2)[:, :, 0]  # not contiguous
    got = gl.map_points(transform, pts)
    assert got.shape == (3, 5, 2)
    assert_close_relative(got, transform(pts))
    assert gl.map_points(transform, np.zeros((0, 2))).shape == (0, 2)
    assert not np.any(np.isfinite(gl.map_points(transform, [[np.nan, 1.0]])))
    assert fpiwarp.map_points(transform, [[1, 2]], backend="gl").shape == (1, 2)


# --- warp_image (per pixel) -----------------------------------------------------


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("order", ORDERS)
def test_warp_image_every_order_and_mode(gl, order, mode):
    img = make_image((48, 64, 3), np.uint8, seed=order)
    compare_warp(gl, img, sample_fpi(), (52, 70), order, mode, [20, 128, 250])


@pytest.mark.parametrize("dtype", DTYPES)
def test_warp_image_every_dtype_and_channel_count(gl, dtype):
    """Every mode once per dtype (the order grid above is uint8 RGB): each
    combination is a shader variant to compile, seconds on llvmpipe."""
    order = 1
    for channels, mode in zip((1, 2, 3, 4), MODES):
        img = make_image((48, 64, channels), dtype, seed=channels)
        cval = np.linspace(0.1, 0.9, channels) * (1 if dtype is np.float32 else np.iinfo(dtype).max)
        compare_warp(gl, img, sample_fpi(), (52, 70), order, mode, cval)


def test_coordinates_are_pixel_centers_x_column_y_row(gl):
    """A translation by (3, 5) moves pixel (row r, column c) to (r + 5, c + 3)
    exactly: no half-pixel offset, no flipped rows."""
    img = make_image((20, 30, 3), np.uint8)
    for order in ORDERS:
        out = gl.warp_image(img, RLinear(1, 0, 3 + 5j), (20, 30), order=order, mode="constant", cval=np.zeros(3))
        assert np.array_equal(out[5:, 3:], img[:15, :27])
        assert np.all(out[:5] == 0) and np.all(out[:, :3] == 0)


def test_hardware_filter_is_close_and_limited_to_what_gl_can_do(gl):
    """The fast option: texture-unit filtering, weights quantized by GL."""
    img = make_image((48, 64, 3), np.uint8)
    for order, mode in [(0, "edge"), (1, "constant"), (1, "wrap")]:
        want, cv = reference(img, sample_fpi(), (52, 70), order, mode, [9, 99, 199])
        got = gl.warper.warp_image(img, sample_fpi(), (52, 70), order=order, mode=mode, cval=cv,
                                   hardware_filter=True)
        assert_images_agree(got, want, np.uint8, fraction=0.99, levels=3)
    with pytest.raises(ValueError, match="modes"):
        gl.warper.warp_image(img, sample_fpi(), (8, 8), mode="reflect", hardware_filter=True)
    with pytest.raises(ValueError, match="order"):
        gl.warper.warp_image(img, sample_fpi(), (8, 8), order=3, hardware_filter=True)


# --- tiling ------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", DTYPES)
def test_tiled_source_and_output_match_untiled(gl, gl_small, dtype):
    """With 16-pixel textures a 48×64 source is 12 tiles and a 52×70 output
    20; the sum over source tiles equals the one-pass result."""
    img = make_image((48, 64, 3), dtype, seed=3)
    cval = np.array([0.2, 0.5, 0.7]) * (1 if dtype is np.float32 else np.iinfo(dtype).max)
    for order, mode in [(0, "wrap"), (3, "reflect")]:
        got, _ = compare_warp(gl_small, img, sample_fpi(), (52, 70), order, mode, cval)
        one_pass = gl.warp_image(img, sample_fpi(), (52, 70), order=order, mode=mode, cval=cval)
        assert_images_agree(got, one_pass, dtype, fraction=0.999)
    _check_gl(gl_small.ctx)


def test_only_the_output_tiled(gl_small):
    img = make_image((12, 10, 2), np.uint16)
    compare_warp(gl_small, img, RLinear(3.1, 0.2j, 1 + 2j), (40, 35), 1, "reflect", [7, 8])


# --- mesh path ------------------------------------------------------------------------


def smooth_image(h, w, channels=3):
    y, x = np.mgrid[0:h, 0:w]
    base = 128 + 90 * np.sin(x / 6.0) * np.cos(y / 5.0)
    return np.stack([base + 10 * k for k in range(channels)], -1).clip(0, 255).astype(np.uint8)


def mesh_regions(transform, shape, src_shape, margin=1.5):
    """Output pixels whose source position is well inside / well outside."""
    grid = np.stack(np.meshgrid(np.arange(shape[1], dtype=float), np.arange(shape[0], dtype=float)), -1)
    src = transform.inverse(grid)
    h, w = src_shape
    inside = np.all((src > margin - 0.5) & (src < np.array([w, h]) - 0.5 - margin), axis=-1)
    outside = np.any((src < -0.5 - margin) | (src > np.array([w, h]) - 0.5 + margin), axis=-1)
    return inside, outside, src


def test_mesh_path_matches_backward_warp_inside_and_gives_cval_outside(gl, gl_small):
    from fpiwarp.backends.gl import warp_image_mesh

    img = smooth_image(48, 64)
    transform = sample_fpi()
    want, _ = reference(img, transform, (52, 70), 1, "constant", [1, 2, 3])
    got = warp_image_mesh(img, transform, (52, 70), order=1, cval=[1, 2, 3], grid_step=2)
    inside, outside, _ = mesh_regions(transform, (52, 70), (48, 64))
    assert inside.sum() > 2000 and outside.sum() > 100
    assert_images_agree(got[inside], want[inside], np.uint8)
    assert np.all(got[outside] == [1, 2, 3])
    # tiled source and output give the same image
    tiled = gl_small.warper.warp_image_mesh(img, transform, (52, 70), order=1, cval=np.array([1.0, 2, 3]),
                                           grid_step=2)
    assert_images_agree(tiled, got, np.uint8, fraction=0.999)
    _check_gl(gl.ctx)


def test_mesh_path_drops_triangles_at_the_pole(gl):
    """The forward map's pole z∞ = (30, 20) lies inside the source: triangles
    around it would span the output; they are dropped (culled), and the rest
    of the image still matches the backward warp."""
    from fpiwarp.backends.gl import warp_image_mesh

    transform = Mobius(1, 0, 0.05, 1, center=0) @ RLinear(1, 0, -30 - 20j)
    transform = RLinear(3, 0, 30 + 20j) @ transform  # keep the output in frame
    img = smooth_image(40, 60)
    want, _ = reference(img, transform, (40, 60), 1, "constant", [0, 0, 0])
    got = warp_image_mesh(img, transform, (40, 60), order=1, cval=0, grid_step=1)
    inside, _, src = mesh_regions(transform, (40, 60), (40, 60))
    far = inside & (np.hypot(src[..., 0] - 30, src[..., 1] - 20) > 4)
    assert far.sum() > 1000
    assert_images_agree(got[far], want[far], np.uint8, fraction=0.99)


def test_mesh_vertices_sent_to_nan_clip_their_triangles(gl):
    """Left of x = 31.8 the forward map gives NaN: those vertices' triangles
    vanish (clip distance) instead of stretching across the output."""
    from fpiwarp.backends.gl import warp_image_mesh

    nan = complex(np.nan, np.nan)
    transform = Staged([Stage(regions=(Region(origin=31.8 + 0j, normal=-1 + 0j, a=nan, b=nan),))])
    img = smooth_image(48, 64)
    got = warp_image_mesh(img, transform, order=0, cval=[1, 2, 3], grid_step=1)
    assert np.array_equal(got[:, 33:], img[:, 33:])  # cells right of x = 32.5 are whole
    assert np.all(got[:, :33] == [1, 2, 3])


def test_mesh_user_triangles_any_winding(gl):
    from fpiwarp.backends.gl import warp_image_mesh

    img = smooth_image(20, 30)
    verts = [[-0.5, -0.5], [29.5, -0.5], [29.5, 19.5], [-0.5, 19.5]]
    tris = [[0, 2, 1], [0, 2, 3]]  # one clockwise, one counter-clockwise
    got = warp_image_mesh(img, RLinear(1, 0, 0), vertices=verts, triangles=tris, order=0)
    assert np.array_equal(got, img)
    with pytest.raises(ValueError, match="indices"):
        warp_image_mesh(img, RLinear(1, 0, 0), vertices=verts, triangles=[[0, 1, 9]])


# --- programs compile once per kind -----------------------------------------------------


def test_a_changed_map_does_not_rebuild_the_program(gl, rng):
    img = make_image((16, 16, 3), np.uint8)
    pts = frame_points(rng, 10)
    gl.map_points(sample_fpi(), pts)
    gl.warp_image(img, sample_fpi(), (16, 16), order=1, mode="edge", cval=np.zeros(3))
    programs, count = dict(gl.warper.programs.programs), gl.warper.compile_count
    for k in range(5):  # drag one corner: new values, same kind of map
        moved = FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4 + k, 3 - k], [60, -2], [66, 50], [-3, 44]])
        gl.map_points(moved, pts)
        out = gl.warp_image(img, moved, (16, 16), order=1, mode="edge", cval=np.zeros(3))
        want, _ = reference(img, moved, (16, 16), 1, "edge", 0)
        assert_images_agree(out, want, np.uint8)
    assert gl.warper.compile_count == count and gl.warper.programs.programs == programs


# --- availability --------------------------------------------------------------------------


def test_probe_reports_why_without_a_driver(monkeypatch):
    pytest.importorskip("moderngl")
    from fpiwarp.backends import gl as gl_backend
    from fpiwarp.backends.gl import context

    def no_driver():
        raise RuntimeError("no OpenGL 3.3 context: egl: no display")

    monkeypatch.setattr(context, "_shared", {})
    monkeypatch.setattr(context, "create_context", no_driver)
    assert gl_backend.probe() == "no OpenGL 3.3 context: egl: no display"
    with pytest.raises(RuntimeError, match="no display"):
        gl_backend.Backend()


def test_bad_arguments_are_clear_errors(gl):
    img = make_image((8, 8, 1), np.uint8)
    with pytest.raises(ValueError, match="order"):
        gl.warp_image(img, sample_fpi(), (8, 8), order=2, mode="edge", cval=np.zeros(1))
    with pytest.raises(ValueError, match="mode"):
        gl.warp_image(img, sample_fpi(), (8, 8), order=1, mode="mirror", cval=np.zeros(1))
    with pytest.raises(ValueError, match="block"):
        gl.warper.set_map(np.zeros((3, 3), np.float32))


def test_calls_from_another_thread_are_refused(gl):
    """A GL context is current in one thread: another thread gets a clear
    error, never a silently wrong picture."""
    import threading

    errors = []

    def worker():
        try:
            fpiwarp.warp_image(np.zeros((4, 4), np.uint8), RLinear(1), backend="gl")
        except RuntimeError as exc:
            errors.append(str(exc))

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert errors and "thread" in errors[0]


def test_the_backend_can_be_handed_to_another_thread(gl):
    """The shared context belongs to one thread: the owner releases it, a
    worker claims it and warps (the same picture), the first thread is
    refused meanwhile, and gets it back once the worker releases it."""
    import threading

    from fpiwarp.backends.gl import claim_shared_context, owner_thread, release_shared_context

    img = make_image((12, 16, 3), np.uint8)
    want = fpiwarp.warp_image(img, sample_fpi(), backend="gl")
    assert owner_thread() == threading.get_ident()
    tried, claimed, released, handed_back = (threading.Event() for _ in range(4))
    seen = {}

    def worker():
        try:
            with pytest.raises(fpiwarp.ThreadOwnershipError, match="thread"):  # not yet released by the main thread
                claim_shared_context()
            tried.set()
            released.wait(30)
            claim_shared_context()
            seen["owner"] = owner_thread() == threading.get_ident()
            seen["out"] = fpiwarp.warp_image(img, sample_fpi(), backend="gl")
            claimed.set()
            handed_back.wait(30)
            release_shared_context()
        except BaseException as exc:  # reported by the main thread
            seen["error"] = exc
        finally:
            tried.set()
            claimed.set()

    t = threading.Thread(target=worker)
    t.start()
    try:
        tried.wait(30)
        release_shared_context()
        assert owner_thread() is None
        released.set()
        claimed.wait(30)
        assert "error" not in seen, seen.get("error")
        assert seen["owner"]
        np.testing.assert_array_equal(seen["out"], want)
        with pytest.raises(fpiwarp.ThreadOwnershipError, match="thread"):
            fpiwarp.warp_image(img, sample_fpi(), backend="gl")
        with pytest.raises(fpiwarp.ThreadOwnershipError, match="thread"):
            release_shared_context()
    finally:
        released.set()
        handed_back.set()
        t.join(30)
    assert "error" not in seen, seen.get("error")
    claim_shared_context()
    assert owner_thread() == threading.get_ident()
    np.testing.assert_array_equal(fpiwarp.warp_image(img, sample_fpi(), backend="gl"), want)


# --- per-draw values as flat varyings; order 1 by textureGather ------------------------


def _warper(**options):
    from fpiwarp.backends.gl import GLWarper, shared_context

    return GLWarper(shared_context(), **options)


def _chain_of_fpis(n):
    """n FPI stages (each FPI and its inverse in turn): a map of n stages."""
    fpi = sample_fpi()
    maps = [fpi if k % 2 == 0 else fpi.inverse for k in range(n)]
    return Staged([s for m in maps for s in m.stages()], [s for m in maps[::-1] for s in m.inverse.stages()])


def test_flat_varyings_give_the_same_pictures_as_uniforms(gl):
    """Full-screen passes hand their per-draw values and the FPI rows of up
    to several stages to the fragment stage as flat varyings (a speed-up on
    llvmpipe). Fewer slots mean fewer forwarded values, never other values:
    plain uniforms (0 slots), per-draw values only, all (the driver's)."""
    from fpiwarp.backends.gl import MAX_PER_DRAW

    img = make_image((48, 64, 3), np.uint8, seed=3)
    maps = [sample_fpi(), _chain_of_fpis(6), MAPS["compound"](), region_map()]
    warpers = {slots: _warper() for slots in (0, MAX_PER_DRAW + 1, None)}
    for slots, warper in warpers.items():
        if slots is not None:
            warper.varying_slots = slots
    try:
        for transform in maps:
            for order, mode in [(1, "constant"), (3, "reflect"), (0, "wrap")]:
                cv = np.array([10.0, 20, 30])
                outs = [w.warp_image(img, transform, (50, 66), order=order, mode=mode, cval=cv)
                        for w in warpers.values()]
                assert all(np.array_equal(o, outs[0]) for o in outs[1:])
                assert_images_agree(outs[0], reference(img, transform, (50, 66), order, mode, cv)[0], np.uint8)
    finally:
        for w in warpers.values():
            w.release()


def test_flat_varyings_forward_what_fits(gl):
    """The per-draw values get MAX_PER_DRAW slots, the FPI rows of as many
    stages as the rest holds; below that budget, plain uniforms."""
    from fpiwarp.backends.gl import FULLSCREEN, HOT_ROWS, MAX_PER_DRAW, ProgramKey, flat_value_sources, stage_kinds

    key = ProgramKey(
        FULLSCREEN,
        glsl.WARP_FRAG,
        stages=stage_kinds(_chain_of_fpis(6).params()),
        order=1,
        mode="constant",
        source="unorm",
        output="int",
    )
    slots = gl.warper.varying_slots
    for n_slots, hot in [
        (slots, min(6, (slots - 1 - MAX_PER_DRAW) // HOT_ROWS)),
        (MAX_PER_DRAW + 1 + HOT_ROWS, 1),
        (MAX_PER_DRAW + 1, 0),
    ]:
        vs, fs = flat_value_sources(key, n_slots)
        for text in (vs, fs):
            assert "#define FPW_FLAT_PER_DRAW\n" in text
            assert ("#define FPW_HOT_STAGES" in text) == (hot > 0)
            if hot:
                assert f"#define FPW_HOT_STAGES {hot}\n" in text
        gl.ctx.program(vertex_shader=vs, fragment_shader=fs).release()
    vs, fs = flat_value_sources(key, MAX_PER_DRAW)  # not even the per-draw values fit: plain uniforms
    assert "#define FPW_FLAT_PER_DRAW\n" not in vs + fs
    gl.ctx.program(vertex_shader=vs, fragment_shader=fs).release()


def test_every_per_draw_list_fits_and_declares_what_is_read(gl):
    """Every full-screen program kind links with its per-draw values
    forwarded (a value read but not listed in glsl/include/per_draw.glsl would not
    compile; more than MAX_PER_DRAW would stop at its #error), and the
    values reach the program under their own names."""
    from fpiwarp.backends.gl import FULLSCREEN, ProgramKey, flat_value_sources

    kinds = [
        dict(source="unorm", output="int"),
        dict(source="float", output="float"),
        dict(source="int", output="accumulate"),
        dict(source="hw", output="int"),
        dict(source="unorm", output=None, pack_pixels=4),
        dict(source=None, output="fill_int"),
    ]
    keys = [ProgramKey(FULLSCREEN, glsl.WARP_FRAG, stages=((0, 0),), order=1, mode="constant", **k) for k in kinds]
    keys.append(ProgramKey(FULLSCREEN, glsl.PREVIEW_FRAG, stages=((0, 0),), order=1, mode="constant"))
    keys.append(ProgramKey(FULLSCREEN, glsl.PACK_RGB_FRAG, pack_pixels=4, samples=False))
    for key in keys:
        vs, fs = flat_value_sources(key, gl.warper.varying_slots)
        prog = gl.ctx.program(vertex_shader=vs, fragment_shader=fs)
        try:
            names = set(prog)
            if key.samples:  # (a fill reads cval only: the compiler drops the rest)
                assert "fpw_cval" in names and ("fpw_src_size" in names or key.output == "fill_int"), key
            if key.fragment == glsl.PREVIEW_FRAG:
                assert {"fpw_view", "pv_heat", "pv_dilation"} <= names
        finally:
            prog.release()


@pytest.mark.parametrize("dtype", DTYPES)
def test_gather_sampling_equals_texel_fetch(gl, dtype):
    """Order 1 through textureGather (one call per channel) gives the values
    of one texelFetch per tap, in every mode it serves, near and far outside
    the source and through a pole: the same taps, weights and sums, so
    float32 rounding apart (bit-identical on llvmpipe, asserted; on NVIDIA float32
    results differ by an ulp and integers by one level at rounding ties, up
    to 7% of pixels where cval is a tie like 25.5). A wrong tap would be
    tens of levels off on these random images."""
    gather, fetch = _warper(), _warper(gather=False)
    if not gather.gather:
        pytest.skip("this context has neither GL 4.0 nor GL_ARB_gpu_shader5: no textureGather with components")
    maps = [sample_fpi(), RLinear(1.1, 0.02j, -700 - 300j), Mobius(1, 0, 0.05, -1 - 0.5j).inverse]
    exact = "llvmpipe" in gl.ctx.info["GL_RENDERER"]  # the same arithmetic, bit for bit
    try:
        for channels in (1, 2, 3, 4):
            img = make_image((48, 64, channels), dtype, seed=channels)
            cval = np.linspace(0.1, 0.9, channels) * (1 if dtype is np.float32 else np.iinfo(dtype).max)
            for transform in maps:
                for mode in ("constant", "edge", "wrap"):
                    a = gather.warp_image(img, transform, (40, 60), order=1, mode=mode, cval=cval)
                    b = fetch.warp_image(img, transform, (40, 60), order=1, mode=mode, cval=cval)
                    diff = np.abs(a.astype(np.float64) - b.astype(np.float64))
                    where = f"{channels} channels, {mode}, {type(transform).__name__}"
                    assert diff.max() <= (0.0 if exact else 1e-6 if dtype is np.float32 else 1.0), where
        assert any(key.gather_channels for key in gather.programs.programs)
        assert not any(key.gather_channels for key in fetch.programs.programs)
    finally:
        gather.release()
        fetch.release()


@pytest.mark.parametrize("dtype", DTYPES)
def test_packed_rgb_readback_equals_the_direct_one(gl, dtype):
    """3-channel pictures read back as RGB32UI texels (4, 2 or 1 pixels per
    texel), packed by the warp shader itself (FPI, order <= 1) or by a pass
    (cubic, the mesh path), equal the driver's own RGB readback: widths that
    are and are not multiples of 4, output tiles, hardware filtering."""
    packed, direct = _warper(pack_rgb=True), _warper(pack_rgb=False)
    small = _warper(pack_rgb=True, max_texture_size=16)
    try:
        for shape in [(48, 64), (37, 61), (5, 1)]:
            img = make_image(shape + (3,), dtype, seed=shape[1])
            cval = np.array([0.2, 0.5, 0.9]) * (1 if dtype is np.float32 else np.iinfo(dtype).max)
            for order, mode in [(1, "constant"), (3, "reflect")]:
                a = packed.warp_image(img, sample_fpi(), shape, order=order, mode=mode, cval=cval)
                b = direct.warp_image(img, sample_fpi(), shape, order=order, mode=mode, cval=cval)
                np.testing.assert_array_equal(a, b)
            np.testing.assert_array_equal(
                packed.warp_image(img, sample_fpi(), shape, order=1, mode="edge", cval=cval, hardware_filter=True),
                direct.warp_image(img, sample_fpi(), shape, order=1, mode="edge", cval=cval, hardware_filter=True),
            )
            out = (40, 30)  # larger than the 16 px textures of `small`: the output is tiled
            small_img = img[:16, :16]
            np.testing.assert_array_equal(
                small.warp_image(small_img, RLinear(0.9, 0.05j, 1 + 2j), out, order=1, mode="edge", cval=cval),
                direct.warp_image(small_img, RLinear(0.9, 0.05j, 1 + 2j), out, order=1, mode="edge", cval=cval),
            )
            np.testing.assert_array_equal(
                packed.warp_image_mesh(img, sample_fpi(), shape, order=1, mode="constant", cval=cval),
                direct.warp_image_mesh(img, sample_fpi(), shape, order=1, mode="constant", cval=cval),
            )
        in_shader = [key for key in packed.programs.programs if key.fragment == glsl.WARP_FRAG and key.pack_pixels]
        assert in_shader and any(key.fragment == glsl.PACK_RGB_FRAG for key in packed.programs.programs)
        assert not any(key.pack_pixels or key.fragment == glsl.PACK_RGB_FRAG for key in direct.programs.programs)
    finally:
        for w in (packed, direct, small):
            w.release()


def test_without_rgb32ui_targets_rgb_is_read_back_directly(gl, monkeypatch):
    """GL does not require RGB32UI to be renderable: where a driver refuses
    it, 3-channel pictures are read back as RGB (slower on some drivers,
    the same picture)."""
    from fpiwarp.backends.gl import readback

    assert isinstance(readback.renders_rgb32ui(gl.ctx), bool)
    monkeypatch.setattr(readback, "renders_rgb32ui", lambda ctx: False)
    warper = _warper()
    try:
        assert not warper.pack_rgb
        img = make_image((30, 41, 3), np.uint8)
        compare_warp(warper, img, sample_fpi(), (30, 41), 1, "constant", [1, 2, 3])
        assert not any(key.pack_pixels or key.fragment == glsl.PACK_RGB_FRAG for key in warper.programs.programs)
    finally:
        warper.release()


def test_a_warp_leaves_the_callers_framebuffer_bound(gl):
    """A GLWarper drawing in a caller's context (a window's, a preview's)
    gives the caller's framebuffer back when it is done."""
    ctx = gl.ctx
    mine = ctx.simple_framebuffer((8, 8))
    try:
        mine.use()
        img = make_image((16, 20, 3), np.uint8)
        gl.warp_image(img, sample_fpi(), (16, 20), order=1, mode="edge", cval=np.zeros(3))
        gl.warper.warp_image_mesh(img, sample_fpi(), (16, 20), order=1, mode="edge", cval=np.zeros(3))
        assert ctx.fbo is mine
    finally:
        ctx.detect_framebuffer(0).use()
        mine.release()


def test_what_a_caller_finds_bound_stays_usable_after_a_warp_of_another_size(gl):
    """A caller that binds again what it found bound (Renderer.warp_full,
    render_image) never gets a framebuffer the warp released: with one of
    the warper's own framebuffers bound, a warp of one size once left its
    cached target bound, and the next warp of another size released it."""
    from fpiwarp import viewer as fgl

    ctx, warper, f = gl.ctx, gl.warper, sample_fpi()
    warper.targets.dummy.use()  # one of the warper's own, as a previous call may leave it
    gl.warp_image(make_image((30, 20, 3), np.uint8), f, (30, 20), order=1, mode="constant", cval=np.zeros(3),
                  antialias=True)
    img = make_image((48, 64, 3), np.uint8)
    renderer = fgl.Renderer(ctx, warper=warper, antialias=True)
    try:
        renderer.set_image(img)
        renderer.set_transform(f)
        got = renderer.warp_full()  # a 64×48 target replaces the 20×30 one
    finally:
        renderer.release()
    want = gl.warp_image(img, f, (48, 64), order=1, mode="constant", cval=np.zeros(3), antialias=True)
    assert_images_agree(got, want, np.uint8)
    assert ctx.fbo is warper.targets.dummy
    mine = ctx.simple_framebuffer((8, 8))
    try:
        mine.use()
        gl.map_points(f, np.zeros((3, 2)))
        assert ctx.fbo is mine  # map_points gives the caller's framebuffer back too
    finally:
        ctx.detect_framebuffer(0).use()
        mine.release()


def test_unknown_core_is_refused_by_the_host_and_outside_in_the_shader(gl_backend, monkeypatch):
    from fpiwarp.backends import gl as glb
    from fpiwarp.backends.gl import warper as gl_warper
    from fpiwarp.block import ROW_HEADER, BlockKind, StageKind

    block = FPI([[0, 0], [9, 0], [9, 7], [0, 7]], [[1, 0], [9, 1], [8, 7], [0, 6]]).params().copy()
    block[1 + ROW_HEADER, 0] = 7

    class RawBlock:
        def params(self):
            return block

    pts = np.array([[1.0, 2.0], [3.5, 4.0], [8.0, 0.5]])
    with pytest.raises(ValueError, match="unknown core 7"):
        glb.GLWarper(glb.shared_context(), specialize=False).map_points(RawBlock(), pts)
    fake = BlockKind(stages=(StageKind(7, 0, 0, 0),), is_short=False, constant_dilation=None)
    monkeypatch.setattr(gl_warper, "describe", lambda b: fake)  # a host without the check
    assert np.isnan(glb.GLWarper(glb.shared_context(), specialize=False).map_points(RawBlock(), pts)).all()


@pytest.mark.parametrize("mode", ["constant", "wrap"])
def test_antialiased_warp_of_a_tiled_source_matches_the_reference(gl_small, mode):
    """Antialiasing is linear in the taps: summing source tiles still gives
    the reference's footprint averages."""
    img = make_image((48, 64, 3), np.uint8, seed=5)
    shrink = RLinear(0.35 + 0.08j, 0.06j, 2 + 1j) @ sample_fpi()
    want = fpiwarp.warp_image(img, shrink, (30, 40), mode=mode, cval=[10, 20, 30], antialias=True, backend="numpy")
    got = gl_small.warp_image(img, shrink, (30, 40), order=1, mode=mode, cval=np.array([10.0, 20.0, 30.0]),
                              antialias=True)
    assert_images_agree(got, want, np.uint8)
    _check_gl(gl_small.ctx)
