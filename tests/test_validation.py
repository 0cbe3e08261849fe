"""One validation module for every entry point (issue 12, defects 3, 5, 6):
huge sizes refused up front with one line naming the size and the limit,
extreme cval never NaN, integral floats accepted everywhere alike, and
backend options checked against what the backend declares."""

import math
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fpiwarp
from fpiwarp import ArgumentError, ArgumentTypeError, FpiwarpError, SizeLimitError
from fpiwarp.backends import REGISTRY, backend_capabilities
from fpiwarp.backends.capabilities import MAX_DEVICE_SIDE, MAX_ELEMENTS
from fpiwarp.block import MAX_STAGES
from fpiwarp.validation import CVAL_LIMIT, check_cval, check_order, check_output_shape, check_sizes

H, W = 24, 32
SRC = [[0, 0], [31, 0], [31, 23], [0, 23]]
DST = [[2, 1], [29, -2], [33, 24], [-1, 21]]
BACKENDS = sorted(REGISTRY)


@pytest.fixture
def fpi():
    return fpiwarp.FPI(SRC, DST)


@pytest.fixture
def image(rng):
    return rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)


# -- defect 3: huge outputs -------------------------------------------------


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("shape", [(2**31, 1), (10**7, 10**7), (100000, 100000), (1, 2**31)])
def test_huge_outputs_are_refused_at_once_with_the_size_and_the_limit(fpi, image, backend, shape):
    t0 = time.perf_counter()
    with pytest.raises(SizeLimitError) as info:
        fpiwarp.warp_image(image, fpi, shape, backend=backend)
    assert time.perf_counter() - t0 < 1.0
    message = str(info.value)
    assert "\n" not in message and f"{shape[0]}x{shape[1]}" in message and str(MAX_ELEMENTS) in message
    assert isinstance(info.value, ValueError) and isinstance(info.value, FpiwarpError)


@settings(max_examples=60, deadline=None)
@given(
    rows=st.integers(1, 10**12),
    cols=st.integers(1, 10**12),
    channels=st.integers(1, 4),
    backend=st.sampled_from(BACKENDS),
)
def test_sizes_are_refused_exactly_beyond_the_declared_limits(rows, cols, channels, backend):
    caps = backend_capabilities(backend)
    over_elements = rows * cols * channels > caps.max_elements
    over_side = caps.max_side is not None and max(rows, cols) > caps.max_side
    if over_elements or over_side:
        with pytest.raises(SizeLimitError, match=f"{rows}x{cols}"):
            check_sizes((1, 1, channels), (rows, cols), np.uint8, caps, backend)
    else:
        check_sizes((1, 1, channels), (rows, cols), np.uint8, caps, backend)


def test_device_backends_declare_the_float32_side_limit():
    assert backend_capabilities("numpy").max_side is None
    for name in ("opencl", "warp", "gl"):
        caps = backend_capabilities(name)
        assert caps.max_side == MAX_DEVICE_SIDE == 2**24
        with pytest.raises(SizeLimitError, match=f"{name} backend's limit of 16777216 px per side"):
            check_sizes((1, 1, 1), (MAX_DEVICE_SIDE + 1, 1), np.uint8, caps, name)


def test_an_output_larger_than_memory_is_refused(monkeypatch):
    monkeypatch.setattr("fpiwarp.validation.physical_memory", lambda: 2**30)
    caps = backend_capabilities("numpy")
    with pytest.raises(SizeLimitError, match="needs 1.1 GiB, more than this machine's 1.0 GiB"):
        check_sizes((1, 1, 3), (20000, 20000), np.uint8, caps, "numpy")
    check_sizes((1, 1, 3), (1000, 1000), np.uint8, caps, "numpy")


def test_source_positions_checks_sizes_too(fpi):
    with pytest.raises(SizeLimitError):
        fpiwarp.source_positions(fpi, (10**7, 10**7))


@pytest.mark.parametrize("backend", ["opencl", "warp", "gl"])
def test_maps_beyond_the_kernels_stages_are_refused_on_device_backends(backend):
    steps = [fpiwarp.FPI(SRC, DST) if k % 2 == 0 else fpiwarp.FPI(DST, SRC) for k in range(MAX_STAGES + 1)]
    long_map = fpiwarp.Compound(steps)
    assert len(long_map.stages()) > MAX_STAGES
    image = np.zeros((H, W), np.uint8)
    with pytest.raises(SizeLimitError, match=f"{backend} backend's limit of {MAX_STAGES}"):
        fpiwarp.warp_image(image, long_map, backend=backend)
    assert fpiwarp.warp_image(image, long_map).shape == (H, W)  # numpy evaluates any number of stages


# -- defect 5: extreme cval ---------------------------------------------------


@pytest.mark.parametrize("cval", [3.5e38, -3.5e38, 1e300, float(np.finfo(np.float32).max)])
def test_cval_beyond_the_float32_limit_is_refused_for_float32_images(fpi, cval):
    image = np.zeros((H, W), np.float32)
    with pytest.raises(ArgumentError, match="cval must lie within"):
        fpiwarp.warp_image(image, fpi, cval=cval)
    with pytest.raises(ArgumentError, match="cval"):
        fpiwarp.warp_image(image, fpi, cval=[cval])


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_cval_for_integer_images_is_clamped_to_the_dtype(dtype):
    top = float(np.iinfo(dtype).max)
    np.testing.assert_array_equal(check_cval([3.5e38, -1e300, 7], 3, dtype), [top, 0.0, 7.0])


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    cval=st.one_of(st.floats(-CVAL_LIMIT, CVAL_LIMIT), st.sampled_from([CVAL_LIMIT, -CVAL_LIMIT, 3.5e38, 1e300])),
    dtype=st.sampled_from([np.uint8, np.uint16, np.float32]),
    order=st.sampled_from([0, 1, 3]),
)
def test_extreme_cval_never_gives_nan_and_integers_match_numpy(any_backend, cval, dtype, order):
    rng = np.random.default_rng(5)
    scale = 1.0 if dtype == np.float32 else float(np.iinfo(dtype).max)
    image = (rng.random((H, W, 3)) * scale).astype(dtype)
    fpi = fpiwarp.FPI(SRC, DST)
    if dtype == np.float32 and abs(cval) > CVAL_LIMIT:
        with pytest.raises(ArgumentError):
            fpiwarp.warp_image(image, fpi, order=order, cval=cval, backend=any_backend)
        return
    out = fpiwarp.warp_image(image, fpi, order=order, cval=cval, backend=any_backend)
    assert not np.isnan(out.astype(np.float64)).any()
    if dtype != np.float32:
        ref = fpiwarp.warp_image(image, fpi, order=order, cval=cval)
        level = 1 if dtype == np.uint8 else 257
        assert np.mean(np.abs(out.astype(np.int64) - ref) > level) <= 0.002


# -- defect 6: integral floats ------------------------------------------------


@pytest.mark.parametrize("order", [0.0, 1.0, 3.0, np.float64(0), np.float32(3), np.int64(1), np.uint8(3)])
def test_integral_orders_work_like_ints_on_every_backend(image, fpi, any_backend, order):
    got = fpiwarp.warp_image(image, fpi, order=order, backend=any_backend)
    np.testing.assert_array_equal(got, fpiwarp.warp_image(image, fpi, order=int(order), backend=any_backend))


@pytest.mark.parametrize(
    "order, error",
    [(1.5, ArgumentError), (2.0, ArgumentError), (math.inf, ArgumentError), (math.nan, ArgumentError),
     (True, ArgumentError), ("1", ArgumentError), (None, ArgumentError), ([1], ArgumentError)],
)
def test_other_orders_are_refused_everywhere(image, fpi, order, error):
    for backend in BACKENDS:
        with pytest.raises(error, match="order must be one of"):
            fpiwarp.warp_image(image, fpi, order=order, backend=backend)
    with pytest.raises(error):
        fpiwarp.warp_images([image], fpi, order=order)
    with pytest.raises(error):
        check_order(order)


@pytest.mark.parametrize("shape", [(math.inf, 5), (5, -math.inf), (math.nan, 5), (2.5, 3), (True, 4), ("3", 4), (3,)])
def test_bad_output_shapes_are_value_errors_not_overflow(image, fpi, shape):
    with pytest.raises(ArgumentError, match="output_shape"):
        fpiwarp.warp_image(image, fpi, shape)


@settings(max_examples=30, deadline=None)
@given(
    rows=st.integers(1, 40), cols=st.integers(1, 40), kind=st.sampled_from([float, np.float64, np.float32, np.int32])
)
def test_integral_output_shapes_equal_their_ints(rows, cols, kind):
    assert check_output_shape((kind(rows), kind(cols)), None) == (rows, cols)
    assert all(type(v) is int for v in check_output_shape((kind(rows), kind(cols)), None))


def test_integral_float_shapes_warp_like_ints(image, fpi, any_backend):
    got = fpiwarp.warp_image(image, fpi, (20.0, np.float64(17)), backend=any_backend)
    np.testing.assert_array_equal(got, fpiwarp.warp_image(image, fpi, (20, 17), backend=any_backend))


# -- backend options ------------------------------------------------------------


def test_gl_hardware_filter_through_warp_image(image, fpi, gl_backend):
    got = fpiwarp.warp_image(image, fpi, backend="gl", backend_options={"hardware_filter": True})
    ref = fpiwarp.warp_image(image, fpi, backend="gl")
    assert got.shape == ref.shape and np.mean(np.abs(got.astype(int) - ref) <= 2) > 0.99
    same = fpiwarp.warp_image(image, fpi, backend="gl", backend_options={"hardware_filter": False})
    np.testing.assert_array_equal(same, ref)


@pytest.mark.parametrize(
    "backend, options, error, phrase",
    [
        ("numpy", {"hardware_filter": True}, ArgumentError, "numpy backend has no option 'hardware_filter'"),
        ("gl", {"hardware_filer": True}, ArgumentError, "its options: ['hardware_filter']"),
        ("gl", {"hardware_filter": "yes"}, ArgumentTypeError, "must be a bool"),
        ("gl", {"hardware_filter": 1}, ArgumentTypeError, "must be a bool"),
        ("gl", ["hardware_filter"], ArgumentTypeError, "must be a dict"),
    ],
)
def test_backend_options_are_checked_against_the_declared_ones(image, fpi, backend, options, error, phrase):
    with pytest.raises(error) as info:
        fpiwarp.warp_image(image, fpi, backend=backend, backend_options=options)
    assert phrase in str(info.value)


@pytest.mark.parametrize("order, mode", [(3, "constant"), (1, "reflect")])
def test_an_option_says_where_it_applies(image, fpi, order, mode):
    with pytest.raises(ArgumentError, match="hardware_filter"):
        fpiwarp.warp_image(image, fpi, order=order, mode=mode, backend="gl", backend_options={"hardware_filter": True})


def test_capabilities_are_declared_for_every_backend():
    for name in BACKENDS:
        caps = fpiwarp.backend_capabilities(name)
        assert caps.max_elements == MAX_ELEMENTS and set(caps.orders) == {0, 1, 3}
    assert fpiwarp.backend_capabilities("numpy").batches
    assert fpiwarp.backend_capabilities("numpy").thread_safe
    assert not fpiwarp.backend_capabilities("gl").thread_safe
    assert [opt.name for opt in fpiwarp.backend_capabilities("gl").options] == ["hardware_filter"]
    with pytest.raises(ArgumentError, match="unknown backend 'vulkan'"):
        fpiwarp.backend_capabilities("vulkan")


@pytest.mark.parametrize("backend", ["opencl", "warp", "gl"])
def test_map_points_refuses_maps_beyond_the_kernels_stages(backend):
    steps = [fpiwarp.FPI(SRC, DST) if k % 2 == 0 else fpiwarp.FPI(DST, SRC) for k in range(MAX_STAGES + 1)]
    with pytest.raises(SizeLimitError, match=f"above the {backend} backend's limit"):
        fpiwarp.map_points(fpiwarp.Compound(steps), [[1.0, 2.0]], backend=backend)


def test_opencl_point_limit_is_checked_before_the_backend():
    from fpiwarp.validation import check_point_count

    caps = backend_capabilities("opencl")
    points = np.broadcast_to(np.zeros(2), (caps.max_points + 1, 2))  # no memory behind it
    with pytest.raises(SizeLimitError, match=f"{caps.max_points + 1} points is above the opencl backend's limit"):
        check_point_count(points, caps, "opencl")


@pytest.mark.parametrize("limit, expected", [("max\n", 64 * 2**30), ("1073741824\n", 2**30), (None, 64 * 2**30)])
def test_memory_is_the_machines_or_its_containers_limit(tmp_path, monkeypatch, limit, expected):
    from fpiwarp import validation

    path = tmp_path / "memory.max"
    if limit is not None:
        path.write_text(limit)
    monkeypatch.setattr(validation, "CGROUP_MEMORY_MAX", str(path))
    pages = {"SC_PAGE_SIZE": 4096, "SC_PHYS_PAGES": 16 * 2**20}
    monkeypatch.setattr(validation.os, "sysconf", lambda name: pages[name])
    assert validation.physical_memory() == expected
