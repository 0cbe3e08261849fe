"""Source pyramids of the ``"warp"`` backend's antialiased kernels.

:mod:`fpiwarp.sampling.pyramid` on the device: levels >= 1 of each source
in one float32 array, made level by level by
:func:`fpiwarp.kernels.nvwarp.factory.pyramid_kernel` (level 1 from the
source in its dtype, each later level from the one below). Image n's
level k is rows ``n·R + offset_k`` onwards (R: the rows of one image's
levels), columns [0, w_k); the level table (``levels``, (top + 1,) vec3i)
holds (offset_k, h_k, w_k) for k >= 1 and (R, H, W) at 0, R being 0
where every image of a launch reads one pyramid (a batch of one source).
"""

import numpy as np

from ...sampling.pyramid import level_sizes


class DevicePyramid:
    """The pyramids of ``sources`` (a list of (Warp array (rows, W, C) of
    one dtype, first row), each an H × W image), built on the backend's
    device when made. ``array`` and ``levels`` are the kernels' arguments."""

    def __init__(self, backend, sources, height, width, channels):
        wp = backend._wp
        sizes = level_sizes(height, width)
        offsets = np.cumsum([0] + [h for h, _ in sizes[1:]])
        rows = int(offsets[-1])  # of one image's levels >= 1
        widest = sizes[1][1] if len(sizes) > 1 else 1
        table = np.zeros((len(sizes), 3), dtype=np.int32)
        table[0] = (rows if len(sources) > 1 else 0, height, width)
        for k in range(1, len(sizes)):
            table[k] = (offsets[k - 1], *sizes[k])
        self.top = len(sizes) - 1
        self.array = wp.empty((max(1, rows * len(sources)), widest, channels), dtype=wp.float32,
                              device=backend.device)
        self.levels = wp.array(table, dtype=wp.vec3i, device=backend.device)
        self._build(backend, sources, sizes, table, rows)

    def _build(self, backend, sources, sizes, table, rows):
        if self.top == 0:
            return
        channels = self.array.shape[2]
        level1 = backend.pyramid_kernel(np.dtype(backend._wp.dtype_to_numpy(sources[0][0].dtype)), channels)
        upper = backend.pyramid_kernel(np.float32, channels)
        for n, (src, src0) in enumerate(sources):
            base = n * rows
            below, below0 = src, src0
            for k in range(1, self.top + 1):
                (h, w), (h2, w2) = sizes[k - 1], sizes[k]
                kernel = level1 if k == 1 else upper
                dst0 = base + int(table[k][0])
                backend.launch_image(kernel, h2, w2, [below, below0, h, w, self.array, dst0, w2])
                below, below0 = self.array, dst0

    @property
    def args(self):
        """The kernels' (pyramid, levels) arguments."""
        return [self.array, self.levels]
