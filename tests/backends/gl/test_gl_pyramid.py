"""The GL antialiasing pyramid: the atlas of levels >= 1, its reuse across
calls, its tiling, and the texture-in/texture-out path."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.kernel_cases import assert_images_agree, make_image

import fpiwarp
from fpiwarp import RLinear
from fpiwarp.backends.gl.pyramid import atlas_layout, build_atlas
from fpiwarp.sampling.pyramid import Pyramid, level_sizes

#: Shrinks whose footprints read levels >= 1 (1/8: level 2; 1/7.5: a blend band; anisotropic).
SHRINKS = [RLinear(0.125, 0, 0.3 + 0.2j), RLinear(1 / 7.5 + 0.01j, 0, 0.1j),
           RLinear((1 / 24 + 1 / 6) / 2, (1 / 24 - 1 / 6) / 2, 1 + 1j)]


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 3000), st.integers(1, 3000))
def test_atlas_holds_every_level_once_in_disjoint_rectangles(h, w):
    (aw, ah), rects = atlas_layout(h, w)
    sizes = level_sizes(h, w)
    assert [(r[3], r[2]) for r in rects] == sizes
    boxes = rects[1:]
    for i, (x0, y0, rw, rh) in enumerate(boxes):
        assert 0 <= x0 and x0 + rw <= aw and 0 <= y0 and y0 + rh <= ah
        for x1, y1, sw, sh in boxes[i + 1:]:
            assert x0 + rw <= x1 or x1 + sw <= x0 or y0 + rh <= y1 or y1 + sh <= y0
    assert aw <= max(w, 2) and ah <= h // 2 + len(sizes) + 1  # about half the source, never larger


def test_atlas_levels_are_the_references_in_float32():
    img = make_image((37, 53, 3), np.uint16, seed=3)
    atlas, rects = build_atlas(img)
    assert atlas.dtype == np.float32
    for (x0, y0, w, h), level in zip(rects[1:], Pyramid(img).levels[1:], strict=True):
        np.testing.assert_array_equal(atlas[y0:y0 + h, x0:x0 + w], level.astype(np.float32))


def _aa(img, transform, backend, mode="reflect"):
    return fpiwarp.warp_image(img, transform, (24, 40), order=1, mode=mode, cval=[9, 99, 200], antialias=True,
                              backend=backend)


def test_pyramid_is_built_once_per_source_and_never_stale(gl_backend):
    from fpiwarp.backends import get_backend

    cache = get_backend(gl_backend).warper.pyramids
    img = make_image((120, 160, 3), np.uint8, seed=8)
    _aa(img, SHRINKS[0], gl_backend)
    builds = cache.builds
    for f in SHRINKS:  # other maps of the same pixels reuse it
        assert_images_agree(_aa(img, f, gl_backend), _aa(img, f, "numpy"), np.uint8)
    assert cache.builds == builds
    img[:, :80] = 255 - img[:, :80]  # changed in place: a new pyramid, not the stale one
    assert_images_agree(_aa(img, SHRINKS[0], gl_backend), _aa(img, SHRINKS[0], "numpy"), np.uint8)
    assert cache.builds == builds + 1
    other = fpiwarp.warp_image(img, SHRINKS[0], (24, 40), antialias=False, backend=gl_backend)
    assert cache.builds == builds + 1 and other.shape == (24, 40, 3)  # plain warps build none


@pytest.mark.parametrize("mode", ["constant", "wrap", "reflect"])
def test_tiled_source_and_atlas_agree_with_the_reference(make_gl_warper, mode):
    """A source and an atlas above the size limit are both tiled; each pass
    sums one tile of each."""
    warper = make_gl_warper(max_texture_size=32)
    img = make_image((120, 160, 3), np.uint8, seed=4)
    for f in SHRINKS:
        got = warper.warp_image(img, f, (24, 40), order=1, mode=mode, cval=np.array([9.0, 99.0, 200.0]),
                                antialias=True)
        assert_images_agree(got, _aa(img, f, "numpy", mode), np.uint8)


def test_batch_of_one_source_reuses_its_pyramid(gl_backend):
    from fpiwarp.backends import get_backend

    cache = get_backend(gl_backend).warper.pyramids
    img = make_image((120, 160, 3), np.uint8, seed=9)
    stack = np.stack([img] * 3)
    got = fpiwarp.warp_batch(stack, SHRINKS, (24, 40), antialias=True, backend=gl_backend)
    builds = cache.builds
    again = fpiwarp.warp_batch(stack, SHRINKS, (24, 40), antialias=True, backend=gl_backend)
    assert cache.builds == builds
    np.testing.assert_array_equal(got, again)
    for k, f in enumerate(SHRINKS):
        want = fpiwarp.warp_image(img, f, (24, 40), antialias=True, backend="numpy")
        assert_images_agree(got[k], want, np.uint8)


def test_textures_antialias_over_the_pyramid(gl_backend):
    from fpiwarp.backends.gl import shared_context

    ctx = shared_context()
    img = make_image((120, 160, 3), np.uint8, seed=6)
    tex = ctx.texture((160, 120), 3, np.ascontiguousarray(img).tobytes(), dtype="f1", alignment=1)
    try:
        for f in SHRINKS:
            res = fpiwarp.warp_image(tex, f, (24, 40), antialias=True)
            got = np.frombuffer(res.read(alignment=1), np.uint8).reshape(24, 40, 3)
            res.release()
            want = fpiwarp.warp_image(img, f, (24, 40), antialias=True, backend="numpy")
            assert_images_agree(got, want, np.uint8)
    finally:
        tex.release()
    assert ctx.error == "GL_NO_ERROR"
