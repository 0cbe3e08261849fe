"""RandomFPI as a ``torchvision.transforms.v2`` transform.

``fpiwarp.augment.torchvision.RandomFPI(...)`` draws one map per call and
applies it to every input of the sample: ``tv_tensors.Image`` and
``Video`` (and a plain tensor or PIL image, as torchvision treats them),
``Mask`` at order 0 (labels and dtype kept), ``BoundingBoxes`` (any
axis-aligned format, converted through XYXY; their new bounds are the
exact bounds of the mapped outline, clipped to ``canvas_size`` with
``clip_boxes``) and ``KeyPoints`` (the exact forward map). Other inputs
(labels, strings) pass through. It works in ``v2.Compose`` and in
DataLoader workers (it pickles).

Conventions: torchvision's keypoints have pixel centres at integers, as
fpiwarp's; its boxes have pixel edges at integers (a full-image XYXY box
is (0, 0, W, H)), so boxes are shifted by half a pixel to fpiwarp's frame
and back.

Random numbers: with ``seed=None`` the draws come from torch's global
generator (``torch.rand``), as torchvision's own transforms do: a
DataLoader seeds each worker differently every epoch, and
``torch.manual_seed`` in the main process reproduces a run. With an
integer ``seed`` they come from a private numpy generator, the same
sequence as ``fpiwarp.augment.RandomFPI(seed=seed)``; in a DataLoader
worker it restarts from (``seed``, the worker's torch seed), so workers
differ from each other and from epoch to epoch, reproducibly under
``torch.manual_seed``. Needs ``pip install 'fpiwarp[torchvision]'``.
"""

try:
    import torch
    from torchvision import tv_tensors
    from torchvision.transforms import v2
    from torchvision.transforms.v2 import functional as F
except ImportError as exc:  # pragma: no cover - exercised only without torchvision
    from fpiwarp.errors import MissingDependencyError

    raise MissingDependencyError(f"fpiwarp.augment.torchvision needs torchvision: pip install "
                                 f"'fpiwarp[torchvision]' ({exc})") from None

import numpy as np
import PIL.Image

from ..errors import ArgumentError, ArgumentTypeError
from . import random_fpi
from .sampling import DRAWS

__all__ = ["RandomFPI"]

#: tv_tensors.KeyPoints (torchvision 0.23 and later; a type nothing is an instance of before).
_KEYPOINTS = getattr(tv_tensors, "KeyPoints", type("NoKeyPoints", (), {}))
#: torch dtypes warped as they are; other floating types go through float32.
_IMAGE_DTYPES = (torch.uint8, torch.uint16, torch.float32)


class RandomFPI(v2.Transform):
    """A random four-point warp within a distortion budget, for
    ``torchvision.transforms.v2`` pipelines.

    The parameters are those of :class:`fpiwarp.augment.RandomFPI`
    (``max_distortion``, ``max_corner_shift``, ``p``, ``seed``,
    ``backend``, ``antialias``, ``order``, ``cval``, ``mask_cval``,
    ``clip_boxes``); see the module's docstring for the random numbers.
    ``make_params`` returns ``{"transform": the FPI}`` (None where the
    sample is left as it is, with probability 1 - p).

    Examples
    --------
    >>> import torch
    >>> from torchvision import tv_tensors
    >>> from torchvision.transforms import v2
    >>> from fpiwarp.augment.torchvision import RandomFPI
    >>> pipeline = v2.Compose([RandomFPI(max_distortion=1.2, seed=0), v2.ToDtype(torch.float32, scale=True)])
    >>> img = tv_tensors.Image(torch.zeros(3, 32, 48, dtype=torch.uint8))
    >>> boxes = tv_tensors.BoundingBoxes([[4, 4, 20, 30]], format="XYXY", canvas_size=(32, 48))
    >>> out_img, out_boxes = pipeline(img, boxes)
    >>> out_img.shape, type(out_boxes).__name__
    (torch.Size([3, 32, 48]), 'BoundingBoxes')
    """

    def __init__(self, max_distortion=1.3, max_corner_shift=0.1, p=1.0, seed=None, backend=None, antialias=False,
                 order=1, cval=0, mask_cval=0, clip_boxes=True):
        super().__init__()
        self.aug = random_fpi.RandomFPI(max_distortion, max_corner_shift, p, seed, backend, antialias, order, cval,
                                        mask_cval, clip_boxes)
        self.seed = seed
        self._worker = None  # the DataLoader worker whose seed the generator holds (None: the main process)

    def extra_repr(self):
        a = self.aug
        return f"max_distortion={a.max_distortion}, max_corner_shift={a.max_corner_shift}, p={a.p}, seed={self.seed}"

    def _draws(self):
        if self.seed is None:
            return torch.rand(DRAWS, dtype=torch.float64).numpy()[None]
        info = torch.utils.data.get_worker_info()
        worker = None if info is None else (info.id, info.seed)
        if worker != self._worker:
            self._worker = worker
            self.aug.rng = np.random.default_rng(self.seed if worker is None else [self.seed, info.seed])
        return self.aug.rng.random((1, DRAWS))

    def make_params(self, flat_inputs):
        """``{"transform": FPI or None}``: the sample's map for its size (None: left as it is)."""
        hw = v2.query_size(flat_inputs)
        draws = self._draws()
        if draws[0, -1] >= self.aug.p:
            return {"transform": None}
        return {"transform": self.aug.maps_from_draws(draws, hw, p=1.0)[0]}

    def transform(self, inpt, params):
        """One input of the sample through the sample's map (see the module's docstring)."""
        f = params["transform"]
        if f is None:
            return inpt
        if isinstance(inpt, tv_tensors.BoundingBoxes):
            return self._boxes(inpt, f)
        if isinstance(inpt, _KEYPOINTS):
            pts = inpt.detach().reshape(-1, 2).cpu().double().numpy()
            out = torch.from_numpy(f(pts)).to(inpt.dtype).reshape(inpt.shape).to(inpt.device)
            return tv_tensors.wrap(out, like=inpt)
        if isinstance(inpt, tv_tensors.Mask):
            return tv_tensors.wrap(self._planes(inpt, f, mask=True), like=inpt)
        if isinstance(inpt, PIL.Image.Image):
            return PIL.Image.fromarray(self.aug.apply_to_image(f, np.ascontiguousarray(np.asarray(inpt))))
        if isinstance(inpt, torch.Tensor):  # Image, Video, or the plain tensor torchvision takes as the image
            out = self._planes(inpt, f, mask=False)
            return tv_tensors.wrap(out, like=inpt) if isinstance(inpt, tv_tensors.TVTensor) else out
        return inpt

    def _planes(self, tensor, f, mask):
        """(..., H, W) masks or (..., C, H, W) images, each plane warped by f."""
        if tensor.ndim < (2 if mask else 3):
            raise ArgumentError(f"a {'mask' if mask else 'image'} tensor must be (..., {'' if mask else 'C, '}H, W), "
                                f"got shape {tuple(tensor.shape)}")
        dtype = tensor.dtype
        x = tensor.detach()
        if not mask and dtype not in _IMAGE_DTYPES:
            if not dtype.is_floating_point:
                raise ArgumentTypeError(f"images must be uint8, uint16 or floating point tensors, got {dtype} "
                                        "(label images are tv_tensors.Mask)")
            x = x.float()
        if x.device.type != "cpu":  # warped where it lives (fpiwarp.arrays), one plane group at a time
            return self._device_planes(x, f, mask).to(dtype)
        h, w = x.shape[-2:]
        if mask:
            planes = x.reshape(-1, h, w).numpy()
            out = np.stack([self.aug.apply_to_mask(f, np.ascontiguousarray(p)) for p in planes])
        else:
            c = x.shape[-3]
            planes = x.reshape(-1, c, h, w).numpy()
            out = np.stack([np.concatenate([self._hwc(f, img[k:k + 4]) for k in range(0, c, 4)]) for img in planes])
        return torch.from_numpy(out).reshape(tensor.shape).to(dtype)

    def _hwc(self, f, chw):
        """Up to 4 channels (c, H, W) warped as one (H, W, c) image, back as (c, H, W)."""
        img = np.ascontiguousarray(chw[0] if len(chw) == 1 else np.moveaxis(chw, 0, -1))
        out = self.aug.apply_to_image(f, img)
        return out[None] if out.ndim == 2 else np.moveaxis(out, -1, 0)

    def _device_planes(self, x, f, mask):
        from ..warping import warp_image  # noqa: PLC0415

        h, w = x.shape[-2:]
        if mask:
            out = [warp_image(p.contiguous(), f, order=0, cval=self.aug.mask_cval, backend=self.aug.backend)
                   for p in x.reshape(-1, h, w)]
            return torch.stack([torch.as_tensor(o, device=x.device) for o in out]).reshape(x.shape)
        c = x.shape[-3]
        out = [torch.cat([torch.as_tensor(warp_image(img[k:k + 4].contiguous(), f, order=self.aug.order,
                                                     cval=self.aug.cval, backend=self.aug.backend,
                                                     antialias=self.aug.antialias, channels="first"),
                                          device=x.device).reshape(-1, h, w) for k in range(0, c, 4)])
               for img in x.reshape(-1, c, h, w)]
        return torch.stack(out).reshape(x.shape)

    def _boxes(self, boxes, f):
        fmt = boxes.format
        if fmt.name not in ("XYXY", "XYWH", "CXCYWH"):
            raise ArgumentError(f"fpiwarp.augment.torchvision.RandomFPI maps axis-aligned boxes (XYXY, XYWH, "
                                f"CXCYWH), got format {fmt.name}: a warped rotated box is not a rotated box")
        xyxy = F.convert_bounding_box_format(boxes.as_subclass(torch.Tensor), old_format=fmt,
                                             new_format=tv_tensors.BoundingBoxFormat.XYXY)
        b = xyxy.detach().reshape(-1, 4).cpu().double().numpy()
        bounds = self.aug.apply_to_annotations(f, boxes.canvas_size, boxes=b - 0.5)["boxes"] + 0.5
        if not boxes.dtype.is_floating_point:  # whole pixels: round outward, the bounds still hold the outline
            bounds = np.concatenate([np.floor(bounds[:, :2]), np.ceil(bounds[:, 2:])], axis=1)
        out = torch.from_numpy(bounds).to(boxes.dtype).reshape(boxes.shape).to(boxes.device)
        out = F.convert_bounding_box_format(out, old_format=tv_tensors.BoundingBoxFormat.XYXY, new_format=fmt)
        return tv_tensors.wrap(out, like=boxes)
