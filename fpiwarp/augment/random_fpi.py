"""RandomFPI: a random four-point warp within a distortion budget, for
images and everything annotated on them."""

import numpy as np

from ..batch.images import warp_batch
from ..errors import ArgumentError
from ..warping import warp_image
from .sampling import DRAWS, check_budget, one_random_fpi, random_fpis
from .targets import as_boxes, as_points, box_bounds, clip_boxes, densify, inside, stack_box_bounds


class RandomFPI:
    """A random FPI per sample: the image outline's four corners move by up
    to ``max_corner_shift`` of its size, with conformal distortion K <=
    ``max_distortion`` everywhere (closed form, see
    ``fpiwarp.augment.sampling``) and no fold over the image.

    Parameters
    ----------
    max_distortion : float
        The budget K_max >= 1 (K = 1: conformal; 1.3: mild).
    max_corner_shift : float
        The largest corner move, a fraction of the width (x) and height
        (y), at most 0.25.
    p : float
        The probability of warping a sample (else the identity).
    seed : int, numpy Generator or None
        Where the draws come from: the same seed gives the same maps, on
        every backend, and ``batch`` of n gives the maps of n calls.
    backend : str or None
        Where images are warped; None: fpiwarp's default (the fastest
        backend that works here for numpy arrays, see
        :func:`fpiwarp.default_backend`; the data's own for device arrays).
    antialias : bool
        Filter images over each pixel's footprint (masks never).
    order : {0, 1, 3}
        Image interpolation (masks always at 0).
    cval, mask_cval : number
        What images and masks show outside the source.
    clip_boxes : bool
        Clip boxes to the output frame (``boxes_visible`` says which keep an area).

    Calling it on one sample, ``aug(image=..., mask=..., keypoints=...,
    boxes=..., polygons=...)`` (any of them), returns a dict of the same
    keys, warped, plus ``"transform"`` (the FPI used), ``"keypoints_visible"``
    and ``"boxes_visible"`` where those were given. Keypoints are (n, 2)
    (x = column, y = row, pixel centres at integers) through the exact
    forward map; boxes (n, 4) (x0, y0, x1, y1) become the exact bounds of
    their outline's image; polygons (a list of (V, 2)) go vertex by vertex,
    with ``densify`` points added on each edge first.

    Examples
    --------
    >>> import numpy as np
    >>> from fpiwarp.augment import RandomFPI
    >>> aug = RandomFPI(max_distortion=1.2, seed=0, backend="numpy")
    >>> out = aug(image=np.zeros((32, 48), np.uint8), keypoints=[[10.0, 5.0]])
    >>> sorted(out), out["transform"].K <= 1.2
    (['image', 'keypoints', 'keypoints_visible', 'transform'], True)
    """

    def __init__(self, max_distortion=1.3, max_corner_shift=0.1, p=1.0, seed=None, backend=None, antialias=False,
                 order=1, cval=0, mask_cval=0, clip_boxes=True, densify=0):
        self.max_distortion, self.max_corner_shift, self.p = check_budget(max_distortion, max_corner_shift, p)
        self.rng = np.random.default_rng(seed)
        self.backend, self.antialias, self.order = backend, antialias, order
        self.cval, self.mask_cval, self.clip_boxes, self.densify = cval, mask_cval, bool(clip_boxes), int(densify)

    def __repr__(self):
        return (f"RandomFPI(max_distortion={self.max_distortion}, max_corner_shift={self.max_corner_shift}, "
                f"p={self.p})")

    # --- the maps
    def sample(self, shape, n=None):
        """The maps of the next ``n`` samples (an FPIStack), or of the next
        one (an FPI) when ``n`` is None, for (H, W) images."""
        draws = self.rng.random((1 if n is None else n, DRAWS))
        if n is None:
            return one_random_fpi(draws, image_size(shape), self.max_distortion, self.max_corner_shift, self.p)
        return self.maps_from_draws(draws, shape)

    def maps_from_draws(self, draws, shape, p=None):
        """The FPIStack of ``draws`` ((n, DRAWS) uniforms in [0, 1), the
        last the probability's, ``p`` None: this transform's) for (H, W)
        images: how the adapters turn their library's random numbers into
        this transform's maps."""
        return random_fpis(np.asarray(draws, np.float64).reshape(-1, DRAWS), image_size(shape), self.max_distortion,
                           self.max_corner_shift, self.p if p is None else p)

    def apply_to_image(self, f, image):
        """``image`` warped by map ``f`` as this transform warps images."""
        return warp_image(image, f, order=self.order, cval=self.cval, backend=self.backend,
                          antialias=self.antialias)

    def apply_to_mask(self, f, mask):
        """``mask`` warped by map ``f`` at order 0 (labels and dtype kept)."""
        return warp_image(mask, f, order=0, cval=self.mask_cval, backend=self.backend)

    # --- one sample
    def __call__(self, *, image=None, mask=None, keypoints=None, boxes=None, polygons=None, shape=None):
        ref = next((a for a in (image, mask) if a is not None), None)
        if ref is None and shape is None:
            raise ArgumentError("give an image or a mask (or shape=(H, W) for annotations alone)")
        hw = image_size(shape if ref is None else _spatial(ref))
        f = self.sample(hw)
        out = {"transform": f}
        if image is not None:
            out["image"] = self.apply_to_image(f, image)
        if mask is not None:
            out["mask"] = self.apply_to_mask(f, mask)
        out.update(self.apply_to_annotations(f, hw, keypoints=keypoints, boxes=boxes, polygons=polygons))
        return out

    def apply_to_annotations(self, f, shape, *, keypoints=None, boxes=None, polygons=None):
        """Keypoints, boxes and polygons of an (H, W) image through map ``f``."""
        out = {}
        if keypoints is not None:
            pts = f(as_points(keypoints, "keypoints"))
            out["keypoints"], out["keypoints_visible"] = pts, inside(pts, shape)
        if boxes is not None:
            bounds = box_bounds(f, boxes)
            if self.clip_boxes:
                bounds, visible = clip_boxes(bounds, shape)
            else:
                visible = inside(bounds[:, :2], shape) | inside(bounds[:, 2:], shape)
            out["boxes"], out["boxes_visible"] = bounds, visible
        if polygons is not None:
            out["polygons"] = [f(densify(as_points(poly, "polygons"), self.densify)) for poly in polygons]
        return out

    # --- many samples
    def batch(self, images=None, masks=None, keypoints=None, boxes=None, *, shape=None, channels="last"):
        """A different map per sample, one launch per kind of call.

        ``images`` and ``masks`` are stacks (N, H, W[, C]) (or (N, C, H, W)
        with ``channels="first"``): numpy, or device arrays warped where
        they live (torch, CuPy, Warp, pyopencl; see :func:`fpiwarp.warp_batch`).
        ``keypoints`` (N, P, 2) and ``boxes`` (N, B, 4) are numpy arrays (or
        lists of (P_i, 2) / (B_i, 4) arrays). The N maps are built at once
        (:meth:`fpiwarp.FPI.many`) and equal those of N calls. Returns a
        dict as the single call does, ``"transform"`` an FPIStack.
        """
        ref = next((a for a in (images, masks) if a is not None), None)
        if ref is None:
            raise ArgumentError("batch needs images or masks (stacks of the same size)")
        dims = tuple(ref.shape)
        n = int(dims[0])
        hw = image_size(dims[2:4] if channels == "first" and len(dims) == 4 else dims[1:3])
        stack = self.sample(hw, n)
        out = {"transform": stack}
        if images is not None:
            out["images"] = warp_batch(images, stack, order=self.order, cval=self.cval,
                                       backend=self.backend, antialias=self.antialias, channels=channels)
        if masks is not None:
            out["masks"] = warp_batch(masks, stack, order=0, cval=self.mask_cval, backend=self.backend,
                                      channels=channels)
        if keypoints is not None:
            out["keypoints"], out["keypoints_visible"] = _batch_points(stack, keypoints, hw)
        if boxes is not None:
            out["boxes"], out["boxes_visible"] = self._batch_boxes(stack, boxes, hw)
        return out

    def _batch_boxes(self, stack, boxes, hw):
        if isinstance(boxes, np.ndarray) and boxes.ndim == 3:
            bounds = stack_box_bounds(stack, boxes)
            if self.clip_boxes:
                return clip_boxes(bounds, hw)
            return bounds, inside(bounds[..., :2], hw) | inside(bounds[..., 2:], hw)
        pairs = [self._batch_boxes(stack[i:i + 1], as_boxes(b)[None], hw) for i, b in enumerate(boxes)]
        return [p[0][0] for p in pairs], [p[1][0] for p in pairs]


def _batch_points(stack, keypoints, hw):
    if isinstance(keypoints, np.ndarray) and keypoints.ndim == 3:
        pts = stack(keypoints)
        return pts, inside(pts, hw)
    mapped = [stack[i:i + 1](as_points(k, "keypoints")[None])[0] for i, k in enumerate(keypoints)]
    return mapped, [inside(m, hw) for m in mapped]


def _spatial(array):
    shape = tuple(array.shape)
    if len(shape) < 2:
        raise ArgumentError(f"an image must be (H, W) or (H, W, C), got shape {shape}")
    return shape[:2]


def image_size(shape):
    """(H, W) of an image's size as ints, or a one-line ArgumentError."""
    h, w = (int(v) for v in shape)
    if h <= 0 or w <= 0:
        raise ArgumentError(f"image size must be positive, got {shape}")
    return h, w
