"""moderngl textures on the gl backend (llvmpipe here): texture in,
texture out, rendered in place, equal to the gl backend on numpy images."""

import numpy as np
import pytest
from support.array_cases import FPI, fails, make_image

import fpiwarp

FORMATS = {np.dtype(np.uint8): "f1", np.dtype(np.uint16): "u2", np.dtype(np.float32): "f4"}


@pytest.fixture
def ctx(gl_backend):
    from fpiwarp.backends.gl import shared_context

    return shared_context()


def texture(ctx, img):
    img3 = img if img.ndim == 3 else img[:, :, None]
    h, w, c = img3.shape
    return ctx.texture((w, h), c, np.ascontiguousarray(img3).tobytes(), dtype=FORMATS[img3.dtype])


def read(tex, dtype):
    w, h = tex.size
    return np.frombuffer(tex.read(), dtype=dtype).reshape(h, w, tex.components)


def forbid_readback(monkeypatch):
    import moderngl

    from fpiwarp.backends.gl import readback

    monkeypatch.setattr(readback, "read_direct", fails)
    monkeypatch.setattr(readback, "read_packed", fails)
    monkeypatch.setattr(moderngl.Texture, "read", fails)
    monkeypatch.setattr(moderngl.Texture, "write", fails)


@pytest.mark.parametrize("dtype, channels, order, mode", [
    (np.uint8, 3, 1, "constant"), (np.uint8, 1, 0, "edge"), (np.uint8, 4, 3, "reflect"),
    (np.uint16, 2, 1, "wrap"), (np.float32, 3, 3, "constant"), (np.float32, 4, 1, "edge"),
])
def test_textures_equal_the_numpy_path(ctx, rng, monkeypatch, dtype, channels, order, mode):
    img = make_image(rng, (24, 32, channels), dtype)
    kw = {"output_shape": (20, 40), "order": order, "mode": mode, "cval": 0.25 if dtype == np.float32 else 7}
    ref = fpiwarp.warp_image(img, FPI, backend="gl", **kw)
    tex = texture(ctx, img)
    state = (tex.filter, tex.repeat_x, tex.repeat_y)
    forbid_readback(monkeypatch)
    res = fpiwarp.warp_image(tex, FPI, **kw)
    monkeypatch.undo()
    assert res.ctx is ctx and res.size == (40, 20) and res.dtype == tex.dtype
    np.testing.assert_array_equal(read(res, dtype), ref.reshape(20, 40, channels))
    assert (tex.filter, tex.repeat_x, tex.repeat_y) == state  # the caller's sampling state is given back


def test_newton_maps_take_the_coarse_pass_as_host_images_do(ctx, rng):
    from support.batch_cases import local_map

    img = make_image(rng, (40, 70, 4), np.uint8)
    local = local_map(1, 70, 40)
    res = fpiwarp.warp_image(texture(ctx, img), local)
    np.testing.assert_array_equal(read(res, np.uint8), fpiwarp.warp_image(img, local, backend="gl"))


def test_out_texture_and_errors(ctx, rng):
    img = make_image(rng, (24, 32, 4), np.uint8)
    tex = texture(ctx, img)
    out = ctx.texture((32, 24), 4, dtype="f1")
    glo = out.glo
    res = fpiwarp.warp_image(tex, FPI, out=out)
    assert res is out and res.glo == glo
    np.testing.assert_array_equal(read(out, np.uint8), fpiwarp.warp_image(img, FPI, backend="gl"))
    with pytest.raises(fpiwarp.ArgumentError, match="own texture"):
        fpiwarp.warp_image(tex, FPI, out=tex)
    with pytest.raises(fpiwarp.ArgumentError, match="out= must be"):
        fpiwarp.warp_image(tex, FPI, out=ctx.texture((31, 24), 4, dtype="f1"))
    with pytest.raises(fpiwarp.DeviceMismatchError, match="backend='gl'"):
        fpiwarp.warp_image(tex, FPI, backend="warp")
    with pytest.raises(fpiwarp.ArgumentError, match="dtype must be"):
        fpiwarp.warp_image(ctx.texture((4, 4), 1, dtype="u1"), FPI)
    np.testing.assert_array_equal(read(tex, np.uint8), img)


def test_texture_of_another_context(ctx, rng):
    from fpiwarp.backends.gl import create_context

    img = make_image(rng, (16, 24, 3), np.uint8)
    ref = fpiwarp.warp_image(img, FPI, backend="gl")
    mine = create_context()  # now current in this thread
    try:
        res = fpiwarp.warp_image(texture(mine, img), FPI)
        assert res.ctx is mine
        np.testing.assert_array_equal(read(res, np.uint8), ref)
        alien = mine.texture((24, 16), 3, dtype="f1")
        with pytest.raises(fpiwarp.DeviceMismatchError, match="another GL context"):
            fpiwarp.warp_image(texture(ctx, img), FPI, out=alien)
    finally:
        mine.release()
        ctx.__enter__()  # the shared context current again (creating one made it current)
    np.testing.assert_array_equal(fpiwarp.warp_image(img, FPI, backend="gl"), ref)


def test_antialiased_textures(ctx, rng):
    shrink = fpiwarp.FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 3], [30, -2], [33, 25], [-3, 22]])
    img = make_image(rng, (48, 64, 3), np.uint8)
    res = fpiwarp.warp_image(texture(ctx, img), shrink, antialias=True)
    np.testing.assert_array_equal(read(res, np.uint8), fpiwarp.warp_image(img, shrink, backend="gl", antialias=True))
