"""The mesh path: a triangulated grid of the source moved per vertex by
the forward map (glsl/backend/mesh.vert) and rasterized, the paper's own way.

Shared by the backend's :meth:`GLWarper.warp_image_mesh` and the preview
renderer: the default grid, the check of a caller's mesh, and the draw
with the culling and clipping that drop triangles through the pole.
"""

import moderngl
import numpy as np

GL_CLIP_DISTANCE0 = 0x3000


def grid_mesh(shape, grid_step, vertices, triangles):
    """Source-space vertices and positively oriented triangles for the mesh
    path: the caller's (checked) or a grid over an image of ``shape`` with
    ``grid_step`` pixels between vertices."""
    if (vertices is None) != (triangles is None):
        raise ValueError("pass both vertices and triangles, or neither (default grid)")
    if vertices is None:
        h, w = shape[:2]
        if not grid_step > 0:
            raise ValueError(f"grid_step must be positive, got {grid_step!r}")
        xs = np.append(np.arange(-0.5, w - 0.5, grid_step), w - 0.5)
        ys = np.append(np.arange(-0.5, h - 0.5, grid_step), h - 0.5)
        gx, gy = np.meshgrid(xs, ys)
        verts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        nx = len(xs)
        i = (np.arange(len(ys) - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
        tris = np.concatenate([np.stack([i, i + 1, i + nx + 1], 1), np.stack([i, i + nx + 1, i + nx], 1)])
        return verts, tris
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(triangles)
    if verts.ndim != 2 or verts.shape[1] != 2 or not np.all(np.isfinite(verts)):
        raise ValueError(f"vertices must be finite (N, 2) source positions, got shape {verts.shape}")
    if tris.ndim != 2 or tris.shape[1] != 3 or not np.issubdtype(tris.dtype, np.integer):
        raise ValueError(f"triangles must be (M, 3) integer indices, got {tris.shape} {tris.dtype}")
    if tris.size and (tris.min() < 0 or tris.max() >= len(verts)):
        raise ValueError(f"triangle indices must lie in [0, {len(verts)})")
    a, b, cc = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    area = (b[:, 0] - a[:, 0]) * (cc[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (cc[:, 0] - a[:, 0])
    tris = np.where((area < 0)[:, None], tris[:, [0, 2, 1]], tris)[area != 0]
    return verts, tris


class MeshBuffers:
    """A mesh's vertex and index buffers in a context, and one vertex
    array per program that draws it (attribute ``fpw_vertex``)."""

    def __init__(self, ctx, vertices, triangles):
        self.ctx = ctx
        self.vbo = ctx.buffer(np.asarray(vertices).astype(np.float32).tobytes())
        self.ibo = ctx.buffer(np.asarray(triangles).astype(np.int32).tobytes())
        self._vaos = {}

    def vao(self, prog):
        """The vertex array that draws the mesh with ``prog``."""
        vao = self._vaos.get(id(prog))
        if vao is None:
            vao = self._vaos[id(prog)] = self.ctx.vertex_array(prog, [(self.vbo, "2f", "fpw_vertex")],
                                                               index_buffer=self.ibo)
        return vao

    def release(self):
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        self.vbo.release()
        self.ibo.release()


def draw_culled_mesh(ctx, vao, front_face="ccw"):
    """Draw a moved mesh with culling and clipping, then restore the state
    (culling and clip distance 0 disabled, front face counter-clockwise).

    Maps are orientation preserving and the mesh's triangles have positive
    area in (x, y): with view steps of equal sign they are counter-clockwise
    in window coordinates (``front_face="ccw"``; a y-up view mirrors them:
    "cw"). Flipped triangles straddle the pole (or fold): cull them.
    Vertices sent to the pole clip their triangles away (clip distance 0,
    see glsl/backend/mesh.vert).
    """
    ctx.front_face = front_face
    ctx.cull_face = "back"
    ctx.enable(moderngl.CULL_FACE)
    ctx.enable_direct(GL_CLIP_DISTANCE0)
    try:
        vao.render(moderngl.TRIANGLES)
    finally:
        ctx.disable_direct(GL_CLIP_DISTANCE0)
        ctx.disable(moderngl.CULL_FACE)
        ctx.front_face = "ccw"
