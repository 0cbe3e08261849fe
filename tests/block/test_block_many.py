"""Packing many maps at once (fpiwarp.block.many) equals packing each map
alone, bit for bit, and groups the blocks by kind as describing each
block would."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.batch_cases import KINDS, make_map
from support.strategies import orient_like, quads

import fpiwarp
from fpiwarp.backends.opencl.backend import kind_options
from fpiwarp.block import Stage, describe, pack
from fpiwarp.block.many import BlockStack, pack_many

SQUARE = [[8, 6], [30, 6], [30, 22], [8, 22]]
BENT = [[8, 6], [30, 6], [33, 25], [10, 22]]
finite = st.floats(-50, 50, allow_nan=False, allow_infinity=False)
cplx = st.builds(complex, finite, finite)
unit = st.builds(lambda r, t: complex(r * np.exp(1j * t)), st.floats(0.2, 5), st.floats(0, 2 * np.pi))


@st.composite
def maps(draw):
    """One map of any kind a batch may hold."""
    kind = draw(st.sampled_from(["fpi", "mobius", "rlinear", "compound", "local", "constrained", "made"]))
    if kind in ("fpi", "compound"):
        src = draw(quads(max_scale=1e3))
        f = fpiwarp.FPI(src, orient_like(draw(quads(max_scale=1e3)), src))
        return f @ fpiwarp.RLinear(draw(unit), 0.1 * draw(unit), draw(cplx)) if kind == "compound" else f
    if kind == "mobius":
        a, d, c = draw(unit), draw(unit), 0.01 * draw(unit)
        return fpiwarp.Mobius(a, 0.1 * draw(cplx), c, d, center=draw(st.sampled_from([None, 0.1 * draw(cplx)])))
    if kind == "rlinear":
        return fpiwarp.RLinear(draw(unit), 0.15 * draw(unit), draw(cplx))
    if kind in ("local", "constrained"):
        edges = draw(st.sampled_from([(1, 3), (0, 2)]))
        cls = fpiwarp.LocalDeformation if kind == "local" else fpiwarp.ConstrainedFPI
        return cls(SQUARE, BENT, edges=edges)
    return make_map(draw(st.sampled_from(KINDS)), draw(st.integers(0, 4)), 23, 17)


def same_bits(a, b):
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.uint32), b.view(np.uint32))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(st.lists(maps(), min_size=1, max_size=6), st.booleans())
def test_each_block_of_the_stack_is_the_maps_params_bit_for_bit(transforms, inverse):
    chosen = [t.inverse if inverse else t for t in transforms]
    stack = BlockStack.of(chosen)
    assert stack.array.dtype == np.float32 and len(stack) == len(chosen)
    for i, t in enumerate(chosen):
        alone = t.params()
        assert same_bits(stack.array[i, : stack.rows[i]], alone)
        assert same_bits(stack.blocks()[i], alone)
        assert not stack.array[i, stack.rows[i]:].any()  # zero rows past the block
    assert same_bits(BlockStack.from_blocks([t.params() for t in chosen]).array, stack.array)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(st.lists(maps(), min_size=1, max_size=8))
def test_groups_match_describing_each_block(transforms):
    stack = BlockStack.of(transforms)
    for key in (kind_options, lambda kind: tuple((s.core, s.n_regions) for s in kind.stages)):
        groups = stack.groups(key)
        seen = np.concatenate([idx for _, idx in groups])
        assert sorted(seen.tolist()) == list(range(len(transforms)))  # each map in exactly one group
        assert len({k for k, _ in groups}) == len(groups)  # one group per key
        firsts = [int(idx[0]) for _, idx in groups]
        assert firsts == sorted(firsts)  # in order of first appearance
        for k, idx in groups:
            assert np.all(np.diff(idx) > 0)
            assert all(key(describe(transforms[i].params())) == k for i in idx)
        rows, blocks = stack.take(groups[0][1])
        assert rows == max(len(transforms[i].params()) for i in groups[0][1]) and blocks.shape[1] == rows


def test_the_errors_of_pack():
    with pytest.raises(ValueError, match="1 to 8 stages"):
        pack_many([[Stage()], []])
    with pytest.raises(ValueError, match="1 to 8 stages"):
        pack_many([[Stage()] * 9])
    with pytest.raises(ValueError, match="unknown core"):
        pack_many([[Stage(core=99)]])
    bad = pack([Stage()])
    bad[1, 0] = 99  # an unknown core in the header
    with pytest.raises(ValueError, match="unknown core 99"):
        BlockStack.from_blocks([pack([Stage()]), bad]).groups(lambda kind: None)
