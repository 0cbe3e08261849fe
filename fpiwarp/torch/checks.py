"""Argument checks of fpiwarp.torch: one-line fpiwarp errors that name the argument."""

import math
import numbers

import torch

import fpiwarp

MODES = ("constant", "edge", "reflect", "wrap")
ORDERS = (0, 1, 3)
FLOATS = (torch.float32, torch.float64)


def image(value):
    """The image as (B, C, H, W) and whether it came without a batch axis."""
    if not isinstance(value, torch.Tensor):
        raise fpiwarp.ArgumentTypeError(f"image must be a torch.Tensor (B, C, H, W) or (C, H, W), "
                                        f"got {type(value).__name__}")
    if value.dtype not in FLOATS:
        raise fpiwarp.ArgumentTypeError(f"image must be float32 or float64, got {value.dtype} "
                                        "(convert it, e.g. image.float() / 255)")
    if value.ndim not in (3, 4):
        raise fpiwarp.ArgumentError(f"image must have shape (B, C, H, W) or (C, H, W), got {tuple(value.shape)}")
    if value.numel() == 0:
        raise fpiwarp.ArgumentError(f"image must not be empty, got shape {tuple(value.shape)}")
    return (value, False) if value.ndim == 4 else (value[None], True)


def points(value, name, device, last=(2,), what="(x, y) points"):
    """A float tensor on ``device``: tensors are taken as they are (their
    gradient kept), array-likes converted to float64."""
    if not isinstance(value, torch.Tensor):
        try:
            value = torch.as_tensor(value, dtype=torch.float64, device=device)
        except (TypeError, ValueError, RuntimeError) as exc:
            raise fpiwarp.ArgumentTypeError(f"{name} must be a tensor of {what}: {exc}") from None
    if value.dtype not in FLOATS:
        raise fpiwarp.ArgumentTypeError(f"{name} must be a float32 or float64 tensor, got {value.dtype}")
    if value.device != device:
        raise fpiwarp.DeviceMismatchError(f"{name} is on {value.device} but the image (or points) on {device}; "
                                          f"move it with {name}.to({str(device)!r})")
    if value.ndim < len(last) or tuple(value.shape[-len(last):]) != tuple(last):
        raise fpiwarp.ArgumentError(f"{name} must have shape (..., {', '.join(map(str, last))}) of {what}, "
                                    f"got {tuple(value.shape)}")
    return value


def quads(src, dst, device):
    """src, dst as (B, 4, 2) tensors of one batch size, and whether both came unbatched."""
    out = []
    for name, q in (("src", src), ("dst", dst)):
        q = points(q, name, device, last=(4, 2), what="four (x, y) corners")
        if q.ndim not in (2, 3):
            raise fpiwarp.ArgumentError(f"{name} must have shape (4, 2) or (B, 4, 2), got {tuple(q.shape)}")
        out.append(q)
    single = out[0].ndim == 2 and out[1].ndim == 2
    s, d = (q if q.ndim == 3 else q[None] for q in out)
    n = batch(s.shape[0], d.shape[0], "src", "dst")
    return s.expand(n, 4, 2), d.expand(n, 4, 2), single


def batch(a, b, name_a, name_b):
    if a != b and a != 1 and b != 1:
        raise fpiwarp.ArgumentError(f"{name_a} has a batch of {a} and {name_b} of {b}: they must match (or be 1)")
    return max(a, b)


def output_shape(value, default):
    if value is None:
        return default
    if (not isinstance(value, (tuple, list, torch.Size)) or len(value) != 2
            or not all(isinstance(v, numbers.Integral) and not isinstance(v, bool) for v in value)
            or min(value) < 1):
        raise fpiwarp.ArgumentError(f"output_shape must be two positive integers (rows, cols), got {value!r}")
    return int(value[0]), int(value[1])


def order(value):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or value not in ORDERS:
        raise fpiwarp.ArgumentError(f"order must be 0, 1 or 3, got {value!r}")
    return int(value)


def mode(value):
    if value not in MODES:
        raise fpiwarp.ArgumentError(f"mode must be one of {', '.join(MODES)}, got {value!r}")
    return value


def cval(value, channels, dtype, device):
    """cval as a (C,) tensor: a finite number or one per channel."""
    if isinstance(value, torch.Tensor):
        value = value.detach().cpu().tolist()
    values = [value] * channels if isinstance(value, numbers.Real) and not isinstance(value, bool) else value
    try:
        values = [float(v) for v in values]
    except (TypeError, ValueError):
        raise fpiwarp.ArgumentError(f"cval must be a number or one number per channel, got {value!r}") from None
    if len(values) != channels or not all(math.isfinite(v) for v in values):
        raise fpiwarp.ArgumentError(f"cval must be finite, one number or {channels} (one per channel), got {value!r}")
    return torch.tensor(values, dtype=dtype, device=device)


def antialias(value):
    if not isinstance(value, bool):
        raise fpiwarp.ArgumentTypeError(f"antialias must be True or False, got {value!r}")
    if value:
        raise fpiwarp.ArgumentError("antialias=True is not supported by fpiwarp.torch (no differentiable footprint "
                                    "filter); use fpiwarp.warp_image(..., antialias=True) for a non-differentiable one")
