"""What kind of array an argument is, and where its data lives.

Recognition is by protocol and by the types of libraries the caller has
already imported (looked up in ``sys.modules``): nothing here imports
torch, CuPy, JAX, Warp, pyopencl or moderngl, so they stay optional.
"""

import sys
from dataclasses import dataclass

import numpy as np

from ..backends import default_for_kind

#: DLPack's device types (``__dlpack_device__()[0]``) that fpiwarp reads.
DLPACK_CPU, DLPACK_CUDA, DLPACK_CUDA_HOST, DLPACK_CUDA_MANAGED = 1, 2, 3, 13
DLPACK_DEVICE_NAMES = {1: "cpu", 2: "cuda", 3: "cuda_host", 4: "opencl", 7: "vulkan", 8: "metal", 10: "rocm",
                       13: "cuda_managed", 14: "oneapi"}

#: What each kind means (:attr:`ArrayInfo.kind`).
KINDS = {
    "numpy": "a numpy array (host memory)",
    "host": "anything else numpy converts (lists, ...): host memory",
    "warp": "a Warp array (wp.array) on its Warp device",
    "dlpack": "an array speaking DLPack (__dlpack__, __dlpack_device__): torch, CuPy, JAX, ...",
    "cuda_array_interface": "an array with __cuda_array_interface__ only (e.g. Numba)",
    "opencl": "a pyopencl.array.Array in its OpenCL context",
    "texture": "a moderngl.Texture in its GL context",
}

#: Kinds in host memory that every backend takes as numpy arrays.
HOST_KINDS = ("numpy", "host")
#: Kinds that every backend also takes through a numpy view when their data
#: is in host memory (a CPU torch tensor, a Warp array on "cpu").
HOST_VIEW_KINDS = ("warp", "dlpack")
#: Kinds that hold one image, never a stack.
IMAGE_ONLY_KINDS = ("texture",)
#: How to bring an array of each kind to the host (in error messages).
TO_HOST = {"opencl": ".get() it into numpy", "texture": ".read() it into numpy"}

#: The backend each kind runs on when the caller names none, from the
#: registry (``default_for``). For host kinds this is the float64 reference
#: that the fast default falls back to (:mod:`fpiwarp.backends.default`).
DEFAULT_BACKENDS = {kind: default_for_kind(kind) for kind in KINDS}


@dataclass(frozen=True)
class ArrayInfo:
    """Where an array lives.

    Attributes
    ----------
    kind : str
        A key of ``fpiwarp.arrays.KINDS``.
    device : str
        ``"cpu"``, ``"cuda:N"``, ``"opencl"`` (its context is the array's),
        ``"gl"`` (its context is the texture's), or another DLPack device name.
    library : str
        The top-level module of the array's type (``"numpy"``, ``"torch"``,
        ``"jax"``, ``"warp"``, ...): results are returned as its arrays.
    """

    kind: str
    device: str
    library: str

    @property
    def on_host(self) -> bool:
        """Whether the data is in host memory numpy can view."""
        return self.device == "cpu"

    @property
    def default_backend(self) -> str:
        """The backend the registry names for this kind when the caller
        names none (for host kinds the reference, "numpy", which the fast
        default of ``choose_backend`` falls back to)."""
        return DEFAULT_BACKENDS[self.kind]


def _loaded_type(module, name):
    """``module.name`` if the module is imported already, else None."""
    mod = sys.modules.get(module)
    return getattr(mod, name, None) if mod is not None else None


def _isinstance(obj, module, name):
    cls = _loaded_type(module, name)
    return cls is not None and isinstance(obj, cls)


def library_of(obj) -> str:
    """The top-level module of ``type(obj)``."""
    return type(obj).__module__.split(".")[0]


def dlpack_device_name(device_type: int, device_id: int) -> str:
    """``"cpu"``, ``"cuda:N"`` or another device's name from a DLPack device."""
    if device_type == DLPACK_CPU:
        return "cpu"
    if device_type in (DLPACK_CUDA, DLPACK_CUDA_MANAGED):
        return f"cuda:{int(device_id)}"
    return f"{DLPACK_DEVICE_NAMES.get(device_type, f'dlpack device type {device_type}')}:{int(device_id)}"


def array_info(obj) -> ArrayInfo:
    """Recognize ``obj``: which kind of array, on which device.

    Parameters
    ----------
    obj : object
        An image or points argument.

    Returns
    -------
    ArrayInfo

    Examples
    --------
    >>> import numpy as np
    >>> from fpiwarp.arrays import array_info
    >>> array_info(np.zeros((2, 2)))
    ArrayInfo(kind='numpy', device='cpu', library='numpy')
    >>> array_info([[1, 2]]).default_backend
    'numpy'
    """
    if isinstance(obj, np.ndarray):
        return ArrayInfo("numpy", "cpu", "numpy")
    if _isinstance(obj, "pyopencl.array", "Array"):
        return ArrayInfo("opencl", "opencl", "pyopencl")
    if _isinstance(obj, "moderngl", "Texture"):
        return ArrayInfo("texture", "gl", "moderngl")
    if _isinstance(obj, "warp", "array"):
        device = obj.device
        return ArrayInfo("warp", "cpu" if device.is_cpu else str(device.alias), "warp")
    if hasattr(obj, "__dlpack_device__") and hasattr(obj, "__dlpack__"):
        device_type, device_id = obj.__dlpack_device__()
        return ArrayInfo("dlpack", dlpack_device_name(int(device_type), int(device_id)), library_of(obj))
    if hasattr(obj, "__cuda_array_interface__"):
        return ArrayInfo("cuda_array_interface", "cuda:0", library_of(obj))
    return ArrayInfo("host", "cpu", "numpy")


def choose_backend(info: ArrayInfo, backend: str | None) -> str:
    """``backend``, or the registry's default of the array's kind when it
    is None. Host arrays with ``backend=None`` do not come here: the entry
    points choose their fast default per call
    (:func:`fpiwarp.backends.default.host_backend`)."""
    return info.default_backend if backend is None else backend
