"""Random FPIs of an image within a distortion budget, built on arrays.

The source quad is the image's outline (pixel centres at integers: the
corners (-0.5, -0.5) and (W - 0.5, H - 0.5)); each target corner moves by
up to ``max_corner_shift`` of the image's width and height. The FPI of
the pair is m_W⁻¹ ∘ A ∘ m_Z (paper §3), whose conformal distortion is
that of its R-linear part A alone, K = (|l1| + |l2|) / (|l1| - |l2|).
Where a draw's K exceeds the budget, A's anti-conformal part l2 is scaled
to meet it exactly (|l2| / |l1| = (K_max - 1) / (K_max + 1)) and the
target corners become m_W⁻¹ ∘ A' ∘ m_Z of the source corners: one closed
form per map, no rejection. The maps keep their pole off the image (a
pole inside would fold the picture) and their target quad convex: with
corner shifts up to 1/4 of the image a drawn quad is convex, but scaling
A can fold a quad of a thin image whose corners moved far; such a map
(or one whose pole lies within a pixel of the image) gets its jitter
halved and is drawn again from the halved jitter (measured: never at
the defaults on square images).
"""

import numpy as np

from ..errors import ArgumentError, FpiwarpError
from ..maps.fpi import FPI, FPIStack
from ..maps.fpi import quads_near_refusal as _near_refusal

#: Largest corner shift: up to it the target quad stays convex.
MAX_CORNER_SHIFT = 0.25
#: The budget is met with this relative margin, so that rounding (about
#: 1e-14 K²) never lifts K above it (at K_max = 1, conformal maps, K is 1
#: to its rounding, 1e-15).
BUDGET_MARGIN = 1e-9
#: Uniform draws per sample: 8 corner coordinates and the probability's.
DRAWS = 9


def image_corners(shape):
    """The outline of an (H, W) image as a quad (4, 2), pixel centres at integers."""
    h, w = shape
    return np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])


def check_budget(max_distortion, max_corner_shift, p):
    """The three numbers as floats, or a one-line ArgumentError."""
    try:
        k, shift, prob = float(max_distortion), float(max_corner_shift), float(p)
    except (TypeError, ValueError):
        raise ArgumentError(f"max_distortion, max_corner_shift and p must be numbers, got {max_distortion!r}, "
                            f"{max_corner_shift!r}, {p!r}") from None
    if not 1 <= k < np.inf:
        raise ArgumentError(f"max_distortion must be a finite number >= 1 (K = 1: conformal), got {max_distortion!r}")
    if not 0 <= shift <= MAX_CORNER_SHIFT:
        raise ArgumentError(f"max_corner_shift must lie in [0, {MAX_CORNER_SHIFT}] (a fraction of the image's size; "
                            f"beyond it the target quad may fold), got {max_corner_shift!r}")
    if not 0 <= prob <= 1:
        raise ArgumentError(f"p must lie in [0, 1], got {p!r}")
    return k, shift, prob


def random_fpis(draws, shape, max_distortion, max_corner_shift, p):
    """The FPIs of ``draws`` (n, DRAWS) uniforms in [0, 1) for an (H, W)
    image: an :class:`~fpiwarp.maps.fpi.FPIStack` of n maps with K <=
    ``max_distortion`` and no pole on the image; a sample whose last draw
    is >= p is the identity."""
    n = len(draws)
    h, w_ = shape
    src = np.broadcast_to(image_corners(shape), (n, 4, 2))
    jitter = (2 * draws[:, :8].reshape(n, 4, 2) - 1) * max_corner_shift * np.array([w_, h], float)
    jitter = np.where((draws[:, 8] < p)[:, None, None], jitter, 0.0)
    for _ in range(60):  # halvings for the few maps the budget's scaling would fold (never at small shifts)
        dst, stack = _within_budget(src, src + jitter, max_distortion)
        w = dst[..., 0] + 1j * dst[..., 1]
        bad = ~_convex(w) | _near_refusal(w)
        if not bad.any():
            stack = FPI.many(src, dst) if stack is None else stack
            pole = stack.poles
            bad = (np.abs(pole.real - (w_ - 1) / 2) <= w_ / 2 + 1) & (np.abs(pole.imag - (h - 1) / 2) <= h / 2 + 1)
            if not bad.any():
                return stack
        jitter = np.where(bad[:, None, None], jitter / 2, jitter)
    raise AssertionError("unreachable: a jitter halved 60 times is an identity")  # pragma: no cover


def one_random_fpi(draws, shape, max_distortion, max_corner_shift, p):
    """The FPI of one draw ((1, DRAWS) uniforms), as :func:`random_fpis`
    gives it, built lean: the corners in plain Python floats (the same
    operations in the same order, so the same numbers) and one
    :class:`~fpiwarp.maps.fpi.FPI` with its own checks, no arrays of maps.
    A draw that the budget binds (rare: 0.1% at the defaults on square
    images), or whose quad or pole needs a look, takes the array path."""
    h, w = shape
    d = draws[0].tolist()
    src = ((-0.5, -0.5), (w - 0.5, -0.5), (w - 0.5, h - 0.5), (-0.5, h - 0.5))
    if d[8] < p:
        size = (float(w), float(h))
        dst = tuple(tuple(c[k] + (2 * d[2 * i + k] - 1) * max_corner_shift * size[k] for k in (0, 1))
                    for i, c in enumerate(src))
    else:
        dst = src
    if _convex_corners(dst):
        try:
            f = FPI(np.array(src), np.array(dst))
        except FpiwarpError:
            f = None
        if f is not None and f.K <= max_distortion:
            pole = f.pole
            on_image = pole is not None and abs(pole[0] - (w - 1) / 2) <= w / 2 + 1 and \
                abs(pole[1] - (h - 1) / 2) <= h / 2 + 1
            if not on_image:
                return f
    return random_fpis(draws, shape, max_distortion, max_corner_shift, p)[0]


def _convex_corners(corners):
    """A quad of 4 (x, y) tuples strictly convex, counter-clockwise on screen (as :func:`_convex`)."""
    for i in range(4):
        (ax, ay), (bx, by), (cx, cy) = corners[i], corners[(i + 1) % 4], corners[(i + 2) % 4]
        if not (bx - ax) * (cy - by) - (by - ay) * (cx - bx) > 0:
            return False
    return True


def _convex(w):
    """(N,) bool: quads w (N, 4) strictly convex, counter-clockwise on screen as the image outline."""
    e = np.roll(w, -1, axis=1) - w
    turn = (np.conj(e) * np.roll(e, -1, axis=1)).imag
    return np.all(turn > 0, axis=1) & np.all(np.isfinite(w), axis=1)


def _within_budget(src, dst, max_distortion):
    """(dst, its FPIStack or None where it changed): the target corners with
    those of maps above the budget moved to meet it (the FPI's R-linear
    part scaled to K = max_distortion)."""
    stack = FPI.many(src, dst)
    K = stack.K
    over = K > max_distortion
    if not over.any():
        return dst, stack
    qs, ss, als, l1, l2, l3, qd, sd, ald = stack.parts
    mu_max = (max_distortion - 1) / (max_distortion + 1) * (1 - BUDGET_MARGIN)
    mu = np.abs(l2) / np.abs(l1)
    scaled = np.where(over, l2 * (mu_max / np.where(over, mu, 1)), l2)
    z = src[..., 0] + 1j * src[..., 1]
    moved = FPIStack(z, z, (qs, ss, als, l1, scaled, l3, qd, sd, ald)).map_complex(z)
    return np.where(over[:, None, None], np.stack([moved.real, moved.imag], axis=-1), dst), None
