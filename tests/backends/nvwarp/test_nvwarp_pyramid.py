"""The Warp backend's source pyramid (fpiwarp.backends.nvwarp.pyramid):
its levels are the numpy reference's (fpiwarp.sampling.pyramid), it is
built once per call, per batch of one source and per prepared job, and a
host image changed in place is never warped with an old pyramid."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.kernel_cases import assert_images_agree, make_image

import fpiwarp
from fpiwarp import FPI, RLinear
from fpiwarp.sampling.pyramid import Pyramid

SHRINK = RLinear(1 / 6 + 0.02j, 0.01, 0.4 + 0.3j)  # levels 1 and 2, a blend band
ANISO = RLinear((1 / 12 + 1 / 3) / 2, (1 / 12 - 1 / 3) / 2, 1 + 1j)


@pytest.fixture
def warp(warp_backend):
    from fpiwarp.backends import get_backend

    return get_backend(warp_backend)


def _levels(warp, image):
    """[level k (h_k, w_k, C) float32 for k >= 1] of the device pyramid of one image."""
    wp = warp._wp
    src = wp.array(image, dtype=wp.dtype_from_numpy(image.dtype), device=warp.device)
    pyramid = warp.pyramid([(src, 0)], *image.shape)
    table, data = pyramid.levels.numpy(), pyramid.array.numpy()
    return [data[r0:r0 + h, :w] for r0, h, w in table[1:]], table


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(h=st.integers(1, 37), w=st.integers(1, 37), c=st.integers(1, 4),
       dtype=st.sampled_from([np.uint8, np.uint16, np.float32]), seed=st.integers(0, 99))
def test_levels_are_the_references(warp, h, w, c, dtype, seed):  # (the backend is shared, not reset)
    """Every level (sizes, 2 × 2 means with clamped indices) equals the
    float64 reference: exactly where float32 holds the means of 4^k
    integers (uint8 up to level 8, uint16 up to level 4), else within
    float32 rounding."""
    image = make_image((h, w, c), dtype, seed=seed)
    got, table = _levels(warp, image)
    want = Pyramid(image).levels[1:]
    assert [g.shape for g in got] == [lv.shape for lv in want]
    assert table[0].tolist() == [0, h, w]
    exact = {np.uint8: 8, np.uint16: 4, np.float32: 0}[dtype]
    for k, (g, lv) in enumerate(zip(got, want, strict=True), start=1):
        if k > exact:
            np.testing.assert_allclose(g, lv, rtol=1e-6, atol=1e-7)
        else:
            np.testing.assert_array_equal(g, lv)


def _count_builds(monkeypatch, warp):
    """A list that grows by (sources, height, width, channels) for each pyramid the backend builds."""
    built = []
    make = warp.pyramid

    def counting(*args):
        built.append(args)
        return make(*args)

    monkeypatch.setattr(warp, "pyramid", counting)
    return built


def test_a_prepared_job_builds_its_pyramid_once(warp, monkeypatch):
    """A job warped by map after map (the preview's, an animation's) reads
    one pyramid, built when it is made, and gives warp_image's pictures."""
    img = make_image((96, 128, 3), np.uint8, seed=4)
    maps = [RLinear(1 / s, 0.1 * s, 2 + 1j) for s in (3, 5, 9)] + [ANISO]
    want = [fpiwarp.warp_image(img, m, (20, 30), mode="reflect", antialias=True, backend="numpy") for m in maps]
    built = _count_builds(monkeypatch, warp)
    job = warp.prepare_warp(img, (20, 30), order=1, mode="reflect", cval=np.zeros(3), antialias=True)
    for m, w in zip(maps, want, strict=True):
        job.set_map(m)
        job.launch()
        job.finish()
        assert_images_agree(job.read(), w, np.uint8)
    assert len(built) == 1


def test_a_batch_of_one_source_builds_one_pyramid(warp, monkeypatch):
    """A stack of one source broadcast over N maps (stride 0, as the
    backend receives it) reads one pyramid; a stack of N images reads one
    each; both equal the loop of warp_image over the images."""
    img = make_image((64, 80, 3), np.uint8, seed=2)
    maps = [SHRINK, ANISO, RLinear(1 / 9, 0, 1j)]
    built = _count_builds(monkeypatch, warp)
    one = warp.warp_batch(np.broadcast_to(img, (3, *img.shape)), maps, (16, 20), order=1, mode="constant",
                          cval=np.zeros(3), antialias=True)
    assert len(built) == 1 and len(built[0][0]) == 1  # one source
    for got, m in zip(one, maps, strict=True):
        assert np.array_equal(got, fpiwarp.warp_image(img, m, (16, 20), antialias=True, backend="warp"))
    stack = np.stack([make_image((64, 80, 3), np.uint8, seed=s) for s in range(3)])
    many = fpiwarp.warp_batch(stack, maps, (16, 20), antialias=True, backend="warp")
    for got, im, m in zip(many, stack, maps, strict=True):
        assert_images_agree(got, fpiwarp.warp_image(im, m, (16, 20), antialias=True, backend="numpy"), np.uint8)
        assert np.array_equal(got, fpiwarp.warp_image(im, m, (16, 20), antialias=True, backend="warp"))


def test_calls_on_one_host_image_share_its_pyramid_until_it_changes(warp, monkeypatch):
    """warp_image calls on one numpy image (an animation, a Warper per
    frame) build its levels once; changed in place, it gets new levels:
    the next call's picture is that of the new pixels."""
    img = make_image((64, 80, 3), np.uint8, seed=6)
    built = _count_builds(monkeypatch, warp)
    first = fpiwarp.warp_image(img, SHRINK, (12, 16), antialias=True, backend="warp")
    again = [fpiwarp.warp_image(img, m, (12, 16), antialias=True, backend="warp") for m in (ANISO, SHRINK)]
    assert len(built) == 1 and np.array_equal(again[1], first)
    assert_images_agree(again[0], fpiwarp.warp_image(img, ANISO, (12, 16), antialias=True, backend="numpy"),
                        np.uint8)
    img[:] = 255 - img
    second = fpiwarp.warp_image(img, SHRINK, (12, 16), antialias=True, backend="warp")
    assert len(built) == 2
    assert_images_agree(second, fpiwarp.warp_image(img, SHRINK, (12, 16), antialias=True, backend="numpy"),
                        np.uint8)
    assert not np.array_equal(first, second)


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
def test_device_arrays_antialias_over_the_pyramid(warp, dtype):
    """Warp arrays, one image and a strided (channels-first) stack, warped
    in place over their pyramids: the numpy reference's pictures."""
    wp = warp._wp
    stack = np.stack([make_image((60, 90, 3), dtype, seed=s) for s in (1, 2)])
    maps = [SHRINK, FPI([[0, 0], [89, 0], [89, 59], [0, 59]], [[1, 2], [20, 0], [6, 4], [0, 11]])]
    want = [fpiwarp.warp_image(im, m, (14, 22), mode="wrap", cval=3, antialias=True, backend="numpy")
            for im, m in zip(stack, maps, strict=True)]
    one = fpiwarp.warp_image(wp.array(stack[0], device=warp.device), maps[0], (14, 22), mode="wrap", cval=3,
                             antialias=True)
    assert_images_agree(one.numpy(), want[0], dtype)
    first = wp.array(np.ascontiguousarray(stack.transpose(0, 3, 1, 2)), device=warp.device)
    got = fpiwarp.warp_batch(first, maps, (14, 22), mode="wrap", cval=3, antialias=True, channels="first")
    for g, w in zip(got.numpy().transpose(0, 2, 3, 1), want, strict=True):
        assert_images_agree(g, w, dtype)
