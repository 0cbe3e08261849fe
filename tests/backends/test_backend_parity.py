"""Rules every backend shares, checked on each backend that can run."""

import numpy as np
import pytest
from support import kernel_cases
from support.kernel_cases import (
    MAPS,
    MODES,
    ORDERS,
    Staged,
    assert_close_relative,
    compare_warp,
    frame_points,
    make_image,
    region_map,
    tps_inverse_stage,
    tps_map,
    tps_stage,
)

import fpiwarp
from fpiwarp import FPI, Mobius, RLinear
from fpiwarp.backends import get_backend
from fpiwarp.block import evaluate


@pytest.mark.parametrize("mode", ["constant", "edge", "reflect", "wrap"])
def test_far_away_source_positions_get_cval_in_every_mode(any_backend, mode):
    """Positions beyond 2**24 px count as outside, like non-finite ones."""
    img = np.full((6, 7, 3), 9, np.uint8)
    far = RLinear(1, 0, -(2.0**25))
    out = fpiwarp.warp_image(img, far, mode=mode, cval=[1, 2, 3], backend=any_backend)
    assert np.array_equal(out, np.broadcast_to([1, 2, 3], (6, 7, 3)))
    near = RLinear(1, 0, -(2.0**20))  # far, but within range: the border mode decides
    out = fpiwarp.warp_image(img, near, mode=mode, cval=[1, 2, 3], backend=any_backend)
    expected = [1, 2, 3] if mode == "constant" else [9, 9, 9]
    assert np.array_equal(out, np.broadcast_to(expected, (6, 7, 3)))


def test_backends_agree_with_the_reference_on_an_fpi(any_backend):
    f = FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 3], [60, -2], [66, 50], [-3, 44]])
    y, x = np.mgrid[0:48, 0:64]
    img = np.stack([x * 4, y * 5, (x + y) * 2], axis=-1).astype(np.uint8)
    ref = fpiwarp.warp_image(img, f, backend="numpy")
    out = fpiwarp.warp_image(img, f, backend=any_backend)
    diff = np.abs(out.astype(int) - ref.astype(int))
    assert np.mean(diff <= 1) >= 0.998
    pts = np.random.default_rng(0).uniform(0, 64, size=(100, 2))
    assert np.allclose(fpiwarp.map_points(f, pts, backend=any_backend), f(pts), rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("name", sorted(kernel_cases.MAPS))
def test_map_points_of_every_kind_of_stage(any_backend, name):
    """The shared cases (FPI family, TPS, Newton inverse, stage compounds)
    on every backend, against the block's float64 reference."""
    transform = kernel_cases.MAPS[name]()
    pts = kernel_cases.frame_points(np.random.default_rng(7), n=500)
    want = evaluate(transform.params(), pts, np.float64)
    got = fpiwarp.map_points(transform, pts, backend=any_backend)
    kernel_cases.assert_close_relative(got, want, atol=kernel_cases.newton_atol(transform))


def test_map_points_with_regions(any_backend):
    transform = kernel_cases.region_map()
    pts = kernel_cases.frame_points(np.random.default_rng(8), n=500)
    far = (np.abs(pts[:, 0] - 52) > 1e-3) & (np.abs(pts[:, 1] - 6) > 1e-3)  # off the region lines
    want = evaluate(transform.params(), pts[far], np.float64)
    kernel_cases.assert_close_relative(fpiwarp.map_points(transform, pts[far], backend=any_backend), want)


def test_integer_rounding_and_clipping(any_backend):
    """Cubic overshoot clips to the dtype range; float32 is neither rounded nor clipped."""
    img = np.zeros((8, 8, 1), np.float32)
    img[:, 4:] = 1.0
    shift = RLinear(1, 0, 0.3)

    def warp(image):
        return fpiwarp.warp_image(image, shift, (8, 8), order=3, mode="edge", cval=0, backend=any_backend)

    got_f = warp(img)
    assert got_f.min() < 0 and got_f.max() > 1
    for dtype in (np.uint8, np.uint16):
        top = np.iinfo(dtype).max
        got = warp((img * top).astype(dtype))
        assert got.min() == 0 and got.max() == top
        want = np.clip(np.floor(got_f.astype(np.float64) * top + 0.5), 0, top)
        assert np.abs(got.astype(np.float64) - want).max() <= 1


def test_public_api_with_2d_image(any_backend):
    img = kernel_cases.make_image((48, 64), np.uint8)
    got = fpiwarp.warp_image(img, kernel_cases.sample_fpi(), backend=any_backend)
    want = fpiwarp.warp_image(img, kernel_cases.sample_fpi())
    assert got.shape == (48, 64)
    kernel_cases.assert_images_agree(got[..., None], want[..., None], np.uint8)


def test_map_points_regions_match_reference_away_from_their_lines(any_backend, rng):
    transform = region_map()
    pts = frame_points(rng)
    far = (np.abs(pts[:, 0] - 52) > 1e-3) & (np.abs(pts[:, 1] - 6) > 1e-3)
    want = evaluate(transform.params(), pts[far], np.float64)
    assert_close_relative(fpiwarp.map_points(transform, pts[far], backend=any_backend), want)
    moved = fpiwarp.map_points(transform, np.array([[60.0, 20.0], [30.0, 2.0]]), backend=any_backend)
    assert_close_relative(moved, np.array([[62.0, 21.0], [0.9 * 30 - 0.1 * 2 + 1, 0.1 * 30 + 0.9 * 2 - 2]]))


@pytest.mark.parametrize(
    "transform",
    [Mobius(1, 0, 0.05, -1 - 0.5j).inverse, RLinear(1, 0, 30 + 20j) @ Mobius(1, 0, 0.05, 1, center=0).inverse],
    ids=["pole-at-row-10-col-20", "pole-after-a-shift"],
)
def test_pole_inside_the_output_is_handled_like_the_reference(any_backend, transform):
    """Positions near the pole are huge or non-finite: handled like the
    reference (clipped, never a crash)."""
    img = make_image((40, 60, 3), np.uint8)
    for mode in MODES:
        compare_warp(get_backend(any_backend), img, transform, (40, 60), 1, mode, [5, 6, 7])


def test_non_finite_positions_give_cval_in_every_mode(any_backend):
    """A Newton inverse that cannot converge (no steps, zero tolerance) sends
    every pixel outside: the output is cval everywhere, whatever the mode."""
    transform = Staged([tps_stage()], [tps_inverse_stage(iters=0, tol=0.0)])
    img = make_image((20, 30, 4), np.uint8)
    for order in ORDERS:
        for mode in MODES:
            out = fpiwarp.warp_image(img, transform, (20, 30), order=order, mode=mode,
                                     cval=[1.0, 2, 3, 254.6], backend=any_backend)
            assert np.all(out == np.array([1, 2, 3, 255], np.uint8))


def _constrained_maps():
    src = [[0, 0], [63, 0], [63, 47], [0, 47]]
    return {
        "constrained": fpiwarp.ConstrainedFPI(src, [[4, 3], [60, -2], [66, 50], [-3, 44]], edges=(0, 2)),
        "local": fpiwarp.LocalDeformation(src, [[4, 3], [60, -2], [66, 50], [-3, 44]], edges=(3, 1)),
    }


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("name", ["tps", "region", "compound", "constrained", "local"])
def test_warp_image_of_tps_regions_and_compounds(any_backend, name, order):
    makers = {"tps": tps_map, "region": region_map, "compound": MAPS["compound"],
              "constrained": lambda: _constrained_maps()["constrained"], "local": lambda: _constrained_maps()["local"]}
    transform = makers[name]()
    img = make_image((48, 64, 3), np.uint8, seed=5)
    # A local deformation's device inverse (float32 Newton, stopped at 5e-5 of
    # the region's scale) is ~1e-2 px from the host's since the spline follows
    # the constrained lines over the whole picture: on this noise image a
    # cubic sample then moves by up to 2 levels.
    levels = 2.0 if name == "local" else 1.0
    for mode in MODES:
        compare_warp(get_backend(any_backend), img, transform, (48, 64), order, mode, [10, 20, 30], levels=levels)


def test_local_deformation_warp_and_inverse_points(any_backend):
    """A LocalDeformation's image warp (Newton inverse inside, similarities in
    the outer regions, the core skipped there) and its inverse's points:
    within the device's Newton accuracy of the float64 reference, and each
    result the same alone as among neighbours that converge at other steps."""
    src = np.array([[30.0, 20.0], [66.0, 20.0], [66.0, 44.0], [30.0, 44.0]])
    dst = src + [[3.0, -4.0], [2.0, 2.0], [-2.0, 3.0], [1.0, -2.0]]
    local = fpiwarp.LocalDeformation(src, dst, edges=(1, 3))
    img = kernel_cases.make_image((64, 96, 3), np.uint8)
    want = fpiwarp.warp_image(img, local, backend="numpy")
    got = fpiwarp.warp_image(img, local, backend=any_backend)
    kernel_cases.assert_images_agree(got, want, np.uint8)
    pts = np.random.default_rng(9).uniform([-10, -10], [106, 74], size=(700, 2))
    inverse = local.inverse
    want = evaluate(inverse.params(), pts, np.float64)
    got = fpiwarp.map_points(inverse, pts, backend=any_backend)
    scale = float(np.ptp(src, axis=0).max())
    kernel_cases.assert_close_relative(got, want, rtol=0.0, atol=2e-4 * scale)
    picks = range(0, 700, 97)
    alone = np.concatenate([fpiwarp.map_points(inverse, pts[i : i + 1], backend=any_backend) for i in picks])
    np.testing.assert_allclose(alone, got[::97], rtol=0, atol=1e-5 * scale)
