"""Registration by gradient descent on the corners (the gallery example, small): < 0.1 px."""

from importlib import resources

import numpy as np
from support.torch_cases import require_torch

import fpiwarp

torch = require_torch()
import torch.nn.functional as F  # noqa: E402

import fpiwarp.torch as ft  # noqa: E402


def blur(x, sigma):
    """Separable Gaussian blur (coarse to fine keeps far starts in the basin)."""
    if sigma < 0.05:
        return x
    r = max(1, int(3 * sigma))
    k = torch.exp(-torch.arange(-r, r + 1, dtype=x.dtype) ** 2 / (2 * sigma * sigma))
    k = (k / k.sum()).to(x.device)
    c = x.shape[1]
    x = F.conv2d(F.pad(x, (r, r, 0, 0), mode="replicate"), k.view(1, 1, 1, -1).expand(c, 1, 1, -1), groups=c)
    return F.conv2d(F.pad(x, (0, 0, r, r), mode="replicate"), k.view(1, 1, -1, 1).expand(c, 1, -1, 1), groups=c)


def register(size, seed, steps=300):
    """Recover the target corners of a warped photo from a start up to 10% of the size off; (error px, K)."""
    with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
        photo, _ = fpiwarp.read_image(path)
    img = torch.from_numpy(photo[..., :3].astype(np.float64) / 255).permute(2, 0, 1)[None]
    img = F.interpolate(img, size=(size, size), mode="area")
    s = size - 1.0
    src = torch.tensor([[0, 0], [s, 0], [s, s], [0, s]], dtype=torch.float64)
    g = torch.Generator().manual_seed(seed)
    inset = torch.tensor([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=torch.float64) * 0.15 * size
    true = src + inset + (torch.rand(4, 2, generator=g, dtype=torch.float64) - 0.5) * 0.1 * size
    target = ft.warp_image(img, src, true)
    layer = ft.FPIWarp(src)
    with torch.no_grad():
        layer.dst.copy_(true + (torch.rand(4, 2, generator=g, dtype=torch.float64) * 2 - 1) * 0.1 * size)
    k_max = 2.0  # a bound, not a pull towards K = 1: the penalty is zero below it
    opt = torch.optim.Adam(layer.parameters(), lr=0.02 * size)
    sched = torch.optim.lr_scheduler.ExponentialLR(opt, 0.5 ** (1 / 60))
    for step in range(steps):
        sigma = 0.06 * size * max(0.0, 1 - step / 150)
        loss = ((blur(layer(img), sigma) - blur(target, sigma)) ** 2).mean()
        loss = loss + torch.relu(layer.distortion() - k_max) ** 2
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
    err = float((layer.dst.detach() - true).norm(dim=1).max())
    return err, float(layer.distortion().detach())


def test_registration_recovers_the_corners_to_a_tenth_of_a_pixel():
    err, k = register(64, seed=3, steps=200)
    assert err < 0.1, err
    assert 1.0 <= k < 2.0
