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


def tps_pairs_core(p, rows, n, dtype, centers_row):
    """The paired TPS core's sum over the ``n`` center rows (n / 2 pairs)
    at complex p, and its Wirtinger derivatives: (val, dz, dzb) without
    the R-linear part. ``centers_row``: the first center row."""
    val = np.zeros_like(p)
    dz = np.zeros_like(p)
    dzb = np.zeros_like(p)
    for j in range(0, n, 2):
        r1, r2 = rows[centers_row + j], rows[centers_row + j + 1]
        c, w = complex(r1[0], r1[1]), complex(r1[2], r1[3])
        d, b2 = complex(r2[0], r2[1]), complex(r2[2], r2[3])
        q = p - c
        q2 = q - d
        a = (q.real**2 + q.imag**2).astype(dtype)
        b = (q2.real**2 + q2.imag**2).astype(dtype)
        dd = dtype(d.real) * dtype(d.real) + dtype(d.imag) * dtype(d.imag)
        e = (dd - 2 * (q.real * dtype(d.real) + q.imag * dtype(d.imag))).astype(dtype)
        near_a = a <= b
        s, m = np.where(near_a, a, b), np.where(near_a, b, a)
        ls, lm, big_l = pair_logs(e, s, m, dtype)
        la = np.where(near_a, ls, lm)
        val = val + w * (0.5 * a * la) + b2 * (0.5 * (e * lm + s * big_l))
        g1, gn = 0.5 * (la + 1), 0.5 * (lm + 1)
        qn = np.where(near_a, q, q2)
        dz = dz + w * (g1 * np.conj(q)) + b2 * (0.5 * big_l * np.conj(qn) - gn * np.conj(d))
        dzb = dzb + w * (g1 * q) + b2 * (0.5 * big_l * qn - gn * d)
    return val, dz, dzb
