"""RandomFPI as an albumentations ``DualTransform``.

``fpiwarp.augment.albumentations.RandomFPI(...)`` draws one map per call
(in ``get_params_dependent_on_data``, from the transform's own
``random_generator``, so ``A.Compose(..., seed=...)`` reproduces it and
albumentations' worker seeding applies) and applies it to the sample's
image(s), mask(s) at order 0 (labels and dtype kept), bboxes and
keypoints, in ``A.Compose`` with ``bbox_params`` / ``keypoint_params`` of
any format (albumentations converts them to its internal ones first).

Conventions: albumentations' keypoints have pixel centres at integers, as
fpiwarp's, and go through the exact forward map; their angle and scale
follow the map's Jacobian along the keypoint's direction (the direction
(cos a, sin a) becomes J (cos a, sin a): its angle, and the scale times
its length). Its boxes are normalized with pixel edges at integers (a
full-image box is (0, 0, 1, 1)); each becomes the exact bounds of its
mapped outline (:func:`fpiwarp.augment.box_bounds`), and the
``bbox_params`` processor then clips and filters them as for any
transform. Needs ``pip install 'fpiwarp[albumentations]'``.
"""

try:
    from albumentations.core.transforms_interface import DualTransform
except ImportError as exc:  # pragma: no cover - exercised only without albumentations
    from fpiwarp.errors import MissingDependencyError

    raise MissingDependencyError(f"fpiwarp.augment.albumentations needs albumentations: pip install "
                                 f"'fpiwarp[albumentations]' ({exc})") from None

import numpy as np

from . import random_fpi
from .sampling import DRAWS

__all__ = ["RandomFPI"]


class RandomFPI(DualTransform):
    """A random four-point warp within a distortion budget, for
    albumentations pipelines.

    ``max_distortion``, ``max_corner_shift``, ``backend``, ``antialias``,
    ``order``, ``cval`` and ``mask_cval`` are those of
    :class:`fpiwarp.augment.RandomFPI`; ``p`` is albumentations' (the
    probability of applying the transform). The map of a call is in its
    parameters as ``"transform"``.

    Examples
    --------
    >>> import albumentations as A
    >>> import numpy as np
    >>> from fpiwarp.augment.albumentations import RandomFPI
    >>> pipeline = A.Compose([RandomFPI(max_distortion=1.2)], seed=0,
    ...                      bbox_params=A.BboxParams(format="pascal_voc", label_fields=["labels"]),
    ...                      keypoint_params=A.KeypointParams(format="xy"))
    >>> out = pipeline(image=np.zeros((32, 48, 3), np.uint8), mask=np.zeros((32, 48), np.int32),
    ...                bboxes=[[4, 4, 20, 30]], labels=[1], keypoints=[[10.0, 5.0]])
    >>> out["image"].shape, out["mask"].dtype, len(out["bboxes"])
    ((32, 48, 3), dtype('int32'), 1)
    """

    def __init__(self, max_distortion=1.3, max_corner_shift=0.1, backend=None, antialias=False, order=1, cval=0,
                 mask_cval=0, p=1.0):
        super().__init__(p=p)
        self.aug = random_fpi.RandomFPI(max_distortion, max_corner_shift, 1.0, None, backend, antialias, order, cval,
                                        mask_cval, clip_boxes=False)
        self.max_distortion, self.max_corner_shift = self.aug.max_distortion, self.aug.max_corner_shift
        self.backend, self.antialias, self.order, self.cval, self.mask_cval = backend, antialias, order, cval, mask_cval

    def get_transform_init_args_names(self):
        return ("max_distortion", "max_corner_shift", "backend", "antialias", "order", "cval", "mask_cval")

    def get_params_dependent_on_data(self, params, data):
        """``{"transform": FPI}``: the sample's map, drawn from ``random_generator``."""
        draws = self.random_generator.random((1, DRAWS))
        return {"transform": self.aug.maps_from_draws(draws, params["shape"][:2], p=1.0)[0]}

    def apply(self, img, transform, **params):
        """The image (H, W[, C], any C) warped by the map."""
        if img.ndim == 3 and img.shape[2] > 4:  # up to 4 channels per warp
            return np.concatenate([self.apply(img[..., k:k + 4], transform) for k in range(0, img.shape[2], 4)], -1)
        out = self.aug.apply_to_image(transform, np.ascontiguousarray(img))
        return out[..., None] if img.ndim == 3 and out.ndim == 2 else out

    def apply_to_mask(self, mask, transform, **params):
        """A mask (H, W[, C]) at order 0, labels and dtype kept."""
        if mask.ndim == 3:  # (H, W, C) label planes, each at order 0
            return np.stack([self.apply_to_mask(mask[..., k], transform) for k in range(mask.shape[2])], -1)
        return self.aug.apply_to_mask(transform, np.ascontiguousarray(mask))

    def apply_to_bboxes(self, bboxes, transform, **params):
        """Normalized (N, 4+) boxes: the bounds of each mapped outline."""
        if len(bboxes) == 0:
            return bboxes
        h, w = params["shape"][:2]
        scale = np.array([w, h, w, h], float)
        pixels = bboxes[:, :4].astype(np.float64) * scale - 0.5  # fpiwarp's frame: pixel centres at integers
        out = bboxes.copy()
        out[:, :4] = (self.aug.apply_to_annotations(transform, (h, w), boxes=pixels)["boxes"] + 0.5) / scale
        return out

    def apply_to_keypoints(self, keypoints, transform, **params):
        """(N, 2+) keypoints through the map (angle and scale by its Jacobian)."""
        if len(keypoints) == 0:
            return keypoints
        out = keypoints.astype(np.float64)
        xy = out[:, :2].copy()
        out[:, :2] = transform(xy)
        if out.shape[1] >= 5:  # x, y, z, angle, scale (albumentations' internal columns)
            direction = np.stack([np.cos(out[:, 3]), np.sin(out[:, 3])], axis=-1)
            moved = np.einsum("nij,nj->ni", transform.jacobian(xy), direction)
            out[:, 3] = np.mod(np.arctan2(moved[:, 1], moved[:, 0]), 2 * np.pi)
            out[:, 4] *= np.hypot(moved[:, 0], moved[:, 1])
        return out.astype(keypoints.dtype, copy=False)
