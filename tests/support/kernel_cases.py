"""Maps and tolerances shared by the kernel backend tests.

Hand-built parameter-block maps (a thin-plate spline, its Newton inverse,
regions) besides the FPI family, and the accuracy contract every backend
meets: map_points within RTOL = 1e-5 relative of the float64 reference,
warp_image within one level of the numpy backend on PIXEL_FRACTION of the
pixels (make_image, reference, assert_images_agree, compare_warp).
"""

import numpy as np

from fpiwarp import FPI, Mobius, RLinear, Transform
from fpiwarp.backends.numpy import backend as numpy_backend
from fpiwarp.block import (
    CORE_TPS,
    CORE_TPS_INVERSE,
    CORE_TPS_PAIRS,
    CORE_TPS_PAIRS_INVERSE,
    LinearPart,
    Region,
    Stage,
    evaluate,
)
from fpiwarp.block.jacobian import wirtinger

RTOL = 1e-5
PIXEL_FRACTION = 0.998
MODES = ["constant", "edge", "reflect", "wrap"]
ORDERS = [0, 1, 3]
DTYPES = [np.uint8, np.uint16, np.float32]
LEVEL = {np.uint8: 1.0, np.uint16: 257.0, np.float32: 1.0 / 255}


class Staged(Transform):
    """A map given directly by parameter-block stages, evaluated by the
    float64 reference; ``inverse_stages`` give its inverse for warp_image."""

    def __init__(self, stages, inverse_stages=None):
        self._stages = list(stages)
        self._inverse_stages = inverse_stages

    def stages(self):
        return list(self._stages)

    def map_complex(self, z):
        out = evaluate(self.params(), np.stack([z.real, z.imag], axis=-1), np.float64)
        return out[..., 0] + 1j * out[..., 1]

    def wirtinger(self, z):
        out, fz, fzb = wirtinger(self.params(), np.stack([z.real, z.imag], axis=-1), np.float64)
        return out[..., 0] + 1j * out[..., 1], fz, fzb

    @property
    def inverse(self):
        return Staged(self._inverse_stages, self._stages)


# A mild thin-plate spline on a 64×48 frame, its Newton inverse, and regions.
_CENTERS = np.array([10 + 8j, 50 + 10j, 30 + 25j, 12 + 40j, 55 + 42j, 32 + 5j])
_WEIGHTS = np.array([3e-4 + 1e-4j, -2e-4 + 2e-4j, 1e-4 - 3e-4j, -3e-4 - 1e-4j, 2e-4, 1e-4j])
_LINEAR = LinearPart(1.02 + 0.01j, 0.03 - 0.02j, 1.5 - 0.5j)


def tps_stage():
    return Stage(linear=_LINEAR, core=CORE_TPS, centers=_CENTERS, weights=_WEIGHTS)


def tps_inverse_stage(iters=20, tol=1e-4):
    return Stage(
        linear=_LINEAR, core=CORE_TPS_INVERSE, centers=_CENTERS, weights=_WEIGHTS, newton_iters=iters, newton_tol=tol
    )


# The same centers as pairs (CORE_TPS_PAIRS): each with a partner 0.05 away
# and weights of 2e-3 (nearly opposite within the pair: W is the small
# _WEIGHTS), except the last, which has none (d = 0, b2 = 0).
_OFFSETS = np.array([0.05j, -0.05, 0.03 + 0.04j, 0.05, -0.04j, 0j])
_OFFSET_WEIGHTS = np.array([2e-3 - 1e-3j, -2e-3, 1e-3j, 2e-3 + 2e-3j, -1e-3 + 1e-3j, 0j])


def tps_pairs_stage():
    return Stage(linear=_LINEAR, core=CORE_TPS_PAIRS, centers=_CENTERS, weights=_WEIGHTS, offsets=_OFFSETS,
                 offset_weights=_OFFSET_WEIGHTS)


def tps_pairs_inverse_stage(iters=20, tol=1e-4):
    return Stage(linear=_LINEAR, core=CORE_TPS_PAIRS_INVERSE, centers=_CENTERS, weights=_WEIGHTS, offsets=_OFFSETS,
                 offset_weights=_OFFSET_WEIGHTS, newton_iters=iters, newton_tol=tol)


_REGIONS = (
    Region(origin=52 + 0j, normal=1 + 0j, a=1 + 0j, b=2 + 1j),  # x > 52: shift
    Region(origin=0 + 6j, normal=-1j, a=0.9 + 0.1j, b=1 - 2j),  # y < 6: similarity
)


def region_stage():
    return Stage(linear=LinearPart(1.01 + 0.02j, 0.02j, 0.5 + 0.25j), regions=_REGIONS)


def region_inverse_stage():
    inv = RLinear(1.01 + 0.02j, 0.02j, 0.5 + 0.25j).inverse
    regions = tuple(Region(r.a * r.origin + r.b, r.a * r.normal, 1 / r.a, -r.b / r.a) for r in _REGIONS)
    return Stage(linear=LinearPart(inv.l1, inv.l2, inv.l3), regions=regions)


def tps_map():
    return Staged([tps_stage()], [tps_inverse_stage()])


def tps_pairs_map():
    return Staged([tps_pairs_stage()], [tps_pairs_inverse_stage()])


def region_map():
    return Staged([region_stage()], [region_inverse_stage()])


def sample_fpi():
    return FPI([[0, 0], [63, 0], [63, 47], [0, 47]], [[4, 3], [60, -2], [66, 50], [-3, 44]])


def frame_points(rng, n=4000, margin=10.0):
    return rng.uniform([-margin, -margin], [64 + margin, 48 + margin], size=(n, 2))


def assert_close_relative(got, want, rtol=RTOL, atol=0.0):
    """|got - want| <= rtol * max(|want|, 1) + atol per point (vector norms)."""
    assert got.shape == want.shape and got.dtype == np.float64
    err = np.linalg.norm(got - want, axis=-1)
    scale = np.maximum(np.linalg.norm(want, axis=-1), 1.0)
    worst = np.max((err - atol) / scale)
    assert worst <= rtol, f"relative error {worst:.3g} > {rtol} (beyond atol {atol})"


def newton_atol(transform):
    """A Newton inverse is only defined to its tolerance: the reference stops
    once the residual is <= newton_tol, the device may take one step more.
    Residual to position: the TPS here has |f_z| - |f_zbar| >= 0.9."""
    tols = [st.newton_tol for st in transform.stages() if st.core in (CORE_TPS_INVERSE, CORE_TPS_PAIRS_INVERSE)]
    return max(tols, default=0.0) / 0.9



MAPS = {
    "fpi": sample_fpi,
    "mobius": lambda: Mobius(2 + 1j, 3 - 1j, 0.004 + 0.006j, 1),  # pole near (-77, 115)
    "rlinear": lambda: RLinear(1.2 + 0.3j, 0.1 - 0.2j, 5 + 7j),
    "compound": lambda: RLinear(0.9, 0.05j, 2) @ sample_fpi() @ Mobius(1 + 0.1j, 2, 0.001j, 1),
    "tps": tps_map,
    "tps_inverse": lambda: tps_map().inverse,
    "compound_of_stages": lambda: Staged([tps_stage(), *sample_fpi().stages(), tps_inverse_stage()]),
    "tps_pairs": tps_pairs_map,
    "tps_pairs_inverse": lambda: tps_pairs_map().inverse,
}


# --- images ---------------------------------------------------------------------


def make_image(shape, dtype, seed=0):
    """Random pixels over the dtype's whole range ([0, 1) for float32)."""
    rng = np.random.default_rng(seed)
    if np.dtype(dtype).kind == "f":
        return rng.random(shape).astype(dtype)
    return rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)


def assert_images_agree(got, want, dtype, fraction=PIXEL_FRACTION, levels=1.0):
    """Same dtype and shape, and ``fraction`` of the pixels within ``levels`` levels."""
    assert got.dtype == want.dtype and got.shape == want.shape
    diff = np.abs(got.astype(np.float64) - want.astype(np.float64))
    ok = np.all(diff <= levels * LEVEL[dtype] * (1 + 1e-6), axis=-1)
    assert ok.mean() >= fraction, f"only {ok.mean():.4%} of pixels within {levels} level(s)"


def reference(img, transform, shape, order, mode, cval):
    """The numpy backend's warp of an (H, W, C) image, and cval per channel."""
    cv = np.broadcast_to(np.asarray(cval, dtype=np.float64), (img.shape[2],)).copy()
    return numpy_backend.Backend().warp_image(img, transform, shape, order=order, mode=mode, cval=cv), cv


def compare_warp(backend, img, transform, shape, order, mode, cval, levels=1.0):
    """``backend.warp_image`` against the reference: within ``levels`` levels."""
    want, cv = reference(img, transform, shape, order, mode, cval)
    got = backend.warp_image(img, transform, shape, order=order, mode=mode, cval=cv)
    assert_images_agree(got, want, img.dtype.type, levels=levels)
    return got, want


def takes_coarse_pass(transform, backend, shape):
    """Whether a plain (not antialiased) warp by ``transform`` to ``shape``
    (rows, cols) on ``backend`` ("opencl" or "gl") takes the coarse pass
    (fpiwarp/block/coarse.py): a map with a Newton core while the backend's
    COARSE_PASS switch is on, where the rule picks it
    (fpiwarp/block/coarse_choice.py). Its positions then lie nearer the
    exact inverse than a per-pixel solve's, agreeing with one within a level."""
    from fpiwarp.block.coarse_choice import takes_coarse_pass as rule  # noqa: PLC0415
    from support.batch_cases import coarse_switch  # noqa: PLC0415

    try:  # the backend's switch (its module needs the backend's library)
        on = coarse_switch(backend).COARSE_PASS
    except ImportError:
        return False
    return on and rule(np.asarray(transform.inverse.params(), np.float32), shape[1], shape[0], backend)
