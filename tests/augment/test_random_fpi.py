"""RandomFPI: the distortion budget, keypoints that follow their pixels
(the dot test), masks whose labels are never invented, boxes against the
densely mapped outline, seeds, and batches equal to the loop."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.array_cases import require_library

import fpiwarp
from fpiwarp.augment import RandomFPI, arc_bounds, box_bounds


@settings(max_examples=40)
@given(k=st.floats(1.0, 3.0), shift=st.floats(0.0, 0.25), seed=st.integers(0, 2**32 - 1),
       h=st.integers(1, 600), w=st.integers(1, 600))
def test_K_never_exceeds_the_budget_and_the_pole_stays_off_the_image(k, shift, seed, h, w):
    maps = RandomFPI(max_distortion=k, max_corner_shift=shift, seed=seed).sample((h, w), 64)
    assert np.all(maps.K <= max(k, 1 + 1e-12))  # K = 1 (conformal) is met to K's rounding, 1e-15
    assert np.all(maps.K >= 1)
    pole = maps.poles
    off = ~np.isfinite(pole) | (np.abs(pole.real - (w - 1) / 2) > w / 2 + 1) | \
        (np.abs(pole.imag - (h - 1) / 2) > h / 2 + 1)
    assert off.all()
    # the corner moves stay within the shift where the budget did not bind
    corners = maps(np.broadcast_to(fpiwarp.augment.image_corners((h, w)), (64, 4, 2)))
    moved = np.abs(corners - fpiwarp.augment.image_corners((h, w))) / [w, h]
    free = maps.K < k * (1 - 1e-6)
    assert np.all(moved[free] <= shift + 1e-9)


def test_the_budget_binds_exactly():
    maps = RandomFPI(max_distortion=1.05, max_corner_shift=0.25, seed=1).sample((200, 300), 500)
    assert maps.K.max() <= 1.05 and maps.K.max() > 1.05 * (1 - 1e-6)  # met, by scaling, not rejection


def dots(shape, step=16, margin=24):
    """An image of 3x3 white dots on black and their centres (x, y)."""
    h, w = shape
    img = np.zeros(shape, np.float32)
    centres = [(x, y) for y in range(margin, h - margin, step) for x in range(margin, w - margin, step)]
    for x, y in centres:
        img[y - 1:y + 2, x - 1:x + 2] = 1.0
    return img, np.array(centres, float)


def centroids(img, predicted, radius=5):
    out = []
    for x, y in predicted:
        x0, y0 = int(round(x)) - radius, int(round(y)) - radius
        win = img[y0:y0 + 2 * radius + 1, x0:x0 + 2 * radius + 1].astype(np.float64)
        yy, xx = np.mgrid[y0:y0 + 2 * radius + 1, x0:x0 + 2 * radius + 1]
        out.append([(win * xx).sum() / win.sum(), (win * yy).sum() / win.sum()])
    return np.array(out)


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_the_dot_test(backend):
    if backend != "numpy":
        from support.requirements import use_backend

        use_backend(backend)
    img, centres = dots((256, 256))
    aug = RandomFPI(max_distortion=1.3, max_corner_shift=0.1, seed=7, backend=backend)
    errors = []
    for _ in range(4):
        out = aug(image=img, keypoints=centres)
        k = out["keypoints"]
        keep = (k.min(axis=1) >= 6) & (k.max(axis=1) <= 256 - 7)  # dots whose window lies on the output
        found = centroids(out["image"], out["keypoints"][keep])
        errors.append(np.hypot(*(found - out["keypoints"][keep]).T))
    errors = np.concatenate(errors)
    assert np.median(errors) <= 0.05 and errors.max() <= 0.3, (np.median(errors), errors.max())


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int32, np.int64, np.bool_])
def test_masks_keep_their_labels(dtype):
    rng = np.random.default_rng(3)
    labels = rng.integers(0, 2 if dtype is np.bool_ else 200, (40, 50)).astype(dtype)
    if np.dtype(dtype).kind == "i":
        labels = labels * 10**6 - 7 if dtype is np.int32 else labels * 10**15 - 7
    aug = RandomFPI(max_corner_shift=0.2, seed=2, mask_cval=0)
    for _ in range(5):
        out = aug(mask=labels)
        assert out["mask"].dtype == labels.dtype
        assert set(np.unique(out["mask"]).tolist()) <= set(np.unique(labels).tolist()) | {0}


def dense_bounds(f, box, n=20000):
    x0, y0, x1, y1 = box
    t = np.linspace(0, 1, n)
    edge = np.concatenate([np.stack([x0 + (x1 - x0) * t, np.full(n, y0)], 1),
                           np.stack([np.full(n, x1), y0 + (y1 - y0) * t], 1),
                           np.stack([x1 - (x1 - x0) * t, np.full(n, y1)], 1),
                           np.stack([np.full(n, x0), y1 - (y1 - y0) * t], 1)])
    p = f(edge)
    return np.array([p[:, 0].min(), p[:, 1].min(), p[:, 0].max(), p[:, 1].max()])


@settings(max_examples=30)
@given(seed=st.integers(0, 2**32 - 1), shift=st.floats(0.05, 0.25))
def test_boxes_are_the_bounds_of_the_mapped_outline(seed, shift):
    rng = np.random.default_rng(seed)
    f = RandomFPI(max_distortion=2.0, max_corner_shift=shift, seed=seed).sample((300, 400))
    a, b = rng.uniform(-50, 450, (2, 6, 2))
    boxes = np.concatenate([np.minimum(a, b), np.maximum(a, b)], axis=1)
    exact = box_bounds(f, boxes)
    for box, got in zip(boxes, exact):
        dense = dense_bounds(f, box)
        scale = np.abs(dense).max() + 1
        # the dense outline lies inside the exact bounds and reaches them to its sampling error
        assert np.all(got[:2] <= dense[:2] + 1e-9 * scale) and np.all(got[2:] >= dense[2:] - 1e-9 * scale)
        np.testing.assert_allclose(got, dense, atol=1e-3)


def test_arc_bounds_of_a_half_circle():
    lo, hi = arc_bounds(np.array([-1 + 0j]), np.array([1j]), np.array([1 + 0j]))
    np.testing.assert_allclose([lo[0].real, lo[0].imag, hi[0].real, hi[0].imag], [-1, 0, 1, 1], atol=1e-15)


def test_boxes_of_other_maps_are_sampled_densely():
    g = fpiwarp.Compound([fpiwarp.FPI([[0, 0], [9, 0], [9, 9], [0, 9]], [[0, 0], [10, 1], [9, 10], [-1, 9]]),
                          fpiwarp.RLinear(1, 0.1, 2)])
    box = np.array([[1.0, 2.0, 7.0, 8.0]])
    np.testing.assert_allclose(box_bounds(g, box)[0], dense_bounds(g, box[0]), atol=1e-3)


def test_keypoints_out_of_frame_and_box_clipping():
    aug = RandomFPI(max_distortion=1.0001, max_corner_shift=0.0, seed=0)  # the identity
    out = aug(shape=(10, 20), keypoints=[[0, 0], [19.5, 9.5], [20, 3], [-0.6, 2]],
              boxes=[[-5, -5, 5, 5], [30, 1, 40, 2]])
    assert out["keypoints_visible"].tolist() == [True, True, False, False]
    np.testing.assert_allclose(out["boxes"][0], [-0.5, -0.5, 5, 5])
    assert out["boxes_visible"].tolist() == [True, False]


def test_seeds_reproduce_and_batches_equal_the_calls():
    a = RandomFPI(seed=11).sample((64, 64), 8)
    b = RandomFPI(seed=11)
    singles = [b.sample((64, 64)) for _ in range(8)]
    np.testing.assert_array_equal(a.dst, np.stack([f.dst for f in singles]))
    assert not np.array_equal(a.dst, RandomFPI(seed=12).sample((64, 64), 8).dst)


def test_probability_gives_identities():
    maps = RandomFPI(p=0.0, seed=0).sample((30, 40), 10)
    np.testing.assert_array_equal(maps.K, 1.0)
    np.testing.assert_allclose(maps.dst, maps.src)


def test_polygons_vertex_wise_with_densification():
    aug = RandomFPI(seed=5, densify=3)
    out = aug(shape=(50, 60), polygons=[[[5, 5], [40, 5], [20, 30]]])
    assert out["polygons"][0].shape == (12, 2)
    np.testing.assert_allclose(out["polygons"][0][0], out["transform"]([[5.0, 5.0]])[0])


@pytest.mark.parametrize("backend", ["numpy", "opencl", "warp", "gl"])
def test_batch_equals_the_loop_on_every_backend(backend):
    from support.requirements import use_backend

    use_backend(backend)
    rng = np.random.default_rng(4)
    images = rng.integers(0, 256, (6, 32, 40, 3)).astype(np.uint8)
    masks = rng.integers(-3, 3, (6, 32, 40)).astype(np.int32)
    kps = rng.uniform(0, 32, (6, 5, 2))
    out = RandomFPI(seed=9, backend=backend).batch(images, masks=masks, keypoints=kps)
    loop = RandomFPI(seed=9, backend=backend)
    for i in range(6):
        one = loop(image=images[i], mask=masks[i], keypoints=kps[i])
        np.testing.assert_array_equal(out["images"][i], one["image"])
        np.testing.assert_array_equal(out["masks"][i], one["mask"])
        np.testing.assert_allclose(out["keypoints"][i], one["keypoints"], atol=1e-9)


def test_torch_batches_equal_the_numpy_batches(warp_backend):
    torch = require_library("torch")
    rng = np.random.default_rng(6)
    images = rng.integers(0, 256, (4, 3, 24, 30)).astype(np.uint8)
    masks = rng.integers(0, 5, (4, 24, 30)).astype(np.int64)
    dev = RandomFPI(seed=3).batch(torch.from_numpy(images), masks=torch.from_numpy(masks), channels="first")
    host = RandomFPI(seed=3, backend="warp").batch(images, masks=masks, channels="first")
    assert isinstance(dev["images"], torch.Tensor) and dev["masks"].dtype == torch.int64
    np.testing.assert_array_equal(dev["images"].numpy(), host["images"])
    np.testing.assert_array_equal(dev["masks"].numpy(), host["masks"])


@pytest.mark.parametrize("kwargs, match", [
    ({"max_distortion": 0.9}, "max_distortion must be"),
    ({"max_corner_shift": 0.3}, "max_corner_shift must lie in"),
    ({"p": 1.5}, "p must lie in"),
])
def test_bad_budgets_are_refused(kwargs, match):
    with pytest.raises(fpiwarp.ArgumentError, match=match):
        RandomFPI(**kwargs)
