"""
A local deformation and its region of interest
==============================================

:class:`fpiwarp.LocalDeformation` bends the picture inside a quad (the
region of interest) while the two constrained edges move rigidly, each by
its own similarity, and everything beyond them follows that similarity:
the paper's local operators (section 4). Here the left edge stays put and
the right edge is lifted and turned, so the left of the picture is not
touched, the right part moves as a whole, and the band between the two
edges' lines bends.

By default the operator is continuous over the picture: the spline is
fitted on the constrained edges extended along their lines to the
picture's border (``extent=(w, h)``), so nothing tears along those lines
above and below the ROI. The paper's construction (``construction="paper"``,
the spline fitted on the ROI alone) is shown below it: its band beyond
the ROI's free edges does not meet the similarities along the lines, and
the picture is cut there (see the coin and the bottom border).
"""

from importlib import resources

import matplotlib.pyplot as plt
import numpy as np

import fpiwarp
import fpiwarp.metrics

with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    image = fpiwarp.read_image(path)
image = image[::2, ::2]  # 320 x 240: quick to build
h, w = image.shape[:2]

# %%
# The ROI spans the middle third of the picture. Edge 3 (point 3 to 0, the
# left side) and edge 1 (point 1 to 2, the right side) are constrained.
src = np.array([[0.35 * w, 0.2 * h], [0.65 * w, 0.2 * h], [0.65 * w, 0.8 * h], [0.35 * w, 0.8 * h]])
dst = src.copy()
dst[1] += [0.02 * w, -0.12 * h]
dst[2] += [0.08 * w, -0.10 * h]
f = fpiwarp.LocalDeformation(src, dst, edges=(3, 1), extent=(w, h))
out = fpiwarp.warp_image(image, f, mode="edge")
paper = fpiwarp.LocalDeformation(src, dst, edges=(3, 1), construction="paper")
out_paper = fpiwarp.warp_image(image, paper, mode="edge")

# %%
# Away from the ROI the map is a similarity: conformal, K = 1.
k = fpiwarp.metrics.conformal_distortion(f, [[0.1 * w, 0.5 * h], [0.9 * w, 0.5 * h], [0.5 * w, 0.5 * h]])
print("K left of the ROI, right of it, inside it:", np.round(k, 3))

fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
axes[0].imshow(image)
axes[0].fill(*src.T, facecolor="none", edgecolor="tab:orange", lw=2)
axes[0].set_title("source and ROI")
axes[1].imshow(out)
axes[1].fill(*dst.T, facecolor="none", edgecolor="tab:orange", lw=2)
axes[1].set_title("LocalDeformation, edges (3, 1): continuous")
axes[2].imshow(out_paper)
axes[2].fill(*dst.T, facecolor="none", edgecolor="tab:orange", lw=2)
axes[2].set_title('construction="paper": torn along the lines')
for ax in axes:
    ax.set_axis_off()
fig.tight_layout()
plt.show()
