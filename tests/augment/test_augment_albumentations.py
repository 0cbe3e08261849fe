"""fpiwarp.augment.albumentations: a DualTransform whose image, mask,
bboxes and keypoints agree with RandomFPI's for the same map, in A.Compose
with bbox_params and keypoint_params, seeded and pickled."""

import pickle

import numpy as np
import pytest
from support.array_cases import require_library

from fpiwarp.augment import RandomFPI, box_bounds


@pytest.fixture(autouse=True)
def _albumentations():
    require_library("albumentations")


def data(h=60, w=80, seed=0):
    rng = np.random.default_rng(seed)
    return {"image": rng.integers(0, 256, (h, w, 3)).astype(np.uint8),
            "mask": (rng.integers(-3, 4, (h, w)) * 10**6).astype(np.int32),
            "bboxes": np.array([[2.0, 3.0, 30.0, 40.0], [20.0, 5.0, 79.0, 59.0]]), "labels": [1, 2],
            "keypoints": np.array([[5.0, 6.0], [40.25, 20.5], [70.0, 50.0]])}


def pipeline(**kwargs):
    import albumentations as A

    from fpiwarp.augment.albumentations import RandomFPI as AlbumentationsFPI

    return A.Compose([AlbumentationsFPI(max_distortion=1.4, max_corner_shift=0.2, backend="numpy", **kwargs)],
                     seed=3, bbox_params=A.BboxParams(format="pascal_voc", label_fields=["labels"], clip=True),
                     keypoint_params=A.KeypointParams(format="xy", remove_invisible=False))


def test_compose_agrees_with_random_fpi_for_the_same_map():
    pipe = pipeline()
    core = RandomFPI(backend="numpy")
    for i in range(3):
        d = data(seed=i)
        out = pipe(**d)
        f = pipe.transforms[0].params["transform"]
        assert f.K <= 1.4
        np.testing.assert_array_equal(out["image"], core.apply_to_image(f, d["image"]))
        np.testing.assert_array_equal(out["mask"], core.apply_to_mask(f, d["mask"]))
        assert out["mask"].dtype == np.int32
        np.testing.assert_allclose(out["keypoints"], f(d["keypoints"]), atol=1e-4)
        # pascal_voc boxes have pixel edges at integers: fpiwarp's frame is half a pixel off; clipped to the image
        exact = box_bounds(f, d["bboxes"] - 0.5) + 0.5
        exact = np.clip(exact, 0, [80, 60, 80, 60])
        np.testing.assert_allclose(np.array(out["bboxes"]), exact, atol=1e-3)
        assert list(out["labels"]) == [1, 2]


def test_the_seed_of_compose_reproduces_and_it_pickles():
    a, b = pipeline(), pipeline()
    d = data()
    np.testing.assert_array_equal(a(**d)["image"], b(**d)["image"])
    copy = pickle.loads(pickle.dumps(a))
    np.testing.assert_array_equal(a(**d)["image"], copy(**d)["image"])
    assert not np.array_equal(a(**d)["image"], a(**d)["image"])  # a new map per call


def test_keypoint_angles_and_scales_follow_the_jacobian():
    import albumentations as A

    from fpiwarp.augment.albumentations import RandomFPI as AlbumentationsFPI

    pipe = A.Compose([AlbumentationsFPI(max_corner_shift=0.2)], seed=1,
                     keypoint_params=A.KeypointParams(format="xyas", angle_in_degrees=False, remove_invisible=False))
    kp = np.array([[30.0, 20.0, 0.5, 2.0]])
    out = np.array(pipe(image=np.zeros((60, 80), np.uint8), keypoints=kp)["keypoints"])
    f = pipe.transforms[0].params["transform"]
    eps = 1e-4  # a short step along the keypoint's direction lands along its new direction, scaled
    step = f(kp[:, :2] + eps * np.array([[np.cos(0.5), np.sin(0.5)]])) - f(kp[:, :2])
    np.testing.assert_allclose(out[0, 2], np.mod(np.arctan2(step[0, 1], step[0, 0]), 2 * np.pi), atol=1e-3)
    np.testing.assert_allclose(out[0, 3], 2.0 * np.hypot(*step[0]) / eps, rtol=1e-3)


def test_masks_of_many_planes_and_images_of_many_channels():
    import albumentations as A

    from fpiwarp.augment.albumentations import RandomFPI as AlbumentationsFPI

    rng = np.random.default_rng(2)
    img = rng.random((30, 40, 6), dtype=np.float32)
    masks = rng.integers(0, 2, (3, 30, 40)).astype(bool)
    pipe = A.Compose([AlbumentationsFPI(max_corner_shift=0.2, backend="numpy")], seed=0)
    out = pipe(image=img, masks=masks)
    f = pipe.transforms[0].params["transform"]
    core = RandomFPI(backend="numpy")
    np.testing.assert_allclose(out["image"][..., 4:], core.apply_to_image(f, img[..., 4:]), atol=1e-6)
    assert out["masks"].dtype == bool
    np.testing.assert_array_equal(out["masks"][2], core.apply_to_mask(f, masks[2]))


def test_the_docstring_examples_run():
    import doctest

    import fpiwarp.augment.albumentations as module

    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
