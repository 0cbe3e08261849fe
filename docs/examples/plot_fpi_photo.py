"""
The FPI on a photo, with its distortion K
=========================================

Move the four corners of the sample picture and warp it with the
4-point interpolant. The map sends each source corner exactly to its
target, and its conformal distortion *K* is one number, the same at every
pixel: :attr:`fpiwarp.FPI.K`.
"""

from importlib import resources

import matplotlib.pyplot as plt
import numpy as np

import fpiwarp
import fpiwarp.metrics

with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    image, info = fpiwarp.read_image(path, with_info=True)
h, w = image.shape[:2]

# %%
# Four source points (the corners, ``x`` = column, ``y`` = row) and where
# they should go.
src = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
dst = np.array([[0.12 * w, 0.10 * h], [0.95 * w, 0.02 * h], [0.85 * w, 0.97 * h], [0.02 * w, 0.85 * h]])
f = fpiwarp.FPI(src, dst)
print(f"K = {f.K:.3f}")
print("corners land on their targets:", np.allclose(f(src), dst))

# %%
# Warp: each output pixel samples the source at the exact inverse.
out = fpiwarp.warp_image(image, f, order=1, mode="constant", cval=255)

# %%
# The distortion is the same everywhere; :mod:`fpiwarp.metrics` measures it
# on a grid of the picture.
pts = fpiwarp.metrics.grid(src, n=16)
k = fpiwarp.metrics.conformal_distortion(f, pts)
print(f"K over a 16 x 16 grid: min {k.min():.6f}, max {k.max():.6f}")

fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
axes[0].imshow(image)
axes[0].plot(*np.vstack([src, src[:1]]).T, "o-", color="tab:orange")
axes[0].set_title("source")
axes[1].imshow(out)
axes[1].plot(*np.vstack([dst, dst[:1]]).T, "o-", color="tab:orange")
axes[1].set_title(f"FPI warp, K = {f.K:.3f}")
for ax in axes:
    ax.set_axis_off()
fig.tight_layout()
plt.show()
