"""The public protocols: what every map implements (Transform), where each
output pixel samples the source (source_positions), and what a backend
offers (Backend, bind, prepare_warp)."""

import numpy as np
import pytest
from support.kernel_cases import MAPS

import fpiwarp
from fpiwarp.backends import get_backend
from fpiwarp.backends.protocol import Backend, BatchingBackend, GenericBoundMap, bind

H, W = 24, 32
SRC = [[0, 0], [31, 0], [31, 23], [0, 23]]
DST = [[2, 1], [29, -2], [33, 24], [-1, 21]]


@pytest.mark.parametrize("name", sorted(MAPS))
def test_every_map_implements_the_public_protocol(name):
    f = MAPS[name]()
    pts = np.array([[3.0, 4.0], [20.0, 7.5], [11.0, 19.0]])
    z = pts[:, 0] + 1j * pts[:, 1]
    w = f.map_complex(z)
    np.testing.assert_array_equal(np.stack([w.real, w.imag], -1), f(pts))
    assert len(f.stages()) >= 1
    if name != "compound_of_stages":  # a hand-built block given without its inverse
        assert isinstance(f.inverse, fpiwarp.Transform)
    try:
        value, fz, fzb = f.wirtinger(z)
    except NotImplementedError:  # maps given only by their block (kernel_cases.Staged)
        return
    np.testing.assert_allclose(value, w, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(f.jacobian(pts)[:, 0, 0], (fz + fzb).real, rtol=1e-12)


def test_transform_is_an_abstract_base_class():
    class Incomplete(fpiwarp.Transform):
        def map_complex(self, z):
            return z

    with pytest.raises(TypeError, match="abstract"):
        Incomplete()

    class Shift(fpiwarp.Transform):
        def wirtinger(self, z):
            return z + 1, np.ones_like(z), np.zeros_like(z)

        @property
        def inverse(self):
            return fpiwarp.RLinear(1, 0, -1)

        def stages(self):
            return fpiwarp.RLinear(1, 0, 1).stages()

    np.testing.assert_array_equal(Shift()([[1.0, 2.0]]), [[2.0, 2.0]])
    assert Shift().distortion([[0.0, 0.0]])[0] == 1.0


def test_compound_keeps_the_former_private_names():
    f = fpiwarp.FPI(SRC, DST) @ fpiwarp.Mobius(1, 0.5, 0.01, 1)
    z = np.array([1 + 2j, 5 + 1j])
    np.testing.assert_array_equal(f._map(z), f.map_complex(z))
    np.testing.assert_array_equal(f._wirtinger(z)[1], f.wirtinger(z)[1])


def test_source_positions_layout_and_remap_semantics(rng):
    f = fpiwarp.FPI(SRC, DST)
    pos = fpiwarp.source_positions(f, (H, W))
    assert pos.shape == (H, W, 2) and pos.dtype == np.float64
    np.testing.assert_array_equal(pos[5, 9], f.inverse([[9.0, 5.0]])[0])  # [row, col] -> source (x, y)
    ndimage = pytest.importorskip("scipy.ndimage")
    image = rng.random((H, W)).astype(np.float32)
    got = fpiwarp.warp_image(image, f, order=1, mode="edge")
    ref = ndimage.map_coordinates(image, [pos[..., 1], pos[..., 0]], order=1, mode="nearest")
    np.testing.assert_allclose(got, ref, atol=1e-5)


def test_source_positions_mark_pixels_at_the_pole_non_finite():
    f = fpiwarp.Mobius(1, 0, 1 / 20, 1)  # f(inf) = 20: the inverse has its pole at pixel (20, 0)
    pos = fpiwarp.source_positions(f, (40, 40))
    assert not np.isfinite(pos).all() and np.isfinite(pos).any()


def test_source_positions_refuse_bad_arguments():
    f = fpiwarp.FPI(SRC, DST)
    with pytest.raises(fpiwarp.ArgumentError, match="output_shape"):
        fpiwarp.source_positions(f, None)
    with pytest.raises(fpiwarp.ArgumentTypeError, match="transform"):
        fpiwarp.source_positions("map", (3, 3))


def test_backends_follow_the_protocol(any_backend):
    backend = get_backend(any_backend)
    assert isinstance(backend, Backend) and backend.name == any_backend
    caps = fpiwarp.backend_capabilities(any_backend)
    assert isinstance(backend, BatchingBackend) == caps.batches


def test_bind_warps_like_warp_image(any_backend, rng):
    image = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
    f = fpiwarp.FPI(SRC, DST)
    bound = bind(get_backend(any_backend), f)
    assert not isinstance(bound, GenericBoundMap)  # every backend prepares its maps (issue 14)
    got = bound.warp_image(image, (20, 30), order=1, mode="edge", cval=np.zeros(3))
    np.testing.assert_array_equal(got, fpiwarp.warp_image(image, f, (20, 30), mode="edge", backend=any_backend))


@pytest.mark.parametrize("name", ["opencl", "warp"])
def test_prepare_warp_runs_the_kernel_alone_like_warp_image(name, rng, request):
    request.getfixturevalue(f"{name}_backend")
    backend = get_backend(name)
    image = rng.integers(0, 256, size=(H, W, 4), dtype=np.uint8)
    maps = [fpiwarp.FPI(SRC, DST), fpiwarp.FPI(SRC, [[0, 0], [33, 2], [30, 22], [1, 25]])]
    job = backend.prepare_warp(image, (H, W), order=1, mode="constant", cval=np.zeros(4))
    for f in maps:
        job.set_map(f)
        job.launch()
        job.finish()
        np.testing.assert_array_equal(job.read(), fpiwarp.warp_image(image, f, backend=name))
