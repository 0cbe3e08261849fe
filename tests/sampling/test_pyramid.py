"""The source pyramid of antialiased warps (fpiwarp.sampling.pyramid) and
the reference's footprint sampling over it: level sizes and halving,
constant images, energy above the output Nyquist, continuity across level
switches, bounded work, and the reuse of host sources' pyramids
(SourcePyramids) on every backend."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from support import kernel_cases

import fpiwarp
import fpiwarp.sampling.antialias as aa
from fpiwarp import FPI, Mobius, RLinear
from fpiwarp.backends import get_backend
from fpiwarp.backends.numpy import backend as numpy_backend
from fpiwarp.block.sampling_rules import AA_LEVEL_SPAN, AA_MAX_LEVEL, AA_MAX_TAPS, COORD_LIMIT
from fpiwarp.sampling.pyramid import Pyramid, SourcePyramids, halve, level_coordinate, level_sizes


def _warp(img, transform, shape, **kw):
    return fpiwarp.warp_image(img, transform, shape, antialias=True, backend="numpy", **kw)


def _shrink(sx, sy, center=0j):
    """x shrunk by 1/sx, y by 1/sy, output pixel 0 at source ``center``."""
    kx, ky = 1 / sx, 1 / sy
    return RLinear((kx + ky) / 2, (kx - ky) / 2, -(kx * center.real + 1j * ky * center.imag))


# --- the levels ------------------------------------------------------------------


@given(st.integers(1, 70000), st.integers(1, 70000))
def test_level_sizes_halve_up_to_one_pixel_or_the_last_level(h, w):
    sizes = level_sizes(h, w)
    assert sizes[0] == (h, w)
    for (a, b), (c, d) in zip(sizes, sizes[1:]):
        assert (c, d) == (-(-a // 2), -(-b // 2))  # ceil halves
    assert sizes[-1] == (1, 1) or len(sizes) == AA_MAX_LEVEL + 1
    assert len(sizes) <= AA_MAX_LEVEL + 1 and len(set(sizes)) == len(sizes)


@settings(max_examples=60)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=3, max_dims=3, min_side=1, max_side=9),
                  elements=st.floats(-1e3, 1e3)))
def test_halving_is_the_mean_of_2x2_blocks_with_the_last_row_and_column_repeated(level):
    h, w = level.shape[:2]
    padded = np.pad(level, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    want = padded.reshape(padded.shape[0] // 2, 2, padded.shape[1] // 2, 2, -1).mean(axis=(1, 3))
    got = halve(level)
    assert got.shape == ((h + 1) // 2, (w + 1) // 2, level.shape[2])
    assert np.allclose(got, want, rtol=1e-12, atol=1e-9)
    if h % 2 == 0 and w % 2 == 0:
        assert np.isclose(got.sum() * 4, level.sum(), rtol=1e-9, atol=1e-6)  # even sizes keep the total


@given(st.integers(0, 12), st.floats(-1e4, 1e4))
def test_level_texel_centres_map_back_to_their_source_position(k, i):
    centre = (i + 0.5) * 2.0**k - 0.5
    assert np.isclose(level_coordinate(centre, k), i, atol=1e-9)
    assert level_coordinate(i, 0) == i


def test_levels_are_built_when_first_read():
    img = kernel_cases.make_image((64, 64, 1), np.float32)
    pyr = Pyramid(img)
    assert pyr.top == 6 and pyr.built == 0
    assert pyr.level(2).shape == (16, 16, 1) and pyr.built == 2
    assert len(pyr.levels) == 7 and pyr.built == 6
    assert pyr.levels[-1][0, 0, 0] == pytest.approx(img.mean(dtype=np.float64))  # 2^k sides: the top is the mean


# --- footprints over the pyramid -------------------------------------------------

SHRINKS = {"1/8": (8, 8), "1/20": (20, 20), "1/24 x 1/6": (24, 6), "1/5 x 1/40": (5, 40)}


@pytest.mark.parametrize("mode", kernel_cases.MODES)
@pytest.mark.parametrize("name", sorted(SHRINKS))
def test_constant_image_stays_constant_over_the_pyramid(mode, name):
    """Every level of a constant image is that constant: every mode gives it
    back where cval is the constant; constant mode with another cval gives it
    on the pixels whose footprints (with their interpolation taps) stay
    inside the image."""
    value = [17, 140, 250]
    img = np.full((300, 420, 3), value, np.uint8)
    transform = _shrink(*SHRINKS[name], center=-60 - 40j)  # output reaches past the borders
    shape = (12, 24)
    assert np.array_equal(_warp(img, transform, shape, mode=mode, cval=value), np.broadcast_to(value, shape + (3,)))
    out = _warp(img, transform, shape, mode=mode, cval=[0, 5, 9])
    pos = fpiwarp.source_positions(transform, shape)
    sx, sy = SHRINKS[name]
    k, u = aa.pyramid_levels(np.full(shape, sx + 0j), np.full(shape, 1j * sy), 8)
    reach = 0.5 * np.array([sx, sy]) + 2.0 ** (k + (u > 0) + 1)[..., None] + 1
    inside = np.all((pos >= reach) & (pos <= np.array([419, 299]) - reach), axis=-1)
    assert inside.sum() >= 10
    assert np.array_equal(out[inside], np.broadcast_to(value, out[inside].shape))


def _stripes(freq_x, freq_y, shape=(480, 640)):
    y, x = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    return (0.5 + 0.5 * np.cos(2 * np.pi * (freq_x * x + freq_y * y))).astype(np.float32)


@pytest.mark.parametrize("sx, sy, fx, fy", [
    (8, 8, 0.3, 0.02),     # 2.4 cycles per output pixel across x
    (20, 20, 0.07, 0.06),  # 1.4 and 1.2
    (24, 6, 0.1, 0.0),     # anisotropic: 2.4 across the long axis
    (6, 24, 0.02, 0.15),   # anisotropic: 3.6 across y
])
def test_energy_above_the_output_nyquist_is_removed_at_pyramid_levels(sx, sy, fx, fy):
    """A sinusoid far above the output's Nyquist frequency: plain sampling
    aliases it into a visible pattern, the pyramid's footprint average
    leaves under 2 % of its variance and keeps the mean."""
    img = _stripes(fx, fy)
    transform = _shrink(sx, sy, center=40 + 40j)
    shape = (int(400 / sy), int(560 / sx))
    plain = fpiwarp.warp_image(img, transform, shape, mode="reflect", backend="numpy")
    smooth = _warp(img, transform, shape, mode="reflect")
    assert plain.std() > 0.15
    assert smooth.var() < 0.02 * plain.var()
    assert abs(smooth.mean() - 0.5) < 0.02


@pytest.mark.parametrize("sx, sy", [(8, 8), (20, 20), (24, 6)])
def test_content_below_the_output_nyquist_is_kept(sx, sy):
    """A sinusoid of a period of 4 output pixels along the shrunk x axis
    keeps most of its amplitude (the pyramid does not blur far beyond the
    footprint, whose box alone keeps sinc(1/4) = 0.90 of it)."""
    img = _stripes(0.25 / sx, 0.0)
    transform = _shrink(sx, sy, center=40 + 40j)
    shape = (int(400 / sy), int(560 / sx) // 4 * 4)
    smooth = _warp(img, transform, shape, mode="reflect").astype(np.float64)
    phase = 2 * np.pi * 0.25 / sx * (40 + sx * np.arange(shape[1]))  # output column q lies at source x 40 + q sx
    amplitude = 2 * np.hypot((smooth * np.cos(phase)).mean(), (smooth * np.sin(phase)).mean())
    assert 0.75 * 0.5 < amplitude <= 0.5


def _smooth_picture(seed=0, size=400):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    img = np.zeros((size, size))
    for _ in range(12):
        f, th, ph = rng.uniform(0.02, 0.1), rng.uniform(0, np.pi), rng.uniform(0, 2 * np.pi)
        img += np.cos(2 * np.pi * f * (x * np.cos(th) + y * np.sin(th)) + ph)
    img = ((img - img.min()) / np.ptp(img)).astype(np.float32)[..., None]
    img.flags.writeable = False  # one pyramid for all the calls below
    return img


def _level_switch_steps(img):
    """Mean change of a 12 × 12 output between shrinks 0.25 % apart, in
    windows around each level switch: (steps crossing a level, all steps)."""
    crossing, steps = [], []
    for k in (1, 2, 3):
        switch = 2.0**k * AA_LEVEL_SPAN / (1 + aa.AA_SLACK)  # lod = k
        scales = switch * 1.0025 ** np.arange(-6, 7)
        outs = np.array([_warp(img, RLinear(1 / s, 0, -(120 + 130j) / s), (12, 12), mode="reflect")
                         for s in scales])
        d = np.abs(np.diff(outs, axis=0)).mean(axis=(1, 2, 3))
        crossing.append(d[5])  # scales[5] < switch < scales[6]
        steps += list(d)
    return np.array(crossing), np.median(steps)


def test_a_smoothly_varying_shrink_has_no_step_at_level_switches(monkeypatch):
    """Shrinking a smooth picture a little more changes the result a little;
    where the footprint's level switches, no more than elsewhere (the blend
    into the next level). The same measure sees the step that switching
    without the blend makes."""
    img = _smooth_picture()
    crossing, typical = _level_switch_steps(img)
    assert np.all(crossing <= 1.5 * typical), (crossing / typical).round(2)
    monkeypatch.setattr(aa, "AA_BLEND", 1e-9)
    numpy_backend.PYRAMIDS.clear()
    crossing, typical = _level_switch_steps(img)
    assert crossing.max() > 2.5 * typical, (crossing / typical).round(2)


# --- bounded work and the pole ------------------------------------------------------


@given(st.floats(-6, 6), st.floats(-6, 6), st.floats(0, 2 * np.pi), st.floats(0, 2 * np.pi),
       st.integers(0, AA_MAX_LEVEL))
def test_every_footprint_reads_a_bounded_number_of_samples(log_x, log_y, ax, ay, top):
    ex = np.array([2.0**log_x * np.exp(1j * ax), np.inf, np.nan])
    ey = np.array([2.0**log_y * np.exp(1j * ay), 1j, np.nan])
    counts = aa.sample_counts(ex, ey, top)
    assert np.all((counts >= 1) & (counts <= 2 * AA_MAX_TAPS**2))


@given(st.floats(0, 12), st.floats(0, 2 * np.pi))
def test_isotropic_footprints_read_a_few_samples_at_any_shrink(log_s, angle):
    """Past level 0 the footprint spans AA_LEVEL_SPAN to 2 AA_LEVEL_SPAN
    texels: its level's taps and the next level's, whatever the shrink."""
    e = 2.0**log_s * np.exp(1j * angle)
    bound = aa.tap_counts(np.array([2 * AA_LEVEL_SPAN]))[0] ** 2 + aa.tap_counts(np.array([AA_LEVEL_SPAN]))[0] ** 2
    assert aa.sample_counts(np.array([e]), np.array([1j * e]), AA_MAX_LEVEL)[0] <= bound


def test_pole_rule_and_bounded_work_next_to_the_pole():
    """A pixel whose source position is not finite or beyond COORD_LIMIT
    (here the inverse's pole lies on pixel (65, 60)) gives cval; its
    neighbours' huge footprints read at most 2 AA_MAX_TAPS² samples."""
    m = Mobius(2 + 1j, 3 - 1j, 0.25, -16.25 - 15j)
    img = kernel_cases.make_image((48, 64, 1), np.float32)
    shape = (130, 130)
    out = _warp(img, m.inverse, shape, mode="wrap", cval=7)
    pos = fpiwarp.source_positions(m.inverse, shape)
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(pos) <= COORD_LIMIT).all(axis=-1)
    assert bad[60, 65] and np.all(out[bad] == 7) and np.isfinite(out).all()
    assert np.any(out[~bad] != 7)
    (_, _, _, ex, ey), = aa.iter_footprints(m.inverse, shape)
    counts = aa.sample_counts(ex, ey, Pyramid(img).top)
    assert counts.max() <= 2 * AA_MAX_TAPS**2 and counts.max() > 100  # huge footprints, capped


# --- reuse of pyramids on the numpy backend ----------------------------------------------------


@pytest.fixture
def builds(monkeypatch):
    """Count the pyramids the numpy backend builds."""
    numpy_backend.PYRAMIDS.clear()
    made = []

    def counting(image):
        made.append(image.shape)
        return Pyramid(image)

    monkeypatch.setattr(numpy_backend.PYRAMIDS, "build", counting)
    yield made
    numpy_backend.PYRAMIDS.clear()


# --- the one reuse rule of host sources (SourcePyramids), on every backend ----------------


def test_host_sources_reuse_their_pyramid_while_their_pixels_are_unchanged(any_backend, monkeypatch):
    """Every backend: maps over one image build its pyramid once; another
    array of equal pixels reuses it; a writeable array changed in place (or
    the base of a read-only view) gets new levels, giving the picture a
    freshly built pyramid gives; a source over the byte limit is not kept."""
    kept = get_backend(any_backend).host_pyramids
    kept.clear()
    maps = [RLinear(1 / s, 0.04 * s, 1 + 2j) for s in (6, 9)]

    def aa(image, transform=maps[0]):
        return fpiwarp.warp_image(image, transform, (10, 14), antialias=True, backend=any_backend)

    img = kernel_cases.make_image((60, 80, 3), np.uint8, seed=11)
    first = aa(img)
    builds = kept.builds
    assert builds >= 1 and len(kept) == 1
    again = [aa(img, m) for m in maps]
    assert kept.builds == builds and np.array_equal(again[0], first)
    assert np.array_equal(aa(img.copy()), first) and kept.builds == builds  # equal pixels, another array
    img[:, :40] = 255 - img[:, :40]  # in place
    changed = aa(img)
    assert kept.builds == builds + 1 and not np.array_equal(changed, first)
    kept.clear()
    assert len(kept) == 0 and np.array_equal(aa(img.copy()), changed)  # as a fresh pyramid gives
    view = img.view()
    view.flags.writeable = False  # read-only, but its base is not
    seen = aa(view)
    img[:] = 255 - img
    assert not np.array_equal(aa(view), seen)
    kept.clear()
    assert np.array_equal(aa(img.copy()), aa(view))
    monkeypatch.setattr(kept, "max_bytes", img.nbytes - 1)
    kept.clear()
    builds = kept.builds
    pictures = [aa(img) for _ in range(2)]
    assert kept.builds == builds + 2 and len(kept) == 0 and np.array_equal(*pictures)


def test_source_pyramids_keep_the_last_few_sources_by_their_pixels():
    made = []
    kept = SourcePyramids(lambda pixels: made.append(pixels) or len(made), size=2)
    a = np.array([[[0.5], [np.nan]]])
    assert kept.get(a) == 1 and kept.get(a.copy()) == 1  # NaN equals NaN
    assert not made[0].flags.writeable and made[0] is not a  # built from a kept copy
    assert kept.get(a.astype(np.float32)) == 2  # another dtype
    assert kept.get(a.reshape(2, 1, 1)) == 3  # another shape: a (dtype float32) is dropped
    assert kept.get(a.astype(np.float32)) == 2 and kept.get(a) == 4
    assert kept.builds == 4 and len(kept) == 2
    kept.clear()
    assert len(kept) == 0 and kept.get(a) == 5


@settings(max_examples=60, deadline=None)
@given(dtype=st.sampled_from(["uint8", "uint16", "int32", "float32", "float64", "bool"]),
       shape=st.tuples(st.integers(1, 5), st.integers(1, 7), st.integers(1, 4)),
       data=st.data())
def test_source_pyramids_match_pixels_as_np_array_equal_does(dtype, shape, data):
    """A kept pyramid serves a source exactly where np.array_equal (NaN
    equal to NaN for floats) says its pixels equal the kept copy's, for any
    layout (a strided view, a copy) and for float bit patterns that differ
    in equal values (0.0 and -0.0, NaNs of other payloads)."""
    floats = dtype.startswith("float")
    elements = st.sampled_from([0.0, -0.0, 1.5, np.nan, np.inf]) if floats else None
    kept_pixels = data.draw(hnp.arrays(dtype, shape, elements=elements))
    other = data.draw(hnp.arrays(dtype, shape, elements=elements)) if data.draw(st.booleans()) else kept_pixels.copy()
    if floats and data.draw(st.booleans()):  # the same values in other bits
        other = np.where(other == 0, -other, other).astype(dtype)
        other[np.isnan(other)] = np.array(np.nan, dtype) * -1
    if data.draw(st.booleans()):  # not C-contiguous
        other = np.asfortranarray(other)
    kept = SourcePyramids(lambda pixels: object())
    first = kept.get(kept_pixels)
    served = kept.get(other) is first
    assert served == np.array_equal(kept_pixels, other, equal_nan=floats)


def test_source_pyramids_are_thread_safe():
    """Threads getting the pyramids of a few sources at once all get a
    pyramid of their source's pixels; at most ``size`` are kept."""
    kept = SourcePyramids(lambda pixels: pixels.sum(), size=2)
    sources = [np.full((8, 8, 1), v, np.uint16) for v in range(4)]

    def work(i):
        src = sources[i % 4]
        return kept.get(src) == src.sum()

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(work, range(400)))
    assert len(kept) == 2


def test_a_batch_of_one_source_builds_one_pyramid(builds):
    img = kernel_cases.make_image((120, 160, 3), np.uint8)
    maps = [RLinear(1 / s, 0, 0) for s in (6, 8, 12)]
    stack = np.stack([img] * 3)
    got = fpiwarp.warp_batch(stack, maps, (16, 20), antialias=True, backend="numpy")
    assert len(builds) == 1
    want = np.stack([_warp(img, t, (16, 20)) for t in maps])
    assert np.array_equal(got, want)
    builds.clear()
    fpiwarp.warp_batch(stack, maps[0], (16, 20), antialias=True, backend="numpy")  # one wide image
    assert len(builds) == 1
    builds.clear()
    other = stack.copy()
    other[1] = 255 - other[1]
    got = fpiwarp.warp_batch(other, maps, (16, 20), antialias=True, backend="numpy")
    # images 0 and 2 are the kept source's pixels: only the changed one builds
    assert len(builds) == 1 and np.array_equal(got[1], _warp(other[1].copy(), maps[1], (16, 20)))


def test_a_map_that_stays_at_level_zero_builds_no_level():
    img = kernel_cases.make_image((60, 80, 3), np.uint8)
    pyr = Pyramid(img)
    out = np.zeros((20, 27, 3))
    for r0, r1, pos, ex, ey in aa.iter_footprints(FPI([[0, 0], [79, 0], [79, 59], [0, 59]],
                                                      [[0, 0], [27, 0], [27, 20], [0, 20]]), (20, 27)):
        out[r0:r1] = aa.sample_antialiased(img, pos, ex, ey, 1, "edge", 0.0, pyramid=pyr)
    assert pyr.built == 0 and np.ptp(out) > 0
