"""Maps of every block kind, varied by an index, and random batches of
images and maps, for the batch tests."""

import numpy as np
from hypothesis import strategies as st

import fpiwarp


def make_map(kind, k, w, h):
    """A map of ``kind`` (each kind a different block kind), varied by k."""
    src = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    d = 0.37 * k
    fpi = fpiwarp.FPI(src, [[1 + d, 1.2], [w - 2 - 0.5 * d, -1 - d], [w + 1, h - 1 + 0.7 * d], [-1 - 0.3 * d, h - 2]])
    tps = fpiwarp.ThinPlateSpline([w / 4 + 1j * h / 3, w / 2 + 1j * h / 2 + k, 3 * w / 4 + 1j * h / 4],
                                  [0.01, -0.02 * (1 + k), 0.01j], (1, 0.05, 1 + 0.5j * k))
    return {
        "fpi": fpi,
        "fpi_inverse": fpi.inverse,
        "shift": fpiwarp.RLinear(1, 0.1 * k, 0.5 + 1j * k),
        "compound": fpi @ fpiwarp.RLinear(1, 0, k),
        "tps": tps,
        "tps_inverse": tps.inverse,
    }[kind]


KINDS = ["fpi", "fpi_inverse", "shift", "compound", "tps", "tps_inverse"]


def local_map(k, w, h):
    """A LocalDeformation over the middle of a w x h frame (edges 1 and 3
    held), varied by k: a Newton map whose warps on opencl and gl take the
    coarse pass (fpiwarp/block/coarse.py)."""
    sx, sy = w - 1.0, h - 1.0
    src = np.array([[0.4 * sx, 0.3 * sy], [0.6 * sx, 0.3 * sy], [0.6 * sx, 0.7 * sy], [0.4 * sx, 0.7 * sy]])
    move = np.array([[0.02, -0.05], [0.03, 0.02], [-0.02, 0.06], [0.01, -0.03]]) * (1 + 0.3 * k)
    return fpiwarp.LocalDeformation(src, src + move * [sx, sy], edges=(1, 3))


def coarse_switch(backend):
    """The module holding ``backend``'s COARSE_PASS switch ("opencl", "gl")."""
    import importlib  # noqa: PLC0415

    return importlib.import_module({"opencl": "fpiwarp.backends.opencl.prepared",
                                    "gl": "fpiwarp.backends.gl.coarse"}[backend])


@st.composite
def batches(draw):
    n = draw(st.integers(1, 4))
    h, w = draw(st.integers(1, 23)), draw(st.integers(1, 37))
    c = draw(st.sampled_from([1, 2, 3, 4]))
    dtype = draw(st.sampled_from([np.uint8, np.uint16, np.float32]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if dtype is np.float32:
        stack = rng.uniform(-2, 3, size=(n, h, w, c)).astype(np.float32)
    else:
        stack = rng.integers(0, np.iinfo(dtype).max, size=(n, h, w, c), dtype=dtype, endpoint=True)
    if c == 1 and draw(st.booleans()):
        stack = stack[..., 0]
    one = draw(st.booleans())
    kinds = draw(st.lists(st.sampled_from(KINDS), min_size=1 if one else n, max_size=1 if one else n))
    maps = [make_map(kind, k, max(w, 8), max(h, 8)) for k, kind in enumerate(kinds)]
    options = {
        "output_shape": draw(st.sampled_from([None, (draw(st.integers(1, 19)), draw(st.integers(1, 41)))])),
        "order": draw(st.sampled_from([0, 1, 3])),
        "mode": draw(st.sampled_from(["constant", "edge", "reflect", "wrap"])),
        "cval": draw(st.sampled_from([0, 7, 0.5])),
        "antialias": draw(st.booleans()),
    }
    return stack, maps[0] if one else maps, options


def loop(stack, transforms, backend, options):
    maps = [transforms] * len(stack) if isinstance(transforms, fpiwarp.Transform) else transforms
    return np.stack([fpiwarp.warp_image(im, t, backend=backend, **options) for im, t in zip(stack, maps)])
