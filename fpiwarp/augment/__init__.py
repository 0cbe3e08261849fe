"""Geometric augmentation with a distortion budget.

:class:`RandomFPI` draws a four-point interpolant per sample with
conformal distortion K <= ``max_distortion`` (closed form) and no fold
over the image, and applies it to images (any order), masks (order 0:
labels kept, any integer or bool dtype), keypoints (the exact forward
map), boxes (the exact bounds of their outline's image) and polygons;
``batch`` does the same for stacks with a different map per sample, in
one launch per kind of call, numpy or device arrays alike.
"""

from .random_fpi import RandomFPI
from .sampling import image_corners, random_fpis
from .targets import arc_bounds, box_bounds

__all__ = ["RandomFPI", "arc_bounds", "box_bounds", "image_corners", "random_fpis"]
