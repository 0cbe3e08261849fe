"""
Mapping points and meshes
=========================

A map is a function of points: ``f(points)`` takes any ``(..., 2)`` array
of ``(x, y)`` and returns the same shape, in float64 on the host.
:func:`fpiwarp.map_points` does the same on any backend (per vertex on a
GPU). Mapping a mesh is mapping its vertices: the triangles keep their
indices. This is also the paper's way to warp an image on a GPU: move a
fine mesh by the forward map and let the rasterizer texture it.
"""

import matplotlib.pyplot as plt
import matplotlib.tri as mtri
import numpy as np

import fpiwarp

src = [[0, 0], [200, 0], [200, 150], [0, 150]]
dst = [[20, 10], [190, -10], [230, 160], [-10, 140]]
f = fpiwarp.FPI(src, dst)

# %%
# Points: any leading shape. The inverse takes them back exactly.
pts = np.array([[[100.0, 75.0], [0.0, 0.0]], [[200.0, 150.0], [50.0, 120.0]]])  # shape (2, 2, 2)
moved = f(pts)
print(moved.shape, np.round(moved[0], 3).tolist())
print("round trip:", np.allclose(f.inverse(moved), pts))

# %%
# The same on a backend: numpy is the float64 reference; "opencl", "warp"
# and "gl" give float32 precision (see the backend guide).
print("backends here:", fpiwarp.available_backends())
print(np.round(fpiwarp.map_points(f, pts, backend="numpy")[0], 3).tolist())

# %%
# A triangulated grid of the source quad, moved by the map. The Jacobian
# gives the local area change of each vertex (``f.jacobian`` is
# (..., 2, 2), ``J[i, j] = d f_i / d x_j``).
xs, ys = np.meshgrid(np.linspace(0, 200, 21), np.linspace(0, 150, 16))
verts = np.stack([xs.ravel(), ys.ravel()], axis=-1)
tri = mtri.Triangulation(verts[:, 0], verts[:, 1])
warped = f(verts)
area = np.linalg.det(f.jacobian(verts))

fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
axes[0].triplot(mtri.Triangulation(verts[:, 0], verts[:, 1], tri.triangles), lw=0.6)
axes[0].set_title("source mesh")
shade = axes[1].tripcolor(mtri.Triangulation(warped[:, 0], warped[:, 1], tri.triangles), area, shading="gouraud")
axes[1].triplot(mtri.Triangulation(warped[:, 0], warped[:, 1], tri.triangles), lw=0.4, color="w")
axes[1].set_title("moved by the FPI, colored by area change")
fig.colorbar(shade, ax=axes[1], shrink=0.8)
for ax in axes:
    ax.set_aspect("equal")
    ax.invert_yaxis()
fig.tight_layout()
plt.show()
