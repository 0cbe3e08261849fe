"""
Registration by gradient descent on the corners (PyTorch)
=========================================================

A photo warped by an unknown 4-point map is registered back: starting from
target corners up to 10% of the image size off, gradient descent on the
pixel difference moves them until they sit on the true ones, to well under
a tenth of a pixel. :mod:`fpiwarp.torch` makes the warp differentiable in
the corners, and its distortion *K* too: a penalty keeps *K* under a bound
(zero below it, so it does not pull the answer away from the truth).

Coarse to fine: the images are blurred at first (a wide basin), less and
less, then compared sharp.
"""

from importlib import resources

import matplotlib.pyplot as plt
import numpy as np
import torch
import torch.nn.functional as F

import fpiwarp
import fpiwarp.torch as ft

size = 64  # a small working resolution keeps the example fast
with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    photo, _ = fpiwarp.read_image(path)
image = torch.from_numpy(photo[..., :3].astype(np.float64) / 255).permute(2, 0, 1)[None]
image = F.interpolate(image, size=(size, size), mode="area")

# %%
# The unknown map: the corners pulled in by 15% and jittered; the start is
# up to 10% of the size off in every coordinate.
s = size - 1.0
src = torch.tensor([[0, 0], [s, 0], [s, s], [0, s]], dtype=torch.float64)
g = torch.Generator().manual_seed(3)
inset = torch.tensor([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=torch.float64) * 0.15 * size
true = src + inset + (torch.rand(4, 2, generator=g, dtype=torch.float64) - 0.5) * 0.1 * size
target = ft.warp_image(image, src, true)
start = true + (torch.rand(4, 2, generator=g, dtype=torch.float64) * 2 - 1) * 0.1 * size


def blur(x, sigma):
    """Separable Gaussian blur of a (B, C, H, W) tensor."""
    if sigma < 0.05:
        return x
    r = max(1, int(3 * sigma))
    k = torch.exp(-torch.arange(-r, r + 1, dtype=x.dtype) ** 2 / (2 * sigma * sigma))
    k = k / k.sum()
    c = x.shape[1]
    x = F.conv2d(F.pad(x, (r, r, 0, 0), mode="replicate"), k.view(1, 1, 1, -1).expand(c, 1, 1, -1), groups=c)
    return F.conv2d(F.pad(x, (0, 0, r, r), mode="replicate"), k.view(1, 1, -1, 1).expand(c, 1, -1, 1), groups=c)


# %%
# :class:`fpiwarp.torch.FPIWarp` holds the target corners as its parameter.
layer = ft.FPIWarp(src)
with torch.no_grad():
    layer.dst.copy_(start)
k_max = 2.0
opt = torch.optim.Adam(layer.parameters(), lr=0.02 * size)
sched = torch.optim.lr_scheduler.ExponentialLR(opt, 0.5 ** (1 / 60))
errors = []
for step in range(300):
    sigma = 0.06 * size * max(0.0, 1 - step / 150)
    loss = ((blur(layer(image), sigma) - blur(target, sigma)) ** 2).mean()
    loss = loss + torch.relu(layer.distortion() - k_max) ** 2
    opt.zero_grad()
    loss.backward()
    opt.step()
    sched.step()
    errors.append(float((layer.dst.detach() - true).norm(dim=1).max()))
print(f"start: {errors[0]:.2f} px off; after {len(errors)} steps: {errors[-1]:.2e} px; "
      f"K = {float(layer.distortion().detach()):.4f} (true {float(ft.distortion(src, true)):.4f})")
assert errors[-1] < 0.1

# %%
# The target, the start and the result, and the largest corner error per step.
fig, axes = plt.subplots(1, 4, figsize=(12, 3.2))
with torch.no_grad():
    pictures = [target, ft.warp_image(image, src, start), layer(image)]
for ax, pic, title in zip(axes, pictures, ["target", "start", "registered"]):
    ax.imshow(pic[0].permute(1, 2, 0).clamp(0, 1).numpy())
    ax.plot(*true[[0, 1, 2, 3, 0]].T.numpy(), "w--", lw=1)
    ax.set_title(title)
    ax.axis("off")
axes[3].semilogy(errors)
axes[3].set_xlabel("step")
axes[3].set_ylabel("largest corner error (px)")
fig.tight_layout()
plt.show()
