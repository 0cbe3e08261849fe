"""Views between array libraries, without copies where the protocols allow.

Each function takes an array recognized by :func:`fpiwarp.arrays.kinds.array_info`
and returns a view of the same memory in another library: a Warp array
(``wp.from_dlpack``, or ``wp.array`` on ``__cuda_array_interface__``), a
numpy array (``np.from_dlpack``) or the caller's library again (its own
``from_dlpack``). The caller's libraries are looked up in ``sys.modules``:
a tensor's library is imported already when the tensor exists.
"""

import sys

import numpy as np

from ..errors import ArgumentTypeError, DeviceMismatchError
from .kinds import ArrayInfo

#: How to turn a DLPack-capable object into each library's array, by the
#: top-level module of the caller's array type.
FROM_DLPACK = {
    "numpy": ("numpy", "from_dlpack"),
    "torch": ("torch", "from_dlpack"),
    "cupy": ("cupy", "from_dlpack"),
    "jax": ("jax.dlpack", "from_dlpack"),
    "jaxlib": ("jax.dlpack", "from_dlpack"),
}


def to_warp(wp, obj, info: ArrayInfo):
    """A Warp array viewing ``obj``'s memory (no copy)."""
    if info.kind == "warp":
        return obj
    if info.kind == "dlpack":
        return wp.from_dlpack(obj)
    if info.kind == "cuda_array_interface":
        return wp.array(obj, copy=False)
    if info.kind == "numpy":
        return wp.array(obj, copy=False, device="cpu")
    raise ArgumentTypeError(f"cannot view a {info.kind} array as a Warp array")


def from_warp(arr, info: ArrayInfo):
    """``arr`` (a Warp array) as an array of the library ``info`` describes
    (a Warp array stays one; a library without ``from_dlpack`` gets the Warp array)."""
    if info.library == "warp":
        return arr
    if info.library == "numpy":
        return arr.numpy()  # a view on the CPU device
    return _from_dlpack(arr, info.library, default=arr)


def host_view(obj, info: ArrayInfo) -> np.ndarray:
    """A numpy view of an array in host memory (no copy)."""
    if info.kind in ("numpy", "host"):
        return np.asarray(obj)
    if not info.on_host:
        raise DeviceMismatchError(f"a {info.library} array on {info.device} is not in host memory")
    if info.kind == "warp":
        return obj.numpy()
    return np.from_dlpack(obj)


def from_host(result: np.ndarray, info: ArrayInfo):
    """A host result as an array of the caller's library (by DLPack, no copy
    where the library accepts it); numpy for numpy and unknown libraries."""
    if info.library == "numpy":
        return result
    if info.library == "warp":
        wp = sys.modules["warp"]
        return wp.array(result, copy=False, device="cpu")
    return _from_dlpack(result, info.library, default=result)


def _from_dlpack(obj, library, default):
    module_name, func = FROM_DLPACK.get(library, (library, "from_dlpack"))
    module = sys.modules.get(module_name)
    if module is None and library == "jax":  # jax is imported, jax.dlpack perhaps not yet
        import importlib  # noqa: PLC0415

        module = importlib.import_module(module_name)
    convert = getattr(module, func, None) if module is not None else None
    return default if convert is None else convert(obj)
