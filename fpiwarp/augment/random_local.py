"""RandomLocal: a random local deformation (paper §4.1) per sample.

Each sample draws a region of interest inside the image (a rectangle of
``region_size`` of the image's sides at a random place, its corners
moved by up to ``region_jitter`` of its sides: a convex quad), two
constrained edges (``edges``: at random among the opposite and adjacent
pairs, or as asked) and target corners moved by up to
``max_corner_shift`` of the region's sides, then builds
:class:`fpiwarp.LocalDeformation` through its public constructor. The
targets respect the constraint: with opposite edges every corner moves
freely (each edge's two corners define its similarity); with adjacent
edges the corner between them and its two neighbours follow one
similarity (that of the first two), the fourth moves freely.

Where the construction refuses the draw (a fold inside the region, a
quad beyond a constrained edge's line, a constraint it cannot meet) the
target jitter is halved and the map rebuilt, at most
:data:`MAX_HALVINGS` times; then the sample is the identity (never an
unbounded loop). The draws per sample are fixed (:data:`DRAWS`), so a
batch of n gives the maps of n calls.

Keypoints and polygons go through the exact forward map. Boxes become
the bounds of their outline sampled densely (:data:`fpiwarp.augment.targets.DENSE_POINTS`
points per edge): they miss the exact bounds by at most |f''| (edge / 256)² / 8
where the map is smooth, plus the map's jump where an outline crosses
the line of a constrained edge beyond the region (see
:mod:`fpiwarp.maps.local`: up to 6e-4 of the edge's length along the
edges with the defaults).
"""

import numpy as np

from ..batch.images import warp_batch
from ..errors import ArgumentError, FpiwarpError
from ..maps.local import LocalDeformation
from .random_fpi import RandomFPI, image_size
from .sampling import MAX_CORNER_SHIFT

#: Uniform draws per sample: region size (2) and place (2), region corners
#: (8), edge choice (1), target corners (8), probability (1).
DRAWS = 22
#: Halvings of the target jitter before a refused draw becomes the identity.
MAX_HALVINGS = 8
#: The constrained-edge pairs drawn from, by ``edges``.
EDGE_CHOICES = {"opposite": ((0, 2), (1, 3)), "adjacent": ((0, 1), (1, 2), (2, 3), (3, 0))}
EDGE_CHOICES["random"] = EDGE_CHOICES["opposite"] + EDGE_CHOICES["adjacent"]


class RandomLocal(RandomFPI):
    """A random :class:`fpiwarp.LocalDeformation` per sample, with the call
    API of :class:`RandomFPI` (``aug(image=..., mask=..., keypoints=...,
    boxes=..., polygons=...)``, ``aug.batch(...)``, ``aug.sample(shape, n)``).

    Parameters
    ----------
    max_corner_shift : float
        The largest target-corner move, a fraction of the region's sides
        (at most 0.25).
    region_size : (float, float)
        The region's sides, as fractions of the image's, drawn uniformly
        in this range (within (0, 1]).
    region_jitter : float
        How far the region's corners stray from its rectangle, a fraction
        of its sides (at most 0.25: the region stays convex).
    edges : {"random", "opposite", "adjacent"} or (int, int)
        The constrained edges (edge k joins corners k and k + 1).
    p, seed, backend, antialias, order, cval, mask_cval, clip_boxes, densify
        As :class:`RandomFPI`.

    Examples
    --------
    >>> import numpy as np
    >>> from fpiwarp.augment import RandomLocal
    >>> aug = RandomLocal(seed=0, backend="numpy")
    >>> out = aug(image=np.zeros((48, 64), np.uint8), keypoints=[[10.0, 5.0]])
    >>> type(out["transform"]).__name__, out["image"].shape
    ('LocalDeformation', (48, 64))
    """

    def __init__(self, max_corner_shift=0.1, region_size=(0.3, 0.7), region_jitter=0.1, edges="random", p=1.0,
                 seed=None, backend=None, antialias=False, order=1, cval=0, mask_cval=0, clip_boxes=True, densify=0):
        super().__init__(1.0, max_corner_shift, p, seed, backend, antialias, order, cval, mask_cval, clip_boxes,
                         densify)
        self.max_distortion = None  # no budget: a local deformation's distortion varies over the plane
        try:
            lo, hi = (float(v) for v in region_size)
            jitter = float(region_jitter)
        except (TypeError, ValueError):
            raise ArgumentError(f"region_size must be two numbers and region_jitter a number, got "
                                f"{region_size!r}, {region_jitter!r}") from None
        if not 0 < lo <= hi <= 1:
            raise ArgumentError(f"region_size must be (low, high) with 0 < low <= high <= 1, got {region_size!r}")
        if not 0 <= jitter <= MAX_CORNER_SHIFT:
            raise ArgumentError(f"region_jitter must lie in [0, {MAX_CORNER_SHIFT}] (beyond it the region may not be "
                                f"convex), got {region_jitter!r}")
        self.region_size, self.region_jitter = (lo, hi), jitter
        self.edge_choices = _edge_choices(edges)

    def __repr__(self):
        return (f"RandomLocal(max_corner_shift={self.max_corner_shift}, region_size={self.region_size}, "
                f"region_jitter={self.region_jitter}, p={self.p})")

    def sample(self, shape, n=None):
        """The maps of the next ``n`` samples (a list), or of the next one
        when ``n`` is None, for (H, W) images."""
        hw = image_size(shape)
        draws = self.rng.random((1 if n is None else n, DRAWS))
        maps = [self.map_from_draw(d, hw) for d in draws]
        return maps[0] if n is None else maps

    def region_and_targets(self, draw, shape):
        """(src (4, 2), dst (4, 2), edges) of one draw (DRAWS uniforms), before any halving."""
        h, w = shape
        size = np.array([w, h], float)
        lo, hi = self.region_size
        margin = self.region_jitter
        sides = (lo + (hi - lo) * draw[0:2]) * size / (1 + 2 * margin)  # with its jitter, inside the frame
        corner = -0.5 + margin * sides + draw[2:4] * (size - (1 + 2 * margin) * sides)
        rect = corner + np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * sides
        src = rect + (2 * draw[4:12].reshape(4, 2) - 1) * margin * sides
        edges = self.edge_choices[min(int(draw[12] * len(self.edge_choices)), len(self.edge_choices) - 1)]
        move = (2 * draw[13:21].reshape(4, 2) - 1) * self.max_corner_shift * sides
        dst = src + move if draw[21] < self.p else src.copy()
        if (edges[1] - edges[0]) % 4 in (1, 3):  # adjacent: corners around the shared one follow one similarity
            i = edges[0] if (edges[1] - edges[0]) % 4 == 1 else edges[1]
            a, b, c = i, (i + 1) % 4, (i + 2) % 4
            zs, ws = src[[a, b, c], 0] + 1j * src[[a, b, c], 1], dst[[a, b], 0] + 1j * dst[[a, b], 1]
            s = (ws[1] - ws[0]) / (zs[1] - zs[0])
            wc = ws[0] + s * (zs[2] - zs[0])
            dst[c] = wc.real, wc.imag
        return src, dst, edges

    def map_from_draw(self, draw, shape):
        """The LocalDeformation of one draw, its jitter halved where refused."""
        src, dst, edges = self.region_and_targets(np.asarray(draw, float), shape)
        for _ in range(MAX_HALVINGS + 1):
            try:
                return LocalDeformation(src, dst, edges=edges)
            except (FpiwarpError, ValueError):  # a fold, a line-bound or a constraint refusal
                dst = src + (dst - src) / 2
        return LocalDeformation(src, src.copy(), edges=edges)

    def batch(self, images=None, masks=None, keypoints=None, boxes=None, *, shape=None, channels="last"):
        """As :meth:`RandomFPI.batch`, ``"transform"`` a list of the maps;
        images and masks in one call of :func:`fpiwarp.warp_batch` each."""
        ref = next((a for a in (images, masks) if a is not None), None)
        if ref is None:
            raise ArgumentError("batch needs images or masks (stacks of the same size)")
        dims = tuple(ref.shape)
        hw = image_size(dims[2:4] if channels == "first" and len(dims) == 4 else dims[1:3])
        maps = self.sample(hw, int(dims[0]))
        out = {"transform": maps}
        if images is not None:
            out["images"] = warp_batch(images, maps, order=self.order, cval=self.cval,
                                       backend=self.backend, antialias=self.antialias, channels=channels)
        if masks is not None:
            out["masks"] = warp_batch(masks, maps, order=0, cval=self.mask_cval, backend=self.backend,
                                      channels=channels)
        if keypoints is not None:
            mapped = [maps[i](np.asarray(k, float)) for i, k in enumerate(keypoints)]
            out["keypoints"], out["keypoints_visible"] = _batch_points_of(mapped, keypoints, hw)
        if boxes is not None:
            pairs = [self.apply_to_annotations(maps[i], hw, boxes=b) for i, b in enumerate(boxes)]
            out["boxes"] = [q["boxes"] for q in pairs]
            out["boxes_visible"] = [q["boxes_visible"] for q in pairs]
            if isinstance(boxes, np.ndarray) and boxes.ndim == 3:
                out["boxes"], out["boxes_visible"] = np.stack(out["boxes"]), np.stack(out["boxes_visible"])
        return out


def _batch_points_of(mapped, keypoints, hw):
    from .targets import inside  # noqa: PLC0415

    visible = [inside(m, hw) for m in mapped]
    if isinstance(keypoints, np.ndarray) and keypoints.ndim == 3:
        return np.stack(mapped), np.stack(visible)
    return mapped, visible


def _edge_choices(edges):
    if isinstance(edges, str):
        if edges not in EDGE_CHOICES:
            raise ArgumentError(f"edges must be 'random', 'opposite', 'adjacent' or a pair of edge indices, "
                                f"got {edges!r}")
        return EDGE_CHOICES[edges]
    try:
        i, j = (int(e) for e in edges)
    except (TypeError, ValueError):
        raise ArgumentError(f"edges must be 'random', 'opposite', 'adjacent' or a pair of edge indices, "
                            f"got {edges!r}") from None
    if not (0 <= i <= 3 and 0 <= j <= 3 and i != j):
        raise ArgumentError(f"edges must be two different edge indices in 0..3, got {edges!r}")
    return ((i, j),)
