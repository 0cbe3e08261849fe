"""
Augmentation: image, mask, keypoints and boxes that agree
=========================================================

:class:`fpiwarp.augment.RandomFPI` warps a picture with a random FPI whose
conformal distortion stays within a budget, and carries its label mask
(order 0, labels kept), keypoints (the exact forward map) and boxes (the
exact bounds of each box's bent outline) along.
"""

from importlib import resources

import matplotlib.pyplot as plt
import numpy as np

import fpiwarp
from fpiwarp.augment import RandomFPI

with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    image = fpiwarp.read_image(path)
h, w = image.shape[:2]

# %%
# A label mask (two int32 regions), keypoints on a grid and two boxes.
yy, xx = np.mgrid[:h, :w]
mask = np.zeros((h, w), np.int32)
mask[(xx - 0.35 * w) ** 2 + (yy - 0.5 * h) ** 2 < (0.2 * h) ** 2] = 1000
mask[(xx > 0.6 * w) & (xx < 0.85 * w) & (yy > 0.2 * h) & (yy < 0.6 * h)] = -7
keypoints = np.stack(np.meshgrid(np.linspace(0.1 * w, 0.9 * w, 5), np.linspace(0.1 * h, 0.9 * h, 4)), -1).reshape(-1, 2)
boxes = np.array([[0.15 * w, 0.3 * h, 0.55 * w, 0.7 * h], [0.6 * w, 0.2 * h, 0.85 * w, 0.6 * h]])

aug = RandomFPI(max_distortion=1.3, max_corner_shift=0.15, seed=4, backend="numpy")
out = aug(image=image, mask=mask, keypoints=keypoints, boxes=boxes)
print(f"K = {out['transform'].K:.3f} (budget 1.3), mask labels {sorted(np.unique(out['mask']).tolist())}")

# %%
# The warped picture with its mask, keypoints and boxes. The bent outline of
# each box (dashed) touches its exact bounds.
fig, axes = plt.subplots(1, 2, figsize=(10, 4))
for ax, img, msk, pts, bxs, title in ((axes[0], image, mask, keypoints, boxes, "original"),
                                      (axes[1], out["image"], out["mask"], out["keypoints"], out["boxes"],
                                       "RandomFPI")):
    ax.imshow(img)
    ax.contour(msk, levels=[-3, 500], colors=["yellow", "cyan"], linewidths=1)
    ax.plot(pts[:, 0], pts[:, 1], "r+", ms=8)
    for x0, y0, x1, y1 in bxs:
        ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="lime", lw=1.5))
    ax.set_title(title)
    ax.axis("off")
t = np.linspace(0, 1, 200)
for x0, y0, x1, y1 in boxes:
    outline = np.concatenate([np.stack([x0 + (x1 - x0) * t, np.full_like(t, y0)], 1),
                              np.stack([np.full_like(t, x1), y0 + (y1 - y0) * t], 1),
                              np.stack([x1 - (x1 - x0) * t, np.full_like(t, y1)], 1),
                              np.stack([np.full_like(t, x0), y1 - (y1 - y0) * t], 1)])
    bent = out["transform"](outline)
    axes[1].plot(bent[:, 0], bent[:, 1], "w--", lw=1)
plt.tight_layout()
plt.show()
