"""Quads and constrained deformations shared by the constrained-FPI and
local-deformation tests."""

import numpy as np
from hypothesis import reject
from hypothesis import strategies as st

from fpiwarp.maps.quad import check_quad, signed_area
from fpiwarp.metrics import grid
from support.strategies import quads

RECT = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])


def cplx(p):
    p = np.asarray(p, dtype=np.float64)
    return p[..., 0] + 1j * p[..., 1]


def xy(z):
    z = np.asarray(z)
    return np.stack([z.real, z.imag], axis=-1)


def size_of(pts):
    return float(np.max(np.linalg.norm(pts - pts.mean(axis=0), axis=1)))


def rotate_edge(src, k, degrees, scale=1.0, shift=0j):
    """dst = src with edge k turned about its midpoint (a similarity of that edge)."""
    z = cplx(src)
    i, j = k, (k + 1) % 4
    mid = 0.5 * (z[i] + z[j])
    a = scale * np.exp(1j * np.deg2rad(degrees))
    w = z.copy()
    w[[i, j]] = mid + a * (z[[i, j]] - mid) + shift
    return xy(w)


def is_convex(q):
    z = cplx(q)
    e = np.roll(z, -1) - z
    turn = (np.conj(e) * np.roll(e, -1)).imag
    return bool(np.all(turn > 0) or np.all(turn < 0))


@st.composite
def deformations(draw, kind=None, convex=False):
    """(src, dst, edges): a quad (any simple one, or convex ones only), a
    global similarity of it, and a moderate extra similarity of the second
    constrained edge (opposite edges) or a moved free corner (adjacent
    edges)."""
    src = draw(quads(min_scale=1.0, max_scale=1e3))
    if convex and not is_convex(src):
        reject()
    kind = kind or draw(st.sampled_from(["opposite", "adjacent"]))
    size = size_of(src)
    z = cplx(src)
    g = draw(st.floats(0.5, 2.0)) * np.exp(1j * draw(st.floats(-np.pi, np.pi)))
    gb = complex(draw(st.floats(-1, 1)), draw(st.floats(-1, 1))) * size
    if kind == "opposite":
        first = draw(st.integers(0, 1))
        edges = (first, first + 2)
        k = first + 2
        theta = np.deg2rad(draw(st.floats(-20, 20)))
        s = draw(st.floats(0.85, 1.15))
        t = complex(draw(st.floats(-0.1, 0.1)), draw(st.floats(-0.1, 0.1))) * size
        w = z.copy()
        mid = 0.5 * (z[k] + z[(k + 1) % 4])
        idx = [k, (k + 1) % 4]
        w[idx] = mid + s * np.exp(1j * theta) * (z[idx] - mid) + t
    else:
        first = draw(st.integers(0, 3))
        edges = (first, (first + 1) % 4)
        free = (first + 3) % 4
        w = z.copy()
        w[free] += complex(draw(st.floats(-0.2, 0.2)), draw(st.floats(-0.2, 0.2))) * size
    w = g * w + gb
    dst = xy(w)
    try:
        wz = check_quad(dst)
    except ValueError:
        reject()
    if np.sign(signed_area(wz)) != np.sign(signed_area(z)) or abs(signed_area(wz)) < 0.05 * (
        abs(g) * size
    ) ** 2:
        reject()
    if convex and not is_convex(dst):
        reject()
    if draw(st.booleans()):
        edges = edges[::-1]
    return src, dst, edges


def edge_points(q, k, n=201):
    t = np.linspace(0, 1, n)[:, None]
    return q[k] + t * (q[(k + 1) % 4] - q[k])


def similarity(src, dst, k):
    z, w = cplx(src), cplx(dst)
    a = (w[(k + 1) % 4] - w[k]) / (z[(k + 1) % 4] - z[k])
    return lambda p: xy(w[k] + a * (cplx(p) - z[k]))


def interior(src, n=25, margin=0.02):
    """An n × n grid over src shrunk by ``margin`` towards its centroid, (n*n, 2)."""
    return grid(shrink(src, margin), n).reshape(-1, 2)


def shrink(src, margin):
    c = src.mean(axis=0)
    return c + (1 - margin) * (src - c)


# --- corners, edges, exactness ------------------------------------------------


@st.composite
def strong_deformations(draw):
    """A quad with one constrained edge turned by up to 120° and scaled
    0.5..2 (opposite edges), or its free corner moved far (adjacent)."""
    src = draw(quads(min_scale=1.0, max_scale=1e3))
    z, size = cplx(src), size_of(src)
    if draw(st.booleans()):
        first = draw(st.integers(0, 1))
        dst = rotate_edge(src, first + 2, draw(st.floats(-120, 120)), draw(st.floats(0.5, 2.0)))
        edges = (first, first + 2)
    else:
        first = draw(st.integers(0, 3))
        w = z.copy()
        w[(first + 3) % 4] += complex(draw(st.floats(-0.8, 0.8)), draw(st.floats(-0.8, 0.8))) * size
        dst, edges = xy(w), (first, (first + 1) % 4)
    return src, dst, edges
