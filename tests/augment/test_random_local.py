"""RandomLocal: random local deformations with RandomFPI's call API:
regions inside the image, constraints met (no silent identities), the
halving bounded, keypoints through the forward map that follow their
pixels, boxes against the densely mapped outline, labels, seeds and
batches equal to the loop."""

import numpy as np
import pytest
from test_random_fpi import centroids, dense_bounds, dots

import fpiwarp
from fpiwarp.augment import RandomLocal, box_bounds, random_local


@pytest.mark.parametrize("edges", ["opposite", "adjacent", (0, 2), (3, 0)])
def test_regions_lie_inside_and_the_constraints_are_met(edges):
    h, w = 120, 160
    maps = RandomLocal(max_corner_shift=0.1, edges=edges, seed=3).sample((h, w), 8)
    moved = 0
    for f in maps:
        assert isinstance(f, fpiwarp.LocalDeformation)
        assert np.all(f.src >= -0.5) and np.all(f.src <= [w - 0.5, h - 0.5])
        if not isinstance(edges, str):
            assert sorted(f.edges) == sorted(edges)
        moved += not np.allclose(f.dst, f.src)
    assert moved >= 7  # the draws meet the constraints: at most a rare refusal ends as the identity


def test_refusals_halve_the_jitter_a_bounded_number_of_times(monkeypatch):
    calls = []

    def refuse(src, dst, edges):
        calls.append(np.abs(np.asarray(dst) - np.asarray(src)).max())
        if calls[-1] > 0:
            raise fpiwarp.FoldOverError("the fit folds over")
        return "identity"

    monkeypatch.setattr(random_local, "LocalDeformation", refuse)
    assert RandomLocal(seed=0).sample((64, 64)) == "identity"
    assert len(calls) == random_local.MAX_HALVINGS + 2
    assert all(b == pytest.approx(a / 2) for a, b in zip(calls[:-2], calls[1:-1]))


def test_keypoints_follow_their_pixels():
    img, centres = dots((256, 256))
    aug = RandomLocal(max_corner_shift=0.1, seed=5, backend="numpy")
    errors = []
    for _ in range(3):
        out = aug(image=img, keypoints=centres)
        np.testing.assert_array_equal(out["keypoints"], out["transform"](centres))
        k = out["keypoints"]
        keep = (k.min(axis=1) >= 6) & (k.max(axis=1) <= 256 - 7)
        errors.append(np.hypot(*(centroids(out["image"], k[keep]) - k[keep]).T))
    errors = np.concatenate(errors)
    assert np.median(errors) <= 0.05, np.median(errors)


def test_boxes_are_the_bounds_of_the_densely_mapped_outline():
    rng = np.random.default_rng(1)
    aug = RandomLocal(max_corner_shift=0.15, seed=2)
    for _ in range(3):
        f = aug.sample((200, 300))
        a, b = rng.uniform(0, 300, (2, 4, 2))
        boxes = np.concatenate([np.minimum(a, b), np.maximum(a, b)], axis=1)
        for box, got in zip(boxes, box_bounds(f, boxes)):
            np.testing.assert_allclose(got, dense_bounds(f, box), atol=0.05)  # 256 points per edge vs 20000


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_masks_keep_labels_and_batches_equal_the_loop(backend):
    if backend != "numpy":
        from support.requirements import use_backend

        use_backend(backend)
    rng = np.random.default_rng(4)
    images = rng.integers(0, 256, (3, 40, 50, 3)).astype(np.uint8)
    masks = (rng.integers(0, 4, (3, 40, 50)) * 10**9).astype(np.int64)
    kps = rng.uniform(0, 40, (3, 4, 2))
    boxes = np.array([[[2.0, 3.0, 20.0, 30.0]]] * 3)
    out = RandomLocal(seed=8, backend=backend).batch(images, masks=masks, keypoints=kps, boxes=boxes)
    loop = RandomLocal(seed=8, backend=backend)
    for i in range(3):
        one = loop(image=images[i], mask=masks[i], keypoints=kps[i], boxes=boxes[i])
        np.testing.assert_array_equal(out["images"][i], one["image"])
        np.testing.assert_array_equal(out["masks"][i], one["mask"])
        assert set(np.unique(one["mask"]).tolist()) <= set(np.unique(masks).tolist())
        np.testing.assert_allclose(out["keypoints"][i], one["keypoints"])
        np.testing.assert_allclose(out["boxes"][i], one["boxes"])


@pytest.mark.parametrize("kwargs, match", [
    ({"region_size": (0.0, 0.5)}, "region_size must be"),
    ({"region_jitter": 0.4}, "region_jitter must lie in"),
    ({"edges": "diagonal"}, "edges must be"),
    ({"edges": (1, 1)}, "two different edge indices"),
    ({"max_corner_shift": 0.3}, "max_corner_shift must lie in"),
])
def test_bad_arguments_are_refused(kwargs, match):
    with pytest.raises(fpiwarp.ArgumentError, match=match):
        RandomLocal(**kwargs)
