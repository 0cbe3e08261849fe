"""The seeded quad-pair fuzz of ``quad_fuzz.py``, small enough for every
CI run (a few seconds): every accepted pair has K >= 1, meets its corners
and its inverse's corners, and round-trips points around the source to
the documented tolerance; mirrored pairs are all refused."""

import numpy as np
import pytest
from support.quad_fuzz import classify, tally

from fpiwarp.testing import broad_pairs, mirrored_pairs, unit_pairs


@pytest.mark.parametrize("seed", [0, 1])
def test_broad_fuzz_accepts_only_exact_maps(seed):
    counts = tally(broad_pairs(np.random.default_rng(seed), 1000), seed)
    wrong = {k: v for k, v in counts.items() if k.startswith("accepted") and k != "accepted: ok"}
    assert not wrong, counts
    assert counts.get("accepted: ok", 0) > 500, counts  # the fuzz exercises real maps


@pytest.mark.parametrize("offset", [0.0, 3e8, 1e9])
def test_unit_pairs_far_out_are_accepted_and_mirrors_refused(offset):
    rng = np.random.default_rng(42)
    assert tally(unit_pairs(rng, 100, offset)) == {"accepted: ok": 100}
    for z, w in mirrored_pairs(rng, 100, offset):
        (verdict, reason), _ = classify(z, w, rng)
        assert verdict == "refused" and "opposite orientations" in reason
