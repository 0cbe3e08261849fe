"""Geometric augmentation with a distortion budget.

:class:`RandomFPI` draws a four-point interpolant per sample with
conformal distortion K <= ``max_distortion`` (closed form) and no fold
over the image, and applies it to images (any order), masks (order 0:
labels kept, any integer or bool dtype), keypoints (the exact forward
map), boxes (the exact bounds of their outline's image) and polygons;
``batch`` does the same for stacks with a different map per sample, in
one launch per kind of call, numpy or device arrays alike.
:class:`RandomLocal` does the same with a random local deformation
(paper §4.1: a region of interest, two constrained edges). The adapters
``fpiwarp.augment.torchvision`` and ``fpiwarp.augment.albumentations``
put RandomFPI into those libraries' pipelines (imported on their own).
"""

from .random_fpi import RandomFPI
from .random_local import RandomLocal
from .sampling import image_corners, random_fpis
from .targets import arc_bounds, box_bounds

__all__ = ["RandomFPI", "RandomLocal", "arc_bounds", "box_bounds", "image_corners", "random_fpis"]
