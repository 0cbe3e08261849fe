"""The ``"opencl"`` backend: the parameter block evaluated by OpenCL kernels.

* :mod:`.backend`: the registry's entry (probe, program build, warp_image, map_points);
* :mod:`.prepared`: prepared jobs, one per kind of call;
* :mod:`.tiles`: work-group tiles on CPU devices;
* :mod:`.batch`: many images or point sets per launch;
* :mod:`.arrays`: ``pyopencl.array.Array`` inputs, on the device.

The kernels are ``kernels/opencl/`` (installed as ``fpiwarp.kernels``).
Nothing here imports pyopencl until the backend is used.
"""
