"""Keypoints, boxes and polygons through a map, exactly.

Keypoints and polygon vertices go through the map's exact forward
formula in float64 (x = column, y = row, pixel centres at integers: the
convention the warp samples with, so a keypoint lands where its pixel
lands, without a half-pixel bias).

A box (x0, y0, x1, y1) becomes the bounds of the image of its outline.
An FPI of the image outline is m_W⁻¹ ∘ A ∘ m_Z with m_Z affine (the
outline is a rectangle, a parallelogram), so each box edge goes through
an affine map to a segment and through the Möbius map m_W⁻¹ to an arc of
a circle (or a segment). The bounds of an arc are its end points and the
points of its circle farthest left, right, up and down that lie on it:
computed in closed form (:func:`arc_bounds`), exact to rounding. Any
other map (a Compound, a local deformation) gets dense sampling: 256
points per edge, whose bounds miss the exact ones by at most
|f''| (edge / 256)² / 8.
"""

import numpy as np

from ..maps.fpi import FPI, FPIStack, mobius_inverse_many

#: Points per box edge where the bounds are sampled (maps other than FPIs).
DENSE_POINTS = 256


def as_points(points, name):
    from ..errors import ArgumentError  # noqa: PLC0415

    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ArgumentError(f"{name} must be an (n, 2) array of (x, y) points, got shape {arr.shape}")
    return arr


def as_boxes(boxes):
    from ..errors import ArgumentError  # noqa: PLC0415

    arr = np.asarray(boxes, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ArgumentError(f"boxes must be an (n, 4) array of (x0, y0, x1, y1), got shape {arr.shape}")
    if np.any(arr[:, 2] < arr[:, 0]) or np.any(arr[:, 3] < arr[:, 1]):
        raise ArgumentError("boxes must have x0 <= x1 and y0 <= y1 (x = column, y = row)")
    return arr


def inside(points, shape):
    """(n,) bool: points within the (H, W) frame [-0.5, W - 0.5] x [-0.5, H - 0.5]."""
    h, w = shape
    x, y = points[..., 0], points[..., 1]
    return np.isfinite(x) & np.isfinite(y) & (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)


def clip_boxes(boxes, shape):
    """Boxes clipped to the (H, W) frame, and (n,) bool: those of positive area."""
    h, w = shape
    out = boxes.copy()
    out[..., 0::2] = np.clip(out[..., 0::2], -0.5, w - 0.5)
    out[..., 1::2] = np.clip(out[..., 1::2], -0.5, h - 0.5)
    return out, (out[..., 2] > out[..., 0]) & (out[..., 3] > out[..., 1])


def _outline(boxes):
    """(n, 4 edges, 2 ends) complex: the box edges, corners in order."""
    x0, y0, x1, y1 = boxes.T
    c = np.stack([x0 + 1j * y0, x1 + 1j * y0, x1 + 1j * y1, x0 + 1j * y1], axis=1)
    return np.stack([c, np.roll(c, -1, axis=1)], axis=2)


def box_bounds(transform, boxes):
    """(n, 4) bounds (x0, y0, x1, y1) of the image of each box's outline
    under ``transform`` (an FPI, one map of an :class:`~fpiwarp.maps.fpi.FPIStack`, or any
    map)."""
    boxes = as_boxes(boxes)
    if len(boxes) == 0:
        return boxes.copy()
    if isinstance(transform, FPI) and transform.m_src.s == 0:
        return stack_box_bounds(FPIStack.of([transform]), boxes[None])[0]
    edges = _outline(boxes)
    t = np.linspace(0, 1, DENSE_POINTS)
    pts = edges[..., :1] + (edges[..., 1:] - edges[..., :1]) * t  # (n, 4, DENSE_POINTS)
    w = transform.map_complex(pts.reshape(-1)).reshape(len(boxes), -1)
    return np.stack([w.real.min(1), w.imag.min(1), w.real.max(1), w.imag.max(1)], axis=1)


def stack_box_bounds(stack, boxes):
    """(N, n, 4) exact bounds of (N, n, 4) boxes, set i under map i of an
    :class:`~fpiwarp.maps.fpi.FPIStack` whose source-side Möbius parts are affine (s = 0: the
    maps of an image outline)."""
    qs, ss, als, l1, l2, l3, qd, sd, ald = stack.parts
    if np.any(ss != 0):
        raise ValueError("stack_box_bounds needs maps whose source Möbius part is affine (s = 0)")
    n, m = boxes.shape[:2]
    edges = _outline(boxes.reshape(-1, 4)).reshape(n, m * 8)
    u = als[:, None] * (edges - qs[:, None])  # m_Z (affine), then A: the ends as points of the middle plane
    p = l1[:, None] * u + l2[:, None] * np.conj(u) + l3[:, None]
    p = p.reshape(n, m * 4, 2)
    ends = np.stack([p[..., 0], 0.5 * (p[..., 0] + p[..., 1]), p[..., 1]], axis=-1).reshape(n, -1)
    with np.errstate(all="ignore"):
        a, mid, b = np.moveaxis(mobius_inverse_many(ends, qd, sd, ald).reshape(n, m * 4, 3), -1, 0)
        lo, hi = arc_bounds(a, mid, b)
    lo, hi = lo.reshape(n, m, 4), hi.reshape(n, m, 4)
    return np.stack([lo.real.min(2), lo.imag.min(2), hi.real.max(2), hi.imag.max(2)], axis=-1)


def arc_bounds(a, mid, b):
    """(low, high) complex corners of the bounds of the circular arcs from
    ``a`` through ``mid`` to ``b`` (complex arrays; a straight segment where
    the three are collinear to rounding)."""
    lo = np.minimum(a.real, b.real) + 1j * np.minimum(a.imag, b.imag)
    hi = np.maximum(a.real, b.real) + 1j * np.maximum(a.imag, b.imag)
    ba, ma = b - a, mid - a
    cross = (np.conj(ba) * ma).imag
    chord = np.abs(ba)
    curved = np.abs(cross) > 1e-12 * chord * chord  # sagitta above 1e-12 chords: a circle, not a segment
    d = np.where(curved, 2 * cross, 1.0)
    # circumcenter of a, mid, b relative to a
    center = a + 1j * (ba * np.abs(ma) ** 2 - ma * np.abs(ba) ** 2) / d
    r = np.abs(a - center)
    for direction in (1, -1, 1j, -1j):
        e = center + r * direction
        on_arc = curved & (np.sign((np.conj(ba) * (e - a)).imag) == np.sign(cross))  # mid's side of the chord
        lo = np.where(on_arc, np.minimum(lo.real, e.real) + 1j * np.minimum(lo.imag, e.imag), lo)
        hi = np.where(on_arc, np.maximum(hi.real, e.real) + 1j * np.maximum(hi.imag, e.imag), hi)
    return lo, hi


def densify(polygon, k):
    """A closed polygon (V, 2) with ``k`` points inserted evenly on each edge."""
    if k <= 0:
        return polygon
    nxt = np.roll(polygon, -1, axis=0)
    t = np.arange(k + 1) / (k + 1)
    return (polygon[:, None] + (nxt - polygon)[:, None] * t[None, :, None]).reshape(-1, 2)
