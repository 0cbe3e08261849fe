"""NVIDIA Warp kernels of fpiwarp (used by :mod:`fpiwarp.backends.nvwarp`).

One stage walk, one sampler, one factory (issue 23's rule: each kernel
language has one of each, mirroring the numpy reference):

* :mod:`.contract`: the block contract's numbers, bound from
  :mod:`fpiwarp.block.codegen`;
* :mod:`.stage`: complex arithmetic, the TPS cores and Newton inverse, the
  one stage function (value and, where asked, Wirtinger derivatives) and
  the walk over a block's stages;
* :mod:`.sample`: border rules, the one sampler (orders 0/1/3),
  antialiasing's footprint over the source pyramid, a pyramid texel, the
  pixel writer;
* :mod:`.factory`: every image and point kernel, specialized by key (kind
  of map, order, mode, channels, dtype, layout, rows, antialias), made
  once per process and cached on disk by Warp, and the pyramid level
  kernel;
* :mod:`.points`: the device-array helpers that widen float32 points to
  the float64 the point kernels read, and narrow them back.

Named ``nvwarp`` so that NVIDIA's library and the verb "warp" cannot be
confused; the backend's name stays ``"warp"``.
"""
