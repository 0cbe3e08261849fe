"""The OpenCL warp with the coarse pass maps a work-group's pixels in phases
(fpiwarp_map.h, fw_map_coarse_group): the stages before the first Newton
stage and its regions per pixel, the band's pixels listed, their seeds
checked FW_VN at a time, the solve where a check fails, the later stages
per pixel. Every launch shape and width it may run with (one-row groups,
tiles, 1 lane as on GPUs where the list is built by a local counter, 8 and
16 lanes) samples where the reference's seeded solve says
(fpiwarp.block.coarse.evaluate_pixels), for maps whose Newton stage is
paired or not, has regions or not, comes first, last or between others,
and for a compound with a second Newton stage (solved per pixel); shapes
at the same width give the same output bit for bit."""

import numpy as np
import pytest
from support.batch_cases import local_map

import fpiwarp
from fpiwarp.block.coarse import evaluate_pixels


def _map(name, w, h):
    """The map ``name`` (of :data:`MAPS`) over a w x h frame."""
    fpi = fpiwarp.FPI([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]],
                      [[0.4, -0.3], [w - 1.6, 0.5], [w - 0.7, h - 0.2], [0.3, h - 1.4]])
    if name == "constrained (paired, no regions)":
        quad = np.array([[0.2 * w, 0.2 * h], [0.8 * w, 0.15 * h], [0.85 * w, 0.8 * h], [0.15 * w, 0.85 * h]])
        return fpiwarp.ConstrainedFPI(quad, quad + [[0.5, 0.3], [-0.4, 0.6], [0.3, -0.5], [-0.2, 0.4]],
                                      edges=(0, 2), spacing="graded")
    if name == "tps (three centers, not paired)":
        return fpiwarp.ThinPlateSpline([w / 4 + 1j * h / 3, w / 2 + 1j * h / 2, 3 * w / 4 + 1j * h / 4],
                                       [0.002, -0.003, 0.002j], (1, 0.05, 1 + 0.5j))
    local = local_map(0, w, h)
    return {"local (paired, two regions)": local, "fpi then local": local @ fpi, "local then fpi": fpi @ local,
            "local twice": local @ local}[name]


MAPS = ["local (paired, two regions)", "constrained (paired, no regions)", "tps (three centers, not paired)",
        "fpi then local", "local then fpi", "local twice"]


#: (tile: local_x, local_y or None for the backend's one-row groups; lanes: FW_VN or None for the backend's)
VARIANTS = [(None, None), (None, 1), (None, 8), (None, 16), ((64, 4), 8), ((16, 16), 16), ((24, 3), 1)]


def _positions(transform, h, w, variant, monkeypatch):
    """The source positions (h, w, 2) an opencl warp with the coarse pass
    (forced) samples, read from a float32 image of its coordinates, built
    with the launch ``variant``."""
    from fpiwarp.backends import get_backend
    from fpiwarp.backends.opencl import prepared
    from fpiwarp.block import coarse_choice

    tile, lanes = variant
    plain = prepared.tiled_program

    def shaped(*args):
        name, options, local = plain(*args)
        if lanes is not None:
            options = (*(o for o in options if not o.startswith("-DFW_VN=")), f"-DFW_VN={lanes}")
        if tile is not None:
            options = (*(o for o in options if not o.startswith(("-DFW_LOCAL_X=", "-DFW_LOCAL_Y="))),
                       f"-DFW_LOCAL_X={tile[0]}", f"-DFW_LOCAL_Y={tile[1]}")
            local = tile
        return name, options, local

    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.stack([x, y, np.zeros_like(x)], -1)
    with monkeypatch.context() as patch:
        patch.setattr(prepared, "tiled_program", shaped)
        patch.setattr(coarse_choice, "ALWAYS", True)
        bound = get_backend("opencl").bind(transform)
        assert prepared.takes_coarse(bound.kind, False, bound.block, (h, w))
        out = bound.warp_image(img, (h, w), order=1, mode="constant", cval=(-1.0, -1.0, -1.0))
    return out[..., :2]


@pytest.mark.parametrize("name", MAPS)
@pytest.mark.parametrize("h, w", [(37, 101), (70, 48)])
def test_every_launch_shape_samples_where_the_seeded_reference_says(opencl_backend, monkeypatch, name, h, w):
    """Inside the picture each shape's positions are the seeded reference's
    (1e-3 px) but where the float32 check decides a pixel's seed the other
    way (at most 0.2 % of them: its own solve then answers, within the
    Newton tolerance), and map back onto their pixels (2e-2 px)."""
    transform = _map(name, w, h)
    want = evaluate_pixels(transform.inverse.params(), w, h, np.float32)
    inside = (want[..., 0] >= 0) & (want[..., 0] <= w - 1) & (want[..., 1] >= 0) & (want[..., 1] <= h - 1)
    assert inside.mean() > 0.5
    y, x = np.mgrid[0:h, 0:w]
    by_lanes = {}
    for variant in VARIANTS:
        got = _positions(transform, h, w, variant, monkeypatch)
        off = np.abs(got - want).max(-1)[inside]
        assert (off > 1e-3).mean() <= 2e-3, (variant, (off > 1e-3).sum())
        back = transform.map_complex(got[..., 0].astype(np.float64) + 1j * got[..., 1])
        assert np.abs(back - (x + 1j * y))[inside].max() <= 2e-2, variant
        same = by_lanes.setdefault(variant[1], got)
        np.testing.assert_array_equal(got, same, err_msg=f"{variant} against the one-row groups' output")
