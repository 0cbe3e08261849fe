"""warp_image conventions on the numpy reference backend."""

import numpy as np
import pytest
from support.kernel_cases import DTYPES, make_image

import fpiwarp
from fpiwarp import FPI, RLinear


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("shape", [(17, 23), (17, 23, 1), (17, 23, 3), (17, 23, 4)])
@pytest.mark.parametrize("order", [0, 1, 3])
def test_identity_returns_the_image(dtype, shape, order):
    img = make_image(shape, dtype)
    out = fpiwarp.warp_image(img, RLinear(1), order=order)
    assert out.dtype == img.dtype and out.shape == img.shape
    assert np.array_equal(out, img)


@pytest.mark.parametrize("order", [0, 1, 3])
def test_identity_fpi_returns_the_image(order):
    quad = [[1, 2], [20, 1], [22, 15], [0, 14]]
    img = make_image((16, 24, 3), np.uint8)
    out = fpiwarp.warp_image(img, FPI(quad, quad), order=order)
    assert np.array_equal(out, img)


@pytest.mark.parametrize(
    "mode, pad_mode", [("edge", "edge"), ("reflect", "reflect"), ("wrap", "wrap"), ("constant", "constant")]
)
@pytest.mark.parametrize("order", [0, 1, 3])
def test_integer_translation_shifts_exactly_with_each_border_mode(mode, pad_mode, order):
    """Output(x, y) = source(x - tx, y - ty), with numpy.pad's meaning of the
    border modes for the pixels that fall outside."""
    img = make_image((9, 11, 2), np.uint16)
    tx, ty = 4, -3
    out = fpiwarp.warp_image(img, RLinear(1, 0, complex(tx, ty)), order=order, mode=mode, cval=7)
    pad = 12
    kwargs = {"constant_values": 7} if pad_mode == "constant" else {}
    padded = np.pad(img, ((pad, pad), (pad, pad), (0, 0)), mode=pad_mode, **kwargs)
    expected = padded[pad - ty : pad - ty + 9, pad - tx : pad - tx + 11]
    assert np.array_equal(out, expected)


def test_x_is_column_and_y_is_row():
    img = np.zeros((5, 8), np.uint8)
    img[1, 2] = 255  # row 1, column 2: the point (x=2, y=1)
    out = fpiwarp.warp_image(img, RLinear(1, 0, 3 + 1j))  # move by x+3, y+1
    assert out[2, 5] == 255 and out.sum() == 255


def test_half_pixel_shift_is_bilinear_average():
    img = np.array([[0, 100, 200, 50]], np.float32).repeat(3, axis=0)
    out = fpiwarp.warp_image(img, RLinear(1, 0, -0.5), mode="edge")
    assert np.allclose(out[1], [50, 150, 125, 50])


def test_uint8_rounding_and_cubic_clipping():
    img = np.zeros((6, 6), np.uint8)
    img[:, 3:] = 255
    out = fpiwarp.warp_image(img, RLinear(1, 0, 0.3), order=3, mode="edge")
    assert out.dtype == np.uint8 and out.max() == 255 and out.min() == 0  # overshoot clipped
    flt = fpiwarp.warp_image(img.astype(np.float32), RLinear(1, 0, 0.3), order=3, mode="edge")
    assert flt.max() > 255 and flt.min() < 0  # float32 keeps the overshoot


def test_output_shape_and_per_channel_cval():
    img = make_image((10, 12, 3), np.uint8)
    out = fpiwarp.warp_image(img, RLinear(1, 0, 100), output_shape=(4, 7), cval=[1, 2, 3])
    assert out.shape == (4, 7, 3)
    assert np.array_equal(out, np.broadcast_to([1, 2, 3], (4, 7, 3)))


def test_pixels_near_the_pole_get_cval_never_nan():
    """An output pixel exactly at w∞ has no finite source position."""
    f = FPI([[0, 0], [10, 0], [10, 10], [0, 10]], [[0, 0], [10, 0], [18, 16], [0, 10]])
    w_inf = f.pole_image
    g = RLinear(1, 0, complex(6, 5) - complex(*w_inf)) @ f  # w∞ on the pixel (6, 5)
    with np.errstate(all="ignore"):
        src = g.inverse([[6.0, 5.0]])
    assert not np.all(np.isfinite(src)) or np.abs(src).max() > 1e9
    img = np.full((12, 12), 1.0, np.float32)
    for mode in ["constant", "edge", "reflect", "wrap"]:
        out = fpiwarp.warp_image(img, g, mode=mode, cval=-1)
        assert np.all(np.isfinite(out))
        assert out[5, 6] == -1


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"image": np.zeros((4, 4), np.float64)}, TypeError, "float32"),
        ({"image": np.zeros((4, 4), np.float16)}, TypeError, "dtype"),
        ({"image": np.zeros((4, 4), np.int32)}, ValueError, "label image: it warps at order 0 only"),
        ({"image": np.zeros((4, 4, 5), np.uint8)}, ValueError, "C in 1..4"),
        ({"image": [[1, 2]]}, TypeError, "numpy array"),
        ({"order": 2}, ValueError, "order"),
        ({"mode": "mirror"}, ValueError, "mode"),
        ({"cval": [1, 2]}, ValueError, "cval"),
        ({"cval": np.nan}, ValueError, "cval"),
        ({"output_shape": (0, 3)}, ValueError, "output_shape"),
        ({"output_shape": (2.5, 3)}, ValueError, "output_shape"),
        ({"output_shape": (2, 3, 4)}, ValueError, "output_shape"),
        ({"image": np.zeros((0, 5), np.uint8)}, ValueError, "empty"),
        ({"transform": "not a map"}, TypeError, "transform"),
        ({"backend": "vulkan"}, ValueError, "unknown backend"),
    ],
)
def test_bad_arguments_are_named(kwargs, error, match):
    args = {"image": np.zeros((4, 4), np.uint8), "transform": RLinear(1)}
    args.update(kwargs)
    image, transform = args.pop("image"), args.pop("transform")
    with pytest.raises(error, match=match):
        fpiwarp.warp_image(image, transform, **args)


def test_input_is_not_modified(sample_fpi):
    img = make_image((48, 64, 3), np.uint8)
    before = img.copy()
    fpiwarp.warp_image(img, sample_fpi, order=3, mode="reflect")
    assert np.array_equal(img, before)


def test_warp_then_inverse_warp_recovers_the_interior(sample_fpi):
    y, x = np.mgrid[0:48, 0:64]
    img = (np.sin(x / 5.0) * np.cos(y / 7.0)).astype(np.float32)  # smooth
    there = fpiwarp.warp_image(img, sample_fpi, order=3)
    back = fpiwarp.warp_image(there, sample_fpi.inverse, order=3)
    interior = (slice(8, 40), slice(8, 56))
    assert np.abs(back[interior] - img[interior]).max() < 0.02
