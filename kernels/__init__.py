"""Kernel sources of fpiwarp (OpenCL ``.cl`` files and NVIDIA Warp modules),
installed as the package ``fpiwarp.kernels``; load text files through
:func:`fpiwarp.resources.source`."""
