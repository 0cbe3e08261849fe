"""Prepared warps (issue 14): the Warper's fast path, the backends' bound
maps and per-call job caches, and the Warp kernels specialized per kind.

Every fast path is checked against the numpy reference with the parity
rules of tests/test_backend_parity.py (kernel_cases.assert_images_agree),
and every cache against a changed input: another map (same kind or
another), shape, dtype, order, mode, cval, output shape, a reassigned
Warper option and a mutated map object must never get a stale result.
"""

import pickle

import numpy as np
import pytest
from support.kernel_cases import assert_images_agree, make_image, region_map, tps_map, tps_pairs_map

import fpiwarp
from fpiwarp import FPI, RLinear
from fpiwarp.warping import Warper

QUAD = [[0, 0], [47, 0], [47, 39], [0, 39]]


def fpi(k=0.0):
    """FPIs of one kind (one stage, affine core) with different values."""
    return FPI(QUAD, [[1 + k, 2], [45, 1 - k], [48, 38 + k], [-1, 40]])


def want(image, transform, shape=None, **kw):
    return fpiwarp.warp_image(image, transform, shape, backend="numpy", **kw)


def agree(got, expected):
    assert_images_agree(got, expected, expected.dtype.type)


@pytest.fixture(params=["opencl", "warp", "gl"])
def device_backend(request):
    return request.getfixturevalue(f"{request.param}_backend")


def test_warper_on_many_images_matches_the_reference(device_backend):
    warper = Warper(fpi(1.0), order=1, mode="reflect", cval=7, backend=device_backend)
    for seed, (shape, dtype) in enumerate([((40, 48, 3), np.uint8), ((40, 48, 3), np.uint8), ((33, 20), np.uint16),
                                            ((40, 48, 4), np.float32), ((40, 48, 3), np.uint8), ((33, 20), np.uint16)]):
        image = make_image(shape, dtype, seed)
        agree(warper(image), want(image, fpi(1.0), order=1, mode="reflect", cval=7))


@pytest.mark.parametrize("order, mode", [(0, "wrap"), (1, "constant"), (3, "edge")])
def test_prepared_calls_serve_no_stale_result(device_backend, order, mode):
    """Plain calls alternating maps of one kind, of other kinds, shapes,
    dtypes, cval and output shapes each get their own result."""
    rgb = make_image((40, 48, 3), np.uint8, 1)
    gray = make_image((40, 48), np.uint16, 2)
    maps = [fpi(0.0), fpi(2.0), RLinear(1.1, 0.05, 3) @ fpi(1.0), fpi(0.0)]
    for transform in maps:
        for image, shape, cval in [(rgb, None, 0), (rgb, None, [9, 99, 199]), (gray, (30, 52), 5), (rgb, (30, 52), 0)]:
            got = fpiwarp.warp_image(image, transform, shape, order=order, mode=mode, cval=cval,
                                     backend=device_backend)
            agree(got, want(image, transform, shape, order=order, mode=mode, cval=cval))


def test_mutated_map_object_is_not_served_stale(device_backend):
    image = make_image((40, 48, 3), np.uint8, 3)
    shift = RLinear(1, 0, 2)
    agree(fpiwarp.warp_image(image, shift, backend=device_backend), want(image, shift))
    shift.l3 = complex(-3, 4)  # the same object, another map
    agree(fpiwarp.warp_image(image, shift, backend=device_backend), want(image, RLinear(1, 0, complex(-3, 4))))


def test_warper_reassigned_options_drop_the_prepared_state(device_backend):
    image = make_image((40, 48, 3), np.uint8, 4)
    warper = Warper(fpi(0.0), backend=device_backend)
    agree(warper(image), want(image, fpi(0.0)))
    warper.transform = fpi(3.0)
    agree(warper(image), want(image, fpi(3.0)))
    warper.cval = 200
    warper.mode = "constant"
    agree(warper(image), want(image, fpi(3.0), cval=200))
    warper.output_shape = (21, 30)
    agree(warper(image), want(image, fpi(3.0), (21, 30), cval=200))
    restored = pickle.loads(pickle.dumps(warper)) if device_backend != "gl" else warper
    agree(restored(image), want(image, fpi(3.0), (21, 30), cval=200))


def test_warper_fast_path_still_checks_unknown_images(device_backend):
    warper = Warper(fpi(0.0), backend=device_backend)
    image = make_image((40, 48, 3), np.uint8, 5)
    warper(image)
    with pytest.raises(fpiwarp.FpiwarpError):
        warper(image.astype(np.int32))
    with pytest.raises(fpiwarp.FpiwarpError):
        warper(image[:, :, :1].repeat(5, axis=2))
    strided = make_image((40, 96, 3), np.uint8, 6)[:, ::2]  # not contiguous: the checked path copies it
    agree(warper(strided), want(np.ascontiguousarray(strided), fpi(0.0)))


@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("mode", ["constant", "edge", "reflect", "wrap"])
def test_warp_kind_kernels_match_the_reference(warp_backend, order, mode):
    """The kernels specialized per kind of map, order, channels, mode and
    dtype, on maps of every core and with regions."""
    for seed, (transform, dtype, channels) in enumerate(
        [(fpi(1.0), np.uint8, 3), (RLinear(1.1, 0.05, 3) @ fpi(1.0), np.float32, 1), (tps_map(), np.uint16, 2),
         (region_map(), np.uint8, 4), (tps_pairs_map(), np.uint8, 3), (tps_pairs_map().inverse, np.float32, 2)]
    ):
        image = make_image((40, 48, channels), dtype, seed)
        got = fpiwarp.warp_image(image, transform, order=order, mode=mode, cval=3, backend=warp_backend)
        agree(got, want(image, transform, order=order, mode=mode, cval=3))


def test_warp_kind_kernels_are_made_once_per_kind(warp_backend):
    from fpiwarp.kernels.nvwarp import factory

    from fpiwarp.block import describe

    key = factory.kind_key(describe(fpi(0.0).params()))
    assert key == factory.kind_key(describe(fpi(5.0).params())) == ((0, 0),)
    kernel = factory.image_kernel(factory.image_spec(key, 1, 0, 3, np.uint8))
    assert factory.image_kernel(factory.image_spec(key, 1, 0, 3, np.dtype(np.uint8))) is kernel
    assert factory.image_kernel(factory.image_spec(key, 1, 1, 3, np.uint8)) is not kernel
    assert factory.image_kernel(factory.image_spec(key, 1, 0, 3, np.uint8, rows=True)) is not kernel


@pytest.mark.parametrize("width", [257, 1000, 1025, 1920])
def test_opencl_group_widths_cover_every_pixel_of_wide_rows(opencl_backend, width):
    """Rows wider than the narrow groups are cut into groups of a multiple
    of GROUP_STEP px (launch_width): every pixel, the row's last included,
    matches the reference."""
    from fpiwarp.backends import get_backend
    from fpiwarp.backends.opencl.backend import launch_width

    local = launch_width(get_backend("opencl"), width)
    assert local * -(-width // local) - width < 128  # little padding
    image = make_image((3, width, 3), np.uint8, width)
    shift = RLinear(1, 0, complex(-0.3, 0.4))
    for order in (0, 1, 3):
        got = fpiwarp.warp_image(image, shift, order=order, mode="edge", backend=opencl_backend)
        agree(got, want(image, shift, order=order, mode="edge"))
