"""The ``"warp"`` backend: NVIDIA Warp kernels on CUDA or Warp's CPU device.

The folder is named ``nvwarp`` so that NVIDIA's library and the verb
"warp" cannot be confused; the backend's name stays ``"warp"``.

* :mod:`.backend`: the registry's entry (probe, device choice, warp_image, map_points);
* :mod:`.prepared`: prepared jobs, one per kind of call;
* :mod:`.batch`: many images or point sets per launch;
* :mod:`.arrays`: Warp, DLPack and CUDA-array-interface inputs, on their device.

The kernels are ``kernels/nvwarp/`` (installed as ``fpiwarp.kernels.nvwarp``).
Nothing here imports Warp until the backend is used.
"""
