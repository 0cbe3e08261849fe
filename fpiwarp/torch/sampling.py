"""Sampling an image at differentiable positions, with a deterministic backward.

The rules are fpiwarp's (:mod:`fpiwarp.block` sampling rules, numpy
reference ``fpiwarp.warp_image(..., backend="numpy")``): order 0 takes
pixel floor(x + 0.5), order 1 is bilinear, order 3 Keys' cubic convolution
(a = -0.5); border modes act on tap indices; the positions arrive already
folded by the mode (``positions.fold``), so every tap
lies within ``MARGIN`` (6) pixels of the image.

Two samplers, one contract, tested against each other and the reference:

* ``grid_sample_path`` (CPU, orders 0 and 1): PyTorch's own
  ``grid_sample``, whose CPU backward walks each image's output pixels in
  order (deterministic); ``constant`` mode samples ``image - cval`` with
  zero padding and adds cval back, ``wrap`` appends the first column and
  row. Nearest sampling receives the already rounded integer positions.
* ``GatherSample`` (CUDA, and order 3 everywhere): the image padded
  by MARGIN pixels per the mode, taps gathered from it. Its backward never
  accumulates floats atomically. The image gradient is a sum per source
  pixel of ``weight × grad_out`` over every (output pixel, tap) landing
  there; it is formed by a stable sort of the tap indices and a segmented
  sum (``segment_sum``, ``method="sort"``, the CUDA default) or, on
  CPU, ``scatter_add_``, which there is one sequential loop per image and
  channel in index order. Both add each pixel's contributions in the same
  order (tap by tap, output pixels in raster order), so they agree bit for
  bit. The padding is then folded back onto the image by a fixed sequence
  of slice additions (``unpad``), not ``index_add_``.

Gathering through the forward map instead (the FPI is a bijection) was
considered and rejected: in ``edge``/``reflect``/``wrap`` modes a border
pixel receives from every output pixel outside the source, and near the
pole's image one source pixel from unboundedly many output pixels, so the
number of terms per source pixel has no fixed bound; sorting has none of
these limits and works for any map, also those of fpiwarp objects.
"""

import torch
import torch.nn.functional as F

#: Pixels of padding per side of the gathering sampler: folded positions lie
#: within [-4, n + 3] (see positions.fold), cubic taps one pixel beyond.
MARGIN = 6


def pad_list(n, mode):
    """Source index of each padded position -MARGIN .. n + MARGIN - 1 (n: the cval slot), fpiwarp's border rule."""
    out = []
    for i in range(-MARGIN, n + MARGIN):
        if mode == "constant":
            out.append(i if 0 <= i < n else n)
        elif mode == "edge" or n == 1:
            out.append(min(max(i, 0), n - 1))
        elif mode == "wrap":
            out.append(i % n)
        else:
            m = i % (2 * (n - 1))
            out.append(2 * (n - 1) - m if m >= n else m)
    return out


def pad_index(n, mode, device):
    return torch.tensor(pad_list(n, mode), dtype=torch.int64, device=device)


def pad(image, mode, cval):
    """The (B, C, H + 2M, W + 2M) padded image of ``mode`` (cval in the margin of 'constant')."""
    b, c, h, w = image.shape
    if mode == "constant":
        image = torch.cat([image, cval.view(1, c, 1, 1).expand(b, c, h, 1)], dim=3)
        image = torch.cat([image, cval.view(1, c, 1, 1).expand(b, c, 1, w + 1)], dim=2)
    image = image.index_select(3, pad_index(w, mode, image.device))
    return image.index_select(2, pad_index(h, mode, image.device))


def unpad(grad, n, mode, dim):
    """The transpose of padding along ``dim`` (padded length n + 2M -> n), by slice additions in a fixed order."""
    index = pad_list(n, mode)
    out = grad.narrow(dim, MARGIN, n).clone()
    for pos, src in enumerate(index):
        if MARGIN <= pos < MARGIN + n or src == n:
            continue  # the interior (taken above) and the cval slot (no gradient)
        out.select(dim, src).add_(grad.select(dim, pos))
    return out


def taps(coord, order):
    """(first tap index, weights, weight derivatives) along one axis; coord float64, folded."""
    if order == 0:
        one = torch.ones_like(coord)
        return coord.long(), [one], None
    base = torch.floor(coord)
    t = coord - base
    if order == 1:
        return base.long(), [1.0 - t, t], [-torch.ones_like(t), torch.ones_like(t)]
    t2, t3 = t * t, t * t * t
    w = [-0.5 * t3 + t2 - 0.5 * t, 1.5 * t3 - 2.5 * t2 + 1.0, -1.5 * t3 + 2.0 * t2 + 0.5 * t, 0.5 * t3 - 0.5 * t2]
    d = [-1.5 * t2 + 2.0 * t - 0.5, 4.5 * t2 - 5.0 * t, -4.5 * t2 + 4.0 * t + 0.5, 1.5 * t2 - t]
    return base.long() - 1, w, d


def segment_sum(keys, values, size, method):
    """out[k] = sum of values[i] (rows) with keys[i] == k, added in the order of i; (size, C).

    Deterministic by construction: ``"sort"`` stable-sorts the keys and sums
    each run of equal keys in order (``torch.segment_reduce``, one sequential
    sum per key), then writes each key's sum once; ``"scatter"`` is CPU's
    sequential ``index_add_``. Neither adds floats atomically."""
    out = torch.zeros((size, values.shape[1]), dtype=values.dtype, device=values.device)
    if method == "scatter":
        return out.index_add_(0, keys, values)
    order = torch.argsort(keys, stable=True)
    sorted_keys = keys[order]
    unique, counts = torch.unique_consecutive(sorted_keys, return_counts=True)
    sums = torch.segment_reduce(values[order], "sum", lengths=counts, axis=0, unsafe=True)
    out[unique] = sums
    return out


class GatherSample(torch.autograd.Function):
    """out (B, C, rows, cols) sampled from ``image`` at folded float64 positions x, y (B or 1, rows, cols)."""

    @staticmethod
    def forward(ctx, image, x, y, order, mode, cval, method):
        b, c, h, w = image.shape
        padded = pad(image, mode, cval)
        out, _ = _gather(padded, x, y, order, b, want=None)
        ctx.save_for_backward(image, x, y, cval)
        ctx.order, ctx.mode, ctx.method = order, mode, method
        return out

    @staticmethod
    def backward(ctx, grad_out):
        image, x, y, cval = ctx.saved_tensors
        b, c, h, w = image.shape
        order, mode = ctx.order, ctx.mode
        grad_image = grad_x = grad_y = None
        need_image, need_x, need_y = ctx.needs_input_grad[:3]
        grad_out = grad_out.contiguous()
        if need_image:
            grad_image = _image_grad(grad_out, x, y, order, mode, ctx.method, (b, c, h, w))
        if (need_x or need_y) and order != 0:
            padded = pad(image, mode, cval)
            _, (gx, gy) = _gather(padded, x, y, order, b, want=grad_out)
            grad_x = gx if need_x else None
            grad_y = gy if need_y else None
        return grad_image, grad_x, grad_y, None, None, None, None


def _tap_layout(x, y, order, wp, batch):
    """Flat padded index of each pixel's first tap (batch, N), and the weights per axis."""
    bx, wx, dx = taps(x, order)
    by, wy, dy = taps(y, order)
    first = ((by + MARGIN) * wp + (bx + MARGIN)).reshape(x.shape[0], -1)
    if first.shape[0] != batch:
        first = first.expand(batch, -1)
    return first, (wx, dx), (wy, dy)


def _flat(t, batch, dtype):
    t = t.reshape(t.shape[0], 1, -1).to(dtype)
    return t if t.shape[0] == batch else t.expand(batch, 1, -1)


def _gather(padded, x, y, order, batch, want):
    """Forward values, or with ``want`` = grad_out the position gradients."""
    _, c, hp, wp = padded.shape
    dtype = padded.dtype
    flat = padded.reshape(batch, c, hp * wp)
    first, (wx, dx), (wy, dy) = _tap_layout(x, y, order, wp, batch)
    n = first.shape[1]
    wx = [_flat(v, batch, dtype) for v in wx]
    wy = [_flat(v, batch, dtype) for v in wy]
    out = torch.zeros((batch, c, n), dtype=dtype, device=padded.device)
    if want is not None:
        g = want.reshape(batch, c, n)
        dx = [_flat(v, batch, dtype) for v in dx]
        dy = [_flat(v, batch, dtype) for v in dy]
        gx = torch.zeros((batch, 1, n), dtype=dtype, device=padded.device)
        gy = torch.zeros_like(gx)
    for j in range(len(wy)):
        for i in range(len(wx)):
            index = (first + (j * wp + i))[:, None, :].expand(batch, c, n)
            vals = torch.gather(flat, 2, index)
            if want is None:
                out += (wy[j] * wx[i]) * vals
            else:
                s = (g * vals).sum(1, keepdim=True)
                gx += (wy[j] * dx[i]) * s
                gy += (dy[j] * wx[i]) * s
    if want is None:
        return out.reshape(batch, c, *x.shape[1:]), None
    shape = x.shape
    gx, gy = gx.reshape(batch, *shape[1:]), gy.reshape(batch, *shape[1:])
    if shape[0] != batch:  # positions shared by the batch: their gradient is the sum over it
        gx, gy = gx.sum(0, keepdim=True), gy.sum(0, keepdim=True)
    return None, (gx.to(x.dtype), gy.to(y.dtype))


def _image_grad(grad_out, x, y, order, mode, method, shape):
    b, c, h, w = shape
    hp, wp = h + 2 * MARGIN, w + 2 * MARGIN
    dtype = grad_out.dtype
    first, (wx, _), (wy, _) = _tap_layout(x, y, order, wp, b)
    n = first.shape[1]
    g = grad_out.reshape(b, c, n)
    offset = (torch.arange(b, device=first.device) * (hp * wp))[:, None]
    keys, values = [], []
    for j in range(len(wy)):
        for i in range(len(wx)):
            weight = _flat(wy[j], b, dtype) * _flat(wx[i], b, dtype)
            keys.append((first + (j * wp + i) + offset).reshape(-1))
            values.append((weight * g).permute(0, 2, 1).reshape(-1, c))
    grad = segment_sum(torch.cat(keys), torch.cat(values), b * hp * wp, method)
    grad = grad.reshape(b, hp, wp, c).permute(0, 3, 1, 2)
    grad = unpad(grad, w, mode, 3)
    return unpad(grad, h, mode, 2).contiguous()


def grid_sample_path(image, x, y, order, mode, cval):
    """Orders 0 and 1 through ``torch.nn.functional.grid_sample`` (CPU: a deterministic backward)."""
    b, c, h, w = image.shape
    if mode == "wrap":
        image = torch.cat([image, image[..., :1]], dim=3)
        image = torch.cat([image, image[..., :1, :]], dim=2)
    shift = mode == "constant" and bool((cval != 0).any())
    if shift:
        image = image - cval.view(1, c, 1, 1)
    hi, wi = image.shape[2:]
    scale = torch.tensor([2.0 / wi, 2.0 / hi], dtype=x.dtype, device=x.device)
    grid = torch.stack([x, y], dim=-1).mul_(scale).add_(scale / 2 - 1).to(image.dtype)
    if grid.shape[0] != b:
        grid = grid.expand(b, -1, -1, -1)
    out = F.grid_sample(image, grid, mode="nearest" if order == 0 else "bilinear",
                        padding_mode="zeros" if mode == "constant" else "border", align_corners=False)
    return out + cval.view(1, c, 1, 1) if shift else out
