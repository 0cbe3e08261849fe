"""Overlays of the preview renderer: the handles (target points) and the
outline (the images of the source quad's edges), drawn as flat-coloured
triangles whose corners are computed on the host in window pixels, so
their sizes do not change with the zoom (glsl/viewer/overlay.vert, overlay.frag).
"""

import moderngl
import numpy as np

from .. import glsl
from ..backends.gl import ProgramKey

#: Overlay colours (RGBA, 0..1).
HANDLE_COLOR = (1.0, 0.85, 0.1, 1.0)
ACTIVE_COLOR = (1.0, 0.3, 0.2, 1.0)
EDGE_COLOR = (0.2, 0.9, 1.0, 0.9)
CONSTRAINED_COLOR = (1.0, 0.55, 0.0, 1.0)
RING_COLOR = (0.0, 0.0, 0.0, 0.8)
#: The overlay program.
OVERLAY_PROGRAM = ProgramKey(glsl.OVERLAY_VERT, glsl.OVERLAY_FRAG, samples=False)


def edge_curves(step, samples=48):
    """The images of the four edges of the source quad of a map (edge k
    joins corner k and k + 1): (4, samples, 2) output points, or None for
    a map without a source quad."""
    src = getattr(step, "src", None)
    if src is None:
        return None
    src = np.asarray(src, dtype=np.float64).reshape(4, 2)
    t = np.linspace(0.0, 1.0, samples)[:, None]
    pts = np.stack([src[k] + t * (src[(k + 1) % 4] - src[k]) for k in range(4)])
    return step(pts)


def polyline(points, width, color):
    """Triangles (N, 6: x, y, r, g, b, a) of a polyline ``width`` pixels
    wide; segments with non-finite ends (through the pole) are left out."""
    a, b = points[:-1], points[1:]
    d = b - a
    n = np.hypot(d[:, 0], d[:, 1])
    ok = np.isfinite(n) & (n > 0) & np.all(np.isfinite(a) & np.isfinite(b), axis=1)
    a, b, d, n = a[ok], b[ok], d[ok], n[ok]
    if not len(a):
        return np.empty((0, 6))
    off = 0.5 * width * np.stack([-d[:, 1], d[:, 0]], 1) / n[:, None]
    quad = np.stack([a - off, a + off, b + off, a - off, b + off, b - off], 1).reshape(-1, 2)
    return np.hstack([quad, np.tile(color, (len(quad), 1))])


def disc(center, radius, color, sides=20):
    """Triangles of a filled disc (a regular polygon) in window pixels."""
    if not np.all(np.isfinite(center)):
        return np.empty((0, 6))
    ang = np.linspace(0.0, 2 * np.pi, sides + 1)
    ring = center + radius * np.stack([np.cos(ang), np.sin(ang)], 1)
    tri = np.stack([np.broadcast_to(center, ring[:-1].shape), ring[:-1], ring[1:]], 1).reshape(-1, 2)
    return np.hstack([tri, np.tile(color, (len(tri), 1))])


def outline_triangles(curves, constrained, to_window, width):
    """Triangles of the outline: ``curves`` (4, n, 2) output points, edges
    whose index is in ``constrained`` in CONSTRAINED_COLOR; ``to_window``
    maps output points to window pixels."""
    return [polyline(to_window(curve), width, CONSTRAINED_COLOR if k in constrained else EDGE_COLOR)
            for k, curve in enumerate(curves)]


def handle_triangles(points, to_window, radius, active=None, invalid=False):
    """Triangles of the handles at output ``points``, each ringed; the
    ``active`` one (or all when ``invalid``) in ACTIVE_COLOR."""
    tris = []
    for i, p in enumerate(to_window(points)):
        color = ACTIVE_COLOR if (invalid or i == active) else HANDLE_COLOR
        tris.append(disc(p, radius + 1.5, RING_COLOR))
        tris.append(disc(p, radius, color))
    return tris


class OverlayLayer:
    """The vertex buffer of the overlays, grown as needed, and their draw."""

    def __init__(self, ctx, programs):
        self.ctx = ctx
        self.programs = programs  # a GLWarper's ProgramCache
        self._vbo = None
        self._vao = None

    def draw(self, tris, viewport):
        """Blend triangles (lists of (N, 6) window-pixel arrays) over the
        bound framebuffer inside ``viewport`` (x, y, w, h)."""
        tris = [t for t in tris if len(t)]
        if not tris:
            return
        vx, vy, vw, vh = viewport
        data = np.concatenate(tris).astype(np.float32)
        data[:, 0] = (data[:, 0] - vx) / vw * 2.0 - 1.0
        data[:, 1] = (data[:, 1] - vy) / vh * 2.0 - 1.0
        data[~np.isfinite(data)] = 0.0
        prog = self.programs.get(OVERLAY_PROGRAM)
        if self._vbo is None or self._vbo.size < data.nbytes:
            self.release()
            self._vbo = self.ctx.buffer(reserve=max(data.nbytes, 1 << 16), dynamic=True)
            self._vao = self.ctx.vertex_array(prog, [(self._vbo, "2f 4f", "ov_position", "ov_color")])
        self._vbo.write(data.tobytes())
        ctx = self.ctx
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        try:
            self._vao.render(moderngl.TRIANGLES, vertices=len(data))
        finally:
            ctx.disable(moderngl.BLEND)

    def release(self):
        for obj in (self._vao, self._vbo):
            if obj is not None:
                obj.release()
        self._vao = self._vbo = None
