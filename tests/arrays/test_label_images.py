"""Label images (bool and integer dtypes other than uint8/uint16) warp at
order 0 on every backend and in warp_batch: dtype kept, values copied
exactly (large and negative labels too), cval honoured exactly, nothing
averaged (fpiwarp/arrays/labels.py)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.array_cases import require_library

import fpiwarp
from fpiwarp.arrays.labels import label_dtype
from fpiwarp.warping import Warper

F = fpiwarp.FPI([[0, 0], [20, 0], [20, 16], [0, 16]], [[1.5, -1], [19, 1.2], [21, 15], [-0.7, 17.3]])
LABEL_DTYPES = (np.int8, np.int16, np.int32, np.int64, np.uint32, np.uint64, np.bool_)


def labels_of(rng, shape, dtype):
    """Random labels over the dtype's whole range (extremes included)."""
    dtype = np.dtype(dtype)
    if dtype.kind == "b":
        return rng.random(shape) < 0.5
    info = np.iinfo(dtype)
    values = rng.integers(info.min, info.max, size=shape, endpoint=True, dtype=dtype)
    values.flat[:2] = info.min, info.max
    return values


def extreme_cval(dtype):
    return True if np.dtype(dtype).kind == "b" else np.iinfo(dtype).min


@pytest.mark.parametrize("dtype", LABEL_DTYPES)
@pytest.mark.parametrize("mode", ["constant", "edge", "reflect", "wrap"])
def test_labels_equal_the_order_0_warp_of_their_index(any_backend, dtype, mode):
    # the reference: warp the pixel index (float32 exact up to 2**24) at order 0 and gather
    rng = np.random.default_rng(1)
    labels = labels_of(rng, (17, 21), dtype)
    cval = extreme_cval(dtype)
    out = fpiwarp.warp_image(labels, F, (19, 23), order=0, mode=mode, cval=cval, backend=any_backend)
    index = np.arange(labels.size, dtype=np.float32).reshape(labels.shape) + 1  # 0 marks cval
    where = fpiwarp.warp_image(index, F, (19, 23), order=0, mode=mode, cval=0, backend="numpy")
    expect = np.where(where > 0, labels.reshape(-1)[np.maximum(where.astype(np.int64) - 1, 0)], cval)
    assert out.dtype == labels.dtype and out.shape == (19, 23)
    np.testing.assert_array_equal(out, expect)


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.bool_])
def test_label_batches_equal_the_loop(any_backend, dtype):
    rng = np.random.default_rng(2)
    stack = labels_of(rng, (3, 15, 18), dtype)
    maps = [F, F.inverse, fpiwarp.RLinear(1, 0, 0.4 + 0.3j)]
    out = fpiwarp.warp_batch(stack, maps, order=0, cval=extreme_cval(dtype), backend=any_backend)
    loop = [fpiwarp.warp_image(s, m, order=0, cval=extreme_cval(dtype), backend="numpy") for s, m in zip(stack, maps)]
    assert out.dtype == stack.dtype
    np.testing.assert_array_equal(out, np.stack(loop))


def test_two_int32_channels_and_channels_first():
    rng = np.random.default_rng(3)
    labels = labels_of(rng, (14, 12, 2), np.int32)
    last = fpiwarp.warp_image(labels, F, order=0, cval=[-5, 7])
    first = fpiwarp.warp_image(np.ascontiguousarray(labels.transpose(2, 0, 1)), F, order=0, cval=[-5, 7],
                               channels="first")
    np.testing.assert_array_equal(first, last.transpose(2, 0, 1))
    assert set(np.unique(last[..., 0])) <= set(np.unique(labels[..., 0])) | {-5}
    assert set(np.unique(last[..., 1])) <= set(np.unique(labels[..., 1])) | {7}


def test_warper_and_out_take_labels():
    labels = labels_of(np.random.default_rng(4), (10, 9), np.int64)
    expect = fpiwarp.warp_image(labels, F, order=0, cval=-1)
    np.testing.assert_array_equal(Warper(F, order=0, cval=-1)(labels), expect)
    out = np.empty_like(labels)
    assert fpiwarp.warp_image(labels, F, order=0, cval=-1, out=out) is out
    np.testing.assert_array_equal(out, expect)


@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), dtype=st.sampled_from(LABEL_DTYPES), shift=st.floats(-3, 3),
       cval=st.integers(-(2**31), 2**31 - 1))
def test_labels_are_never_invented(seed, dtype, shift, cval):
    rng = np.random.default_rng(seed)
    labels = labels_of(rng, (9, 11), dtype)
    if np.dtype(dtype).kind == "b":
        cval = bool(cval % 2)
    else:
        info = np.iinfo(dtype)
        cval = int(np.clip(cval, info.min, info.max))
    f = fpiwarp.FPI([[0, 0], [10, 0], [10, 8], [0, 8]], [[shift, 0], [10, shift], [10 - shift, 8], [0, 8 + shift]])
    out = fpiwarp.warp_image(labels, f, order=0, cval=cval)
    assert out.dtype == labels.dtype
    assert set(np.unique(out).tolist()) <= set(np.unique(labels).tolist()) | {cval}


@pytest.mark.parametrize("kwargs, message", [
    ({"order": 1}, "order 0 only"),
    ({"order": 3}, "order 0 only"),
    ({"order": 0, "antialias": True}, "antialias=True would average"),
    ({"order": 0, "cval": 0.5}, "must be an integer"),
    ({"order": 0, "cval": 2**40}, "outside the range"),
    ({"order": 0, "cval": [1, 2]}, "one value of its dtype"),
])
def test_label_refusals_are_one_line(kwargs, message):
    labels = np.zeros((4, 5), np.int32)
    with pytest.raises(fpiwarp.ArgumentError, match=message) as err:
        fpiwarp.warp_image(labels, F, **kwargs)
    assert "\n" not in str(err.value)


def test_too_many_label_channels_are_refused():
    with pytest.raises(fpiwarp.ArgumentError, match="at most 1 channel"):
        fpiwarp.warp_image(np.zeros((4, 5, 2), np.int64), F, order=0)
    with pytest.raises(fpiwarp.ArgumentError, match="bool label image must be False or True"):
        fpiwarp.warp_image(np.zeros((4, 5), bool), F, order=0, cval=3)


def test_uint8_uint16_float32_stay_images():
    for dtype in (np.uint8, np.uint16, np.float32):
        assert label_dtype(np.zeros(1, dtype)) is None
    assert label_dtype(np.zeros(1, np.int32)) == np.int32


def test_torch_label_tensors(warp_backend):
    torch = require_library("torch")
    labels = labels_of(np.random.default_rng(5), (2, 13, 11), np.int64)
    expect = fpiwarp.warp_batch(labels, [F, F.inverse], order=0, cval=-3)
    out = fpiwarp.warp_batch(torch.from_numpy(labels), [F, F.inverse], order=0, cval=-3)
    assert isinstance(out, torch.Tensor) and out.dtype == torch.int64
    np.testing.assert_array_equal(out.numpy(), expect)
    mask = torch.from_numpy(labels[0] > 0)
    one = fpiwarp.warp_image(mask, F, order=0)
    assert one.dtype == torch.bool
    np.testing.assert_array_equal(one.numpy(), fpiwarp.warp_image(labels[0] > 0, F, order=0))
    first = fpiwarp.warp_image(torch.from_numpy(labels[0][None].astype(np.int32)), F, order=0, channels="first")
    np.testing.assert_array_equal(first.numpy()[0], fpiwarp.warp_image(labels[0].astype(np.int32), F, order=0))


def test_pyopencl_label_arrays(opencl_backend):
    require_library("pyopencl")
    queue = fpiwarp.arrays.opencl_queue()
    import pyopencl.array as cla

    labels = labels_of(np.random.default_rng(6), (12, 10), np.int32)
    out = fpiwarp.warp_image(cla.to_device(queue, labels), F, order=0, cval=9)
    assert out.dtype == np.int32
    np.testing.assert_array_equal(out.get(), fpiwarp.warp_image(labels, F, order=0, cval=9))
    stack = np.stack([labels, -labels])
    batch = fpiwarp.warp_batch(cla.to_device(queue, stack), [F, F.inverse], order=0)
    np.testing.assert_array_equal(batch.get(), fpiwarp.warp_batch(stack, [F, F.inverse], order=0))
