"""fpiwarp.augment.torchvision: a v2 transform whose image, mask, boxes and
keypoints agree with RandomFPI's for the same map, in v2.Compose, pickled,
and in DataLoader workers (distinct, reproducible maps)."""

import pickle

import numpy as np
import pytest
from support.array_cases import require_library

import fpiwarp
from fpiwarp.augment import RandomFPI

try:  # at collection, before any test makes a GL context: a process that loads triton (torchvision imports it)
    import torchvision  # noqa: F401  after Mesa's llvmpipe crashes (two LLVMs), whichever suite order runs
except ImportError:
    pass


@pytest.fixture(autouse=True)
def _torchvision():
    require_library("torch")
    require_library("torchvision")


def sample(h=48, w=64, seed=0):
    import torch
    from torchvision import tv_tensors

    rng = np.random.default_rng(seed)
    return {
        "image": tv_tensors.Image(torch.from_numpy(rng.integers(0, 256, (3, h, w)).astype(np.uint8))),
        "mask": tv_tensors.Mask(torch.from_numpy(rng.integers(-2, 6, (h, w)).astype(np.int64) * 10**12)),
        "boxes": tv_tensors.BoundingBoxes(torch.tensor([[2.0, 3.0, 30.0, 40.0], [20.0, 5.0, 63.0, 47.0]]),
                                          format="XYXY", canvas_size=(h, w)),
        "keypoints": tv_tensors.KeyPoints(torch.tensor([[5.0, 6.0], [40.25, 20.5], [63.0, 47.0]]),
                                          canvas_size=(h, w)),
        "label": 7,
    }


def test_compose_agrees_with_random_fpi_for_the_same_map():
    from torchvision.transforms import v2

    from fpiwarp.augment.torchvision import RandomFPI as TorchvisionFPI

    pipeline = v2.Compose([TorchvisionFPI(max_distortion=1.4, max_corner_shift=0.2, seed=21, backend="numpy")])
    core = RandomFPI(max_distortion=1.4, max_corner_shift=0.2, seed=21, backend="numpy")
    for _ in range(3):
        s = sample()
        out = pipeline(s)
        ref = core(image=s["image"].permute(1, 2, 0).numpy(), mask=s["mask"].numpy(),
                   keypoints=s["keypoints"].numpy(), boxes=s["boxes"].numpy() - 0.5)
        assert type(out["image"]).__name__ == "Image" and type(out["mask"]).__name__ == "Mask"
        assert out["label"] == 7 and out["mask"].dtype == s["mask"].dtype
        np.testing.assert_array_equal(out["image"].permute(1, 2, 0).numpy(), ref["image"])
        np.testing.assert_array_equal(out["mask"].numpy(), ref["mask"])
        np.testing.assert_allclose(out["keypoints"].numpy(), ref["keypoints"], atol=1e-4)
        np.testing.assert_allclose(out["boxes"].numpy(), ref["boxes"] + 0.5, atol=1e-4)  # pixel edges at integers
        assert out["boxes"].canvas_size == (48, 64)


@pytest.mark.parametrize("fmt", ["XYWH", "CXCYWH"])
def test_other_box_formats_go_through_xyxy(fmt):
    import torch
    from torchvision import tv_tensors
    from torchvision.transforms.v2 import functional as F

    from fpiwarp.augment.torchvision import RandomFPI as TorchvisionFPI

    s = sample()
    other = F.convert_bounding_box_format(s["boxes"], new_format=fmt)
    a = TorchvisionFPI(max_corner_shift=0.2, seed=4)(s["image"], other)[1]
    b = TorchvisionFPI(max_corner_shift=0.2, seed=4)(s["image"], s["boxes"])[1]
    assert a.format.name == fmt
    torch.testing.assert_close(F.convert_bounding_box_format(a, new_format="XYXY").as_subclass(torch.Tensor),
                               b.as_subclass(torch.Tensor), atol=1e-4, rtol=0)
    with pytest.raises(fpiwarp.ArgumentError, match="axis-aligned"):
        TorchvisionFPI(seed=0)(s["image"], tv_tensors.BoundingBoxes(torch.zeros(1, 5), format="XYWHR",
                                                                    canvas_size=(48, 64)))


def test_batched_and_many_channel_images_share_one_map():
    import torch

    from fpiwarp.augment.torchvision import RandomFPI as TorchvisionFPI

    x = torch.rand(2, 6, 24, 32)
    out = TorchvisionFPI(max_corner_shift=0.2, seed=8, backend="numpy")(x)
    assert isinstance(out, torch.Tensor) and out.shape == x.shape and out.dtype == x.dtype
    f = RandomFPI(max_corner_shift=0.2, seed=8).sample((24, 32))
    ref = fpiwarp.warp_image(x[1, 4:].permute(1, 2, 0).contiguous().numpy(), f, backend="numpy")
    np.testing.assert_allclose(out[1, 4:].permute(1, 2, 0).numpy(), ref, atol=1e-6)


def test_probability_zero_returns_the_inputs():
    from fpiwarp.augment.torchvision import RandomFPI as TorchvisionFPI

    s = sample()
    out = TorchvisionFPI(p=0.0, seed=1)(s)
    assert out["image"] is s["image"] and out["boxes"] is s["boxes"]


def test_it_pickles_and_keeps_its_sequence():
    from fpiwarp.augment.torchvision import RandomFPI as TorchvisionFPI

    t = TorchvisionFPI(seed=5)
    copy = pickle.loads(pickle.dumps(t))
    s = sample()
    np.testing.assert_array_equal(t(s)["image"].numpy(), copy(s)["image"].numpy())


class Samples:
    """A dataset of the same sample, to see the maps the workers draw."""

    def __init__(self, transform):
        self.transform = transform

    def __len__(self):
        return 8

    def __getitem__(self, i):
        return self.transform(sample()["keypoints"]).as_subclass(__import__("torch").Tensor)


@pytest.mark.parametrize("seed", [None, 13])
def test_dataloader_workers_draw_distinct_reproducible_maps(seed):
    import torch

    from fpiwarp.augment.torchvision import RandomFPI as TorchvisionFPI

    def run():
        torch.manual_seed(0)
        loader = torch.utils.data.DataLoader(Samples(TorchvisionFPI(seed=seed)), batch_size=None, num_workers=2)
        return torch.stack(list(loader)).numpy()

    a, b = run(), run()
    np.testing.assert_array_equal(a, b)  # reproducible under torch.manual_seed
    flat = a.reshape(len(a), -1)
    assert len(np.unique(flat, axis=0)) == len(a)  # no two samples (of either worker) share a map


def test_the_docstring_examples_run():
    import doctest

    import fpiwarp.augment.torchvision as module

    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


def test_the_device_path_equals_the_host_path(warp_backend):
    """The path of tensors off the CPU (warped where they live through
    fpiwarp.arrays), run here on CPU tensors through Warp's DLPack path."""
    import torch

    from fpiwarp.augment.torchvision import RandomFPI as TorchvisionFPI

    t = TorchvisionFPI(max_corner_shift=0.2, seed=6, backend="warp")
    f = RandomFPI(max_corner_shift=0.2, seed=6).sample((24, 32))
    rng = np.random.default_rng(1)
    images = torch.from_numpy(rng.integers(0, 256, (2, 5, 24, 32)).astype(np.uint8))
    masks = torch.from_numpy(rng.integers(-4, 4, (3, 24, 32)).astype(np.int64))
    for x, mask in ((images, False), (masks, True)):
        device = t._device_planes(x, f, mask)
        host = t._planes(x, f, mask)
        assert device.shape == x.shape and device.dtype == x.dtype
        np.testing.assert_array_equal(device.numpy(), host.numpy())
