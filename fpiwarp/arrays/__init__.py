"""Arrays on devices: what fpiwarp accepts besides numpy, and where it runs them.

:func:`fpiwarp.warp_image` and :func:`fpiwarp.map_points` take, besides
numpy arrays (unchanged behaviour):

* any array that speaks DLPack (``__dlpack__``/``__dlpack_device__``:
  PyTorch, CuPy, JAX, numpy itself) or the CUDA array interface, and Warp
  arrays: the "warp" backend reads and writes them in place on their
  device ("cpu" or "cuda:N"); the result is an array of the input's
  library on the same device;
* a ``pyopencl.array.Array`` in the opencl backend's context (made with
  :func:`opencl_queue`, or by :func:`to_opencl`): the kernel runs on its
  buffer, the result is a pyopencl array;
* a ``moderngl.Texture`` ("f1", "u2" or "f4"): rendered into a texture of
  the same format and context.

With ``backend=None`` (the default) the backend follows the data, as the
registry declares it (each entry's ``default_for``, ``reads``): for numpy
images the fast default (``fpiwarp.backends.default``), for numpy
points the numpy reference, "opencl" for pyopencl arrays, "gl" for
textures, "warp" for Warp, DLPack and CUDA arrays. A backend that cannot
read the data in place (a CUDA tensor for "opencl", a texture for
"warp") raises :class:`~fpiwarp.DeviceMismatchError` naming the backends
that can. CPU DLPack arrays
also run on the host backends, through a numpy view.

:func:`fpiwarp.warp_batch` and :func:`fpiwarp.map_points_batch` take
stacks (N, H, W[, C]), or (N, C, H, W) with ``channels="first"``, and
point sets (N, ..., 2) of the same kinds the same way (Warp/DLPack/CUDA
on "warp", pyopencl on "opencl"), one launch per kind of map, in place
(``fpiwarp.batch.arrays``).

Nothing here imports torch, CuPy or JAX: arrays are recognized by their
protocols and by the types of libraries already imported
(:func:`array_info`).
"""

from ..backends.opencl.arrays import opencl_queue, to_opencl
from .dispatch import CHANNELS, check_channels
from .kinds import DEFAULT_BACKENDS, KINDS, ArrayInfo, array_info, choose_backend

__all__ = ["CHANNELS", "DEFAULT_BACKENDS", "KINDS", "ArrayInfo", "array_info", "check_channels", "choose_backend",
           "opencl_queue", "to_opencl"]
