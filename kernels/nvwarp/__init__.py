"""NVIDIA Warp kernels of fpiwarp (imported by :mod:`fpiwarp.backends.nvwarp`)."""
