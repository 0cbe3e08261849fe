"""A thin-plate spline's centers as pairs for the block's paired TPS cores.

A constrained FPI's spline pins every edge point c and its offset copy
c + d, a distance δ apart, with nearly opposite weights of order 1 / δ.
:func:`paired_fields` regroups the spline's terms, in float64, into the
pairs the block stores (:mod:`fpiwarp.block.layout`): per pair the first
center c, the summed weight W, the offset d and the second weight b2, so
that the float32 kernels evaluate them without cancellation
(:mod:`fpiwarp.block.tps_pairs`). The sum of the terms is unchanged:
b_c U(|p - c|) + b_o U(|p - c - d|) = W U(|p - c|) + b_o (U(|p - c - d|) -
U(|p - c|)) with W = b_c + b_o.
"""

import numpy as np

from .block import MAX_CENTERS


def paired_fields(centers, weights, partner):
    """(c, W, d, b2), complex arrays with one entry per pair, or None when
    the pairs do not fit the block (2 rows each, MAX_CENTERS rows).

    ``partner[i]``: the index of the center that center i is the offset
    copy of, -1 for the others (each a pair's first center). A center
    with several offset copies (a shared corner of adjacent constrained
    edges) heads one pair per copy and its weight is split among them in
    proportion to the copies' weights, so each W stays of the order of
    the sum of the group's weights; one without copies is a pair with
    d = 0 and b2 = 0.
    """
    centers = np.asarray(centers, dtype=np.complex128)
    weights = np.asarray(weights, dtype=np.complex128)
    partner = np.asarray(partner, dtype=int)
    c, w, d, b2 = [], [], [], []
    for a in np.flatnonzero(partner < 0):
        copies = np.flatnonzero(partner == a)
        if copies.size == 0:
            c.append(centers[a]), w.append(weights[a]), d.append(0j), b2.append(0j)
            continue
        total, spread = weights[a] + weights[copies].sum(), weights[copies].sum()
        for o in copies:
            share = weights[o] / spread if spread != 0 else 1.0 / copies.size
            c.append(centers[a]), w.append(total * share), d.append(centers[o] - centers[a]), b2.append(weights[o])
    if 2 * len(c) > MAX_CENTERS:
        return None
    return tuple(np.array(v, dtype=np.complex128) for v in (c, w, d, b2))
