"""The paired TPS core of the block (``CORE_TPS_PAIRS``): the reference every
kernel mirrors (OpenCL ``fw_tps_pairs``, Warp ``tps_pairs_sum``, GLSL
``fpw_tps_pairs``).

A pair (rows in :mod:`fpiwarp.block.layout`) is a center c with the summed
weight W = b1 + b2 and a second center c + d with weight b2. Its term,
with U(r) = r² log r = ½ A log A for A = r²,

    W U(|p - c|) + b2 (U(|p - c - d|) - U(|p - c|)),

equals b1 U(|p - c|) + b2 U(|p - c - d|), but in float32 it keeps the
precision the plain sum loses when b1 ≈ -b2 are large (a point and its
offset copy δ apart: weights of order 1 / δ). The difference is formed
without cancellation, with a = |p - c|², b = |p - c - d|²:

* e = b - a = |d|² - 2 Re((p - c) conj(d)), from d directly;
* L = log(b / a) = sign(e) log1p(|e| / s), s = min(a, b): the series
  2 atanh(t) = log1p(x), t = |e| / (2 s + |e|) = x / (2 + x), to t⁷
  where 4 |e| <= s (x <= 1/4, relative error < 1e-9; the test needs no
  division), else log(max) - log(min) (then |L| > 0.22, and both logs are
  accurate to a few float32 ulps);
* log(max(a, b)) = log(s) + |L| where the series holds: one logarithm per
  pair instead of two there (away from the pair's two centers, nearly
  everywhere: |e| / s is about 2 |d| / |p - c|);
* b log b - a log a = e log(max(a, b)) + s L.

The Wirtinger derivatives come from the same pieces: with g(A) = ½ (log A + 1),
b1 g(a) conj(p - c) + b2 g(b) conj(p - c - d) = W g(a) conj(p - c) + b2 P,
where P = ½ L conj(p - c) - g(b) conj(d) if a <= b, else
½ L conj(p - c - d) - g(a) conj(d) (the form that stays finite where the
nearer center is hit exactly); d/dconj(p) alike without the conjugates.
A log of 0 is read as 0, as in the plain core (U and its derivatives
vanish at a center). With d = 0 and b2 = 0 (a center without a partner)
e = L = 0 and the term is exactly the plain one.
"""

import numpy as np

#: Where x = |e| / min(a, b) is at most this, L comes from the series.
SERIES_LIMIT = 0.25


def _log0(v):
    """log v, and 0 where v == 0 (as the plain core)."""
    return np.where(v > 0, np.log(np.where(v > 0, v, 1)), 0)


def pair_logs(e, s, m, dtype):
    """(ls, lm, L): the logs of s = min(a, b) and m = max(a, b) and
    L = log(b / a) for e = b - a (see the module docstring): one logarithm
    where the series holds (|e| <= s / 4, s > 0), two elsewhere."""
    ae = np.abs(e).astype(dtype)
    ok = (s > 0) & (ae <= SERIES_LIMIT * s)
    t = (ae / np.where(ok, 2 * s + ae, 1)).astype(dtype)
    t = np.where(ok, t, 0).astype(dtype)
    t2 = t * t
    series = (2 * t * (1 + t2 * (dtype(1 / 3) + t2 * (dtype(0.2) + t2 * dtype(1 / 7))))).astype(dtype)
    ls = _log0(s).astype(dtype)
    lm = np.where(ok, ls + series, _log0(m)).astype(dtype)
    mag = np.where(ok, series, lm - ls)
    return ls, lm, np.where(e < 0, -mag, mag).astype(dtype)


#: Points times pairs evaluated in one pass (at most; at least one pair):
#: the pairs lie along a last axis, so that for the few hundred points a
#: Newton of fpiwarp.block.coarse_choice evaluates one pass of numpy calls
#: serves every pair (a loop over the pairs made some forty calls per pair,
#: which dominated), while large point sets go a pair or a few at a time
#: with arrays that stay in the caches.
CHUNK_ELEMENTS = 1 << 13


def _weak(values, other):
    """Python complex ``values`` (held as complex128) cast as numpy casts a
    Python complex scalar beside the array ``other`` (NEP 50: to other's
    complex kind), so that the arrays of pairs compute what the scalars did."""
    return values.astype(np.result_type(other, 1j))


def _sequential_sum(terms, start):
    """start + terms[..., 0] + terms[..., 1] + ..., added in that order (as
    the loop over the pairs added them): numpy's accumulate is sequential
    (one term each: the two additions themselves)."""
    if terms[0].shape[-1] == 1:
        total = start
        for t in terms:
            total = total + t[..., 0]
        return total
    dtype = np.result_type(start, *terms)
    stacked = np.empty(terms[0].shape[:-1] + (1 + len(terms) * terms[0].shape[-1],), dtype)
    stacked[..., 0] = start
    for i, t in enumerate(terms):
        stacked[..., 1 + i::len(terms)] = t
    return np.add.accumulate(stacked, axis=-1)[..., -1]


def _pairs_group(p, c, w, d, b2, dtype, sums):
    """``sums`` (val, dz, dzb at the points p (m, 1); None: zeros) plus the
    terms of the pairs (c, w, d, b2), each (k,), added in their order."""
    q = p - _weak(c, p)
    q2 = q - _weak(d, q)
    a = (q.real**2 + q.imag**2).astype(dtype)
    b = (q2.real**2 + q2.imag**2).astype(dtype)
    dr, di = d.real.astype(dtype), d.imag.astype(dtype)
    dd = dr * dr + di * di
    e = (dd - 2 * (q.real * dr + q.imag * di)).astype(dtype)
    near_a = a <= b
    s, m = np.where(near_a, a, b), np.where(near_a, b, a)
    ls, lm, big_l = pair_logs(e, s, m, dtype)
    la = np.where(near_a, ls, lm)
    g1, gn = 0.5 * (la + 1), 0.5 * (lm + 1)
    qn = np.where(near_a, q, q2)
    terms = []
    for plain, paired in ((0.5 * a * la, 0.5 * (e * lm + s * big_l)),
                          (g1 * np.conj(q), 0.5 * big_l * np.conj(qn) - gn * np.conj(d)),
                          (g1 * q, 0.5 * big_l * qn - gn * _weak(d, gn))):
        terms.append((_weak(w, plain) * plain, _weak(b2, paired) * paired))
    if sums is None:
        sums = (np.zeros(p.shape[:-1], p.dtype),) * 3
    return tuple(_sequential_sum(t, start) for t, start in zip(terms, sums))


def tps_pairs_core(p, rows, n, dtype, centers_row):
    """The paired TPS core's sum over the ``n`` center rows (n / 2 pairs)
    at complex p, and its Wirtinger derivatives: (val, dz, dzb) without
    the R-linear part. ``centers_row``: the first center row. Each pair's
    terms are added in the pairs' order, as a loop over them would."""
    p = np.asarray(p)
    pairs = np.asarray(rows[centers_row:centers_row + n], dtype=np.float64)
    first, second = pairs[0::2], pairs[1::2]
    c, w = first[:, 0] + first[:, 1] * 1j, first[:, 2] + first[:, 3] * 1j
    d, b2 = second[:, 0] + second[:, 1] * 1j, second[:, 2] + second[:, 3] * 1j
    if len(c) == 0:
        zero = np.zeros_like(p)
        return zero, zero.copy(), zero.copy()
    flat = p.reshape(-1, 1)
    group = max(1, min(len(c), CHUNK_ELEMENTS // max(len(flat), 1)))
    sums = None
    for g in range(0, len(c), group):
        part = slice(g, g + group)
        sums = _pairs_group(flat, c[part], w[part], d[part], b2[part], dtype, sums)
    return tuple(v.reshape(p.shape) for v in sums)
