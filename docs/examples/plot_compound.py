"""
A compound deformation
======================

Maps chain with ``@`` in mathematical order: ``(g @ f)(p) == g(f(p))``.
Here an FPI first puts the picture in perspective, then a local
deformation bends a region of the result. :func:`fpiwarp.warp_image`
applies the inverses in reverse order, in one pass over the output.
"""

from importlib import resources

import matplotlib.pyplot as plt
import numpy as np

import fpiwarp

with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    image = fpiwarp.read_image(path)
image = image[::2, ::2]
h, w = image.shape[:2]

corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
first = fpiwarp.FPI(corners, [[0.1 * w, 0.05 * h], [0.9 * w, 0.12 * h], [0.95 * w, 0.9 * h], [0.05 * w, 0.95 * h]])

# %%
# The second step bends a quad around the middle of the *warped* picture:
# its left edge (edge 3) stays, its right edge (edge 1) is lifted, and the
# part of the picture right of it follows as a whole.
roi = np.array([[0.4 * w, 0.25 * h], [0.6 * w, 0.25 * h], [0.6 * w, 0.75 * h], [0.4 * w, 0.75 * h]])
bent = roi + [[0, 0], [0, -0.12 * h], [0, -0.12 * h], [0, 0]]
second = fpiwarp.LocalDeformation(roi, bent, edges=(3, 1))
both = second @ first
print(type(both).__name__, "of", len(both.steps), "steps")

fig, axes = plt.subplots(1, 3, figsize=(11, 3))
for ax, (title, f) in zip(axes, [("first: FPI", first), ("second: local", second), ("second @ first", both)]):
    ax.imshow(fpiwarp.warp_image(image, f, cval=255))
    ax.set_title(title)
    ax.set_axis_off()
axes[1].fill(*roi.T, facecolor="none", edgecolor="tab:orange")
fig.tight_layout()
plt.show()
