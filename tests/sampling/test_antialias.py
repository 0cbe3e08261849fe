"""Antialiased warps (warp_image(..., antialias=True)): the numpy reference's
properties, the block's analytic derivatives, the argument's checks, and
every backend against the reference."""

import numpy as np
import pytest
from support import kernel_cases

import fpiwarp
from fpiwarp import FPI, Mobius, RLinear
from fpiwarp.backends import backend_capabilities
from fpiwarp.backends.capabilities import Capabilities
from fpiwarp.block import evaluate
from fpiwarp.block.jacobian import jacobian, wirtinger
from fpiwarp.block.sampling_rules import AA_MAX_TAPS
from fpiwarp.sampling.antialias import tap_counts
from fpiwarp.validation import check_antialias

SHRINK = RLinear(0.35 + 0.08j, 0.06j, 2 + 1j)  # about 1/3, sheared


def _shrunk(name):
    return SHRINK @ kernel_cases.MAPS[name]()


# --- the block's derivatives ------------------------------------------------


@pytest.mark.parametrize("name", sorted(kernel_cases.MAPS))
def test_block_jacobian_matches_finite_differences(name):
    for transform in (kernel_cases.MAPS[name](), _shrunk(name)):
        block = transform.params()
        pts = kernel_cases.frame_points(np.random.default_rng(3), n=300)
        got = jacobian(block, pts)
        h = 1e-5
        fd = np.stack([(evaluate(block, pts + [h, 0]) - evaluate(block, pts - [h, 0])) / (2 * h),
                       (evaluate(block, pts + [0, h]) - evaluate(block, pts - [0, h])) / (2 * h)], axis=-1)
        # Newton inverses are exact to their tolerance only: their differences are not
        tol = 1e-6 if kernel_cases.newton_atol(transform) == 0 else 1e-3
        assert np.abs(got - fd).max() <= tol * max(1.0, np.abs(fd).max())
        assert np.array_equal(wirtinger(block, pts)[0], evaluate(block, pts))


@pytest.mark.parametrize("name", ["fpi", "mobius", "rlinear", "compound"])
def test_block_jacobian_matches_the_maps_own(name):
    transform = kernel_cases.MAPS[name]().inverse
    pts = kernel_cases.frame_points(np.random.default_rng(4), n=300)
    want = transform.jacobian(pts)
    assert np.allclose(jacobian(transform.params(), pts), want, rtol=1e-5, atol=1e-6)  # float32 coefficients
    assert np.allclose(jacobian(transform.params(), pts, np.float32), want, rtol=1e-4, atol=1e-5)


# --- properties of the reference ---------------------------------------------


def test_tap_counts_are_capped_and_nan_safe():
    edges = np.array([0.3, 1.0, 1.005, 1.02, 2.0, 2.5, 2.6, 5.0, 8.75, 9.0, 1e9, np.inf, np.nan]) + 0j
    assert tap_counts(edges).tolist() == [1, 1, 1, 2, 2, 2, 3, 4, 5, 6, AA_MAX_TAPS, AA_MAX_TAPS, 1]


@pytest.mark.parametrize("mode", ["constant", "edge", "reflect", "wrap"])
def test_constant_image_stays_constant(mode):
    img = np.full((60, 80, 3), [17, 140, 250], np.uint8)
    f = FPI([[0, 0], [79, 0], [79, 59], [0, 59]], [[3, 5], [30, 0], [27, 22], [0, 18]])
    out = fpiwarp.warp_image(img, f, (24, 32), mode=mode, cval=[17, 140, 250], antialias=True, backend="numpy")
    assert np.array_equal(out, np.broadcast_to([17, 140, 250], out.shape))


@pytest.mark.parametrize("order", [0, 1, 3])
def test_identity_and_magnification_are_plain_interpolation(order):
    img = kernel_cases.make_image((40, 50, 3), np.uint16)
    # the identity, a sheared magnifier (|a| - |b| > 1: every direction grows) and a pure magnifier
    for transform in (RLinear(1, 0, 0), RLinear(1.7 + 0.4j, 0.1j, -3 + 2j), RLinear(2, 0, 0)):
        plain = fpiwarp.warp_image(img, transform, order=order, mode="reflect", backend="numpy")
        smooth = fpiwarp.warp_image(img, transform, order=order, mode="reflect", antialias=True, backend="numpy")
        assert np.array_equal(plain, smooth)  # bit for bit


def test_exact_half_shrink_is_a_tent_box_filter_in_wrap_mode():
    """At scale 1/2 each pixel averages 2×2 bilinear sub-samples at ±1/2 px:
    weights (1, 2, 1)/4 per axis around source pixel (2x, 2y)."""
    img = kernel_cases.make_image((16, 20, 1), np.float32, seed=2)
    out = fpiwarp.warp_image(img, RLinear(0.5, 0, 0), (8, 10), mode="wrap", antialias=True, backend="numpy")
    w = np.array([0.25, 0.5, 0.25])
    want = np.zeros((8, 10, 1))
    for dy in range(3):
        for dx in range(3):
            want += w[dy] * w[dx] * np.roll(img, (1 - dy, 1 - dx), axis=(0, 1))[::2, ::2]
    assert np.allclose(out, want, atol=1e-6)


def test_anisotropic_footprint_filters_one_direction_only():
    """Shrinking x by 4 and keeping y: stripes along x (period 2 in x) are
    averaged away, stripes along y (period 2 in y) are kept."""
    y, x = np.mgrid[0:32, 0:64]
    squeeze = RLinear(0.625 + 0j, -0.375 + 0j, 0)  # x -> x/4, y -> y
    assert np.allclose(squeeze.jacobian([[0, 0]])[0], [[0.25, 0], [0, 1]])
    across = (255 * (x % 2)).astype(np.uint8)
    along = (255 * (y % 2)).astype(np.uint8)
    out_across = fpiwarp.warp_image(across, squeeze, (32, 16), mode="edge", antialias=True, backend="numpy")
    out_along = fpiwarp.warp_image(along, squeeze, (32, 16), mode="edge", antialias=True, backend="numpy")
    assert np.all(np.abs(out_across[:, 1:-1].astype(int) - 128) <= 1)
    assert np.array_equal(out_along, along[:, :16])


def test_energy_above_the_output_nyquist_is_removed():
    """A sinusoid of 0.3 cycles per source pixel shrunk 1/3 lies at 0.9
    cycles per output pixel, far above Nyquist: plain sampling aliases it
    into a visible pattern; antialiasing (a box over the 3-px footprint,
    whose response at 0.9 cycles per pixel is |sinc(0.9)| = 0.11) leaves
    under 2.5% of its energy."""
    y, x = np.mgrid[0:240, 0:240].astype(np.float64)
    img = (0.5 + 0.5 * np.sin(2 * np.pi * (0.3 * x + 0.05 * y))).astype(np.float32)
    f = FPI([[0, 0], [239, 0], [239, 239], [0, 239]], [[2, 3], [80, 0], [82, 79], [0, 80]])
    plain = fpiwarp.warp_image(img, f, (70, 70), mode="reflect", backend="numpy")[5:-5, 5:-5]
    smooth = fpiwarp.warp_image(img, f, (70, 70), mode="reflect", antialias=True, backend="numpy")[5:-5, 5:-5]
    assert plain.std() > 0.2
    assert smooth.var() < 0.025 * plain.var()
    assert abs(smooth.mean() - 0.5) < 0.01


def test_pole_rule_and_cap_hold():
    """Pixels whose source position is not finite get cval; pixels next to
    the pole (huge footprints) read at most AA_MAX_TAPS² sub-samples and
    stay finite."""
    m = Mobius(2 + 1j, 3 - 1j, 0.004 + 0.006j, 1)
    img = kernel_cases.make_image((48, 64, 1), np.float32)
    out = fpiwarp.warp_image(img, m.inverse, (130, 130), mode="wrap", cval=7, antialias=True, backend="numpy")
    assert np.isfinite(out).all()
    pos = fpiwarp.source_positions(m.inverse, (130, 130))
    bad = ~np.isfinite(pos).all(axis=-1)
    assert np.all(out[bad] == 7)


# --- the argument ------------------------------------------------------------


def test_antialias_argument_is_checked():
    img = np.zeros((4, 4), np.uint8)
    for bad in ("yes", 1, None, 0.0):
        with pytest.raises(fpiwarp.FpiwarpError, match="antialias must be True or False"):
            fpiwarp.warp_image(img, RLinear(1, 0, 0), antialias=bad)
    out = fpiwarp.warp_image(img, RLinear(1, 0, 0), antialias=np.bool_(True))
    assert out.shape == (4, 4)


def test_batch_entry_points_pass_antialias():
    stack = np.stack([kernel_cases.make_image((30, 40, 3), np.uint8, seed=s) for s in range(3)])
    f = SHRINK
    want = np.stack([fpiwarp.warp_image(im, f, (12, 15), antialias=True) for im in stack])
    assert np.array_equal(fpiwarp.warp_batch(stack, f, (12, 15), antialias=True), want)
    assert np.array_equal(fpiwarp.warp_batch(stack, [f, f, f], (12, 15), antialias=True), want)
    got = list(fpiwarp.warp_images(list(stack), f, (12, 15), antialias=True))
    assert np.array_equal(np.stack(got), want)
    assert not np.array_equal(fpiwarp.warp_batch(stack, f, (12, 15)), want)


# --- every backend -------------------------------------------------------------


PARITY_MAPS = ["fpi", "mobius", "compound", "tps", "tps_inverse", "tps_pairs", "tps_pairs_inverse"]


def test_every_backend_antialiases_and_one_without_would_refuse_in_one_line(any_backend):
    assert backend_capabilities(any_backend).antialias
    with pytest.raises(fpiwarp.FpiwarpError, match="the x backend does not antialias"):
        check_antialias(True, Capabilities(), "x")
    assert check_antialias(False, Capabilities(), "x") is False


@pytest.mark.parametrize("name", PARITY_MAPS)
def test_backends_agree_on_antialiased_warps(any_backend, name):
    _agree_with_numpy(any_backend, _shrunk(name), (48, 64, 3), (30, 40), seed=11)


def _agree_with_numpy(backend, transform, image_shape, output_shape, seed):
    """``backend``'s antialiased warps of ``transform`` against the numpy
    reference: every dtype and order, a random border mode each."""
    rng = np.random.default_rng(seed)
    for dtype in kernel_cases.DTYPES:
        img = kernel_cases.make_image(image_shape, dtype, seed=int(rng.integers(100)))
        for order in kernel_cases.ORDERS:
            options = dict(order=order, mode=kernel_cases.MODES[int(rng.integers(4))], cval=[9, 99, 200],
                           antialias=True)
            want = fpiwarp.warp_image(img, transform, output_shape, backend="numpy", **options)
            got = fpiwarp.warp_image(img, transform, output_shape, backend=backend, **options)
            kernel_cases.assert_images_agree(got, want, dtype)


@pytest.mark.parametrize("mode", kernel_cases.MODES)
def test_backends_agree_antialiasing_next_to_the_pole(any_backend, mode):
    m = Mobius(2 + 1j, 3 - 1j, 0.004 + 0.006j, 1)
    img = kernel_cases.make_image((48, 64, 3), np.uint8)
    want = fpiwarp.warp_image(img, m.inverse, (130, 130), mode=mode, cval=[1, 2, 3], antialias=True,
                              backend="numpy")
    got = fpiwarp.warp_image(img, m.inverse, (130, 130), mode=mode, cval=[1, 2, 3], antialias=True,
                             backend=any_backend)
    kernel_cases.assert_images_agree(got, want, np.uint8)


def test_gl_hardware_filter_with_antialias_keeps_the_options_limits(gl_backend):
    """The combination filters in the texture unit (tests/backends/gl/test_gl_texgrad.py);
    what hardware_filter cannot do stays refused."""
    with pytest.raises(fpiwarp.FpiwarpError, match="hardware_filter"):
        fpiwarp.warp_image(np.zeros((4, 4), np.uint8), SHRINK, order=3, antialias=True, backend=gl_backend,
                           backend_options={"hardware_filter": True})


def test_viewer_export_antialiases(gl_backend):
    """Renderer(antialias=True).warp_full is the picture of warp_image(antialias=True)."""
    from fpiwarp import viewer as fgl
    from fpiwarp.backends import get_backend

    backend = get_backend(gl_backend)
    img = kernel_cases.make_image((48, 64, 3), np.uint8)
    want = fpiwarp.warp_image(img, SHRINK, antialias=True, backend="numpy")
    renderer = fgl.Renderer(backend.ctx, warper=backend.warper, antialias=True)
    try:
        renderer.set_image(img)
        renderer.set_transform(SHRINK)
        kernel_cases.assert_images_agree(renderer.warp_full(), want, np.uint8)
    finally:
        renderer.release()
    with pytest.raises(fpiwarp.FpiwarpError, match="antialias must be True or False"):
        fgl.Renderer(backend.ctx, warper=backend.warper, antialias="on")


def test_cli_warp_antialiases_by_default_except_at_order_0(tmp_path, capsys):
    """``fpiwarp warp`` writes the picture of warp_image(antialias=True) by
    default and with ``--antialias``, the plain one with ``--no-antialias``
    and at ``--order 0`` (labels are never averaged); its help names the
    backends that antialias, from their capabilities."""
    from fpiwarp.cli.commands import antialiasing_backends, main

    img = kernel_cases.make_image((40, 60, 3), np.uint8)
    src = tmp_path / "in.png"
    fpiwarp.write_image(src, img)
    corners = ["--src", "0,0,59,0,59,39,0,39", "--dst", "2,1,20,0,19,13,0,12"]
    f = FPI([[0, 0], [59, 0], [59, 39], [0, 39]], [[2, 1], [20, 0], [19, 13], [0, 12]])
    runs = {"default": [], "on": ["--antialias"], "off": ["--no-antialias"], "nearest": ["--order", "0"],
            "nearest on": ["--order", "0", "--antialias"]}
    for name, flags in runs.items():
        assert main(["warp", str(src), str(tmp_path / f"{name}.png"), *corners, *flags]) == 0
    got = {name: fpiwarp.read_image(tmp_path / f"{name}.png") for name in runs}
    smooth, plain = fpiwarp.warp_image(img, f, antialias=True), fpiwarp.warp_image(img, f)
    assert not np.array_equal(smooth, plain)
    assert np.array_equal(got["default"], smooth) and np.array_equal(got["on"], smooth)
    assert np.array_equal(got["off"], plain)
    assert np.array_equal(got["nearest"], fpiwarp.warp_image(img, f, order=0))
    assert np.array_equal(got["nearest on"], fpiwarp.warp_image(img, f, order=0, antialias=True))
    assert set(antialiasing_backends()) == {n for n in fpiwarp.backends.REGISTRY
                                            if backend_capabilities(n).antialias} >= {"numpy"}
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["warp", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "Backends that antialias: " + ", ".join(antialiasing_backends()) in text


# --- over the pyramid: levels >= 1 and the blend between levels ----------------

#: Maps whose footprints reach pyramid levels >= 1: uniform shrinks landing
#: inside one level, in a blend band, far up the pyramid, anisotropic, and an
#: FPI whose shrink varies across the frame (crossing levels and bands).
PYRAMID_MAPS = {
    "shrink 1/8": lambda: RLinear(0.125, 0, 0.3 + 0.2j),
    "shrink 1/7.5 (blend band)": lambda: RLinear(1 / 7.5 + 0.01j, 0, 0.1j),
    "shrink 1/40": lambda: RLinear(1 / 40, 0, 0.5),
    "anisotropic 1/24 x 1/6": lambda: RLinear((1 / 24 + 1 / 6) / 2, (1 / 24 - 1 / 6) / 2, 1 + 1j),
    "fpi varying shrink": lambda: FPI([[0, 0], [159, 0], [159, 119], [0, 119]],
                                      [[1, 2], [38, 0], [9, 6], [0, 20]]),
}


@pytest.mark.parametrize("name", sorted(PYRAMID_MAPS))
def test_backends_agree_over_the_pyramid(any_backend, name):
    _agree_with_numpy(any_backend, PYRAMID_MAPS[name](), (120, 160, 3), (24, 40), seed=17)
