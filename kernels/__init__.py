"""Kernel sources of fpiwarp, installed as the package ``fpiwarp.kernels``.

* ``opencl/``: the OpenCL program (``fpiwarp.cl``) and the map and sampler it
  includes (``fpiwarp_map.h``), text files loaded through
  :func:`fpiwarp.resources.source`;
* ``nvwarp/``: the NVIDIA Warp kernels, Python modules
  (``fpiwarp.kernels.nvwarp``).
"""
