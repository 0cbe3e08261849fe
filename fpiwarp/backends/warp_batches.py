"""Batches on the ``"warp"`` backend: many images (point sets) per launch.

The kernels of :mod:`fpiwarp.kernels.warp_batch` run the single image's
per-pixel code on image n of a stack with its own parameter block, read
from the N blocks stacked in one (N, rows, 4) array (rows: the longest
block's; one map for all images is one block that every image reads).
Warp's kernels read the kind of each map at run time, so a batch of any
mix of kinds is one launch (on the CPU device split, like one tall image,
into one band of rows per thread).

Bounds: a launch covers at most :data:`CHUNK_BYTES` of input plus output
(at least one image): larger batches are several launches, never refused.
On the CPU the kernels read and write the caller's arrays in place; on
CUDA each chunk is copied in, warped and copied out (no overlap of copies
and kernels yet: see the opencl backend's pipelined transfers).
"""

import numpy as np

from ..block import describe
from ..block.sampling_rules import MODES

#: Bytes of input plus output one launch covers at most.
CHUNK_BYTES = 256 << 20

_TOP = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0, np.dtype(np.float32): 0.0}


def stacked_blocks(transforms):
    """(N or 1, rows, 4) float32 blocks of ``transforms``, each padded with
    zero rows to the longest; a block no kernel knows raises ValueError."""
    blocks = [np.asarray(t.params(), dtype=np.float32) for t in transforms]
    for block in blocks:
        describe(block)
    rows = max(b.shape[0] for b in blocks)
    out = np.zeros((len(blocks), rows, 4), dtype=np.float32)
    for i, block in enumerate(blocks):
        out[i, : block.shape[0]] = block
    return out


def _ranges(n, item_bytes):
    per = max(1, CHUNK_BYTES // max(item_bytes, 1))
    return [(a, min(n, a + per)) for a in range(0, n, per)]


class BatchRunner:
    """Batches on one Warp backend: ``wp`` (the module), ``device``,
    ``on_cpu`` and ``launch(kernel, rows, cols, inputs)`` (the backend's
    banded launcher) come from the backend."""

    def __init__(self, wp, device, on_cpu, launch, kernels):
        self.wp, self.device, self.on_cpu, self.launch, self.k = wp, device, on_cpu, launch, kernels

    def _array(self, data, dtype):
        """``data`` on the device: aliased on the CPU, copied on CUDA."""
        if self.on_cpu:
            return self.wp.array(data, dtype=dtype, device="cpu", copy=False)
        return self.wp.array(data, dtype=dtype, device=self.device)

    def _which(self, blocks, a, b):
        idx = np.zeros(b - a, dtype=np.int32) if blocks.shape[0] == 1 else np.arange(a, b, dtype=np.int32)
        return self._array(idx, self.wp.int32)

    def warp_batch(self, stack, transforms, output_shape, *, order, mode, cval, antialias=False):
        """(N, rows, cols, C) from a validated (N, H, W, C) stack and one
        map or one map per image."""
        wp = self.wp
        n, _, _, c = stack.shape
        oh, ow = output_shape
        out = np.empty((n, oh, ow, c), dtype=stack.dtype)
        scalar = wp.dtype_from_numpy(stack.dtype)
        cv = np.zeros(4, dtype=np.float32)
        cv[:c] = cval
        tail = [MODES.index(mode), wp.vec4(*cv.tolist()), _TOP[stack.dtype]]
        kernel = self.k.BATCH_KERNELS[order]
        if antialias:
            kernel, tail = self.k.batch_antialias, [int(order), *tail]
        blocks = stacked_blocks([t.inverse for t in transforms])
        blks = self._array(blocks, wp.vec4)
        for a, b in _ranges(n, stack[0].nbytes + out[0].nbytes):
            src = self._array(stack[a:b], scalar)
            dst = self._array(out[a:b], scalar) if self.on_cpu else wp.empty(out[a:b].shape, scalar, self.device)
            which = self._which(blocks, a, b)
            self.launch(kernel, (b - a) * oh, ow, [blks, which, src, dst, *tail])
            if not self.on_cpu:
                out[a:b] = dst.numpy()
        return out

    def map_points_batch(self, transforms, points):
        """float64 (N, P, 2) point sets mapped by one map or one each."""
        wp = self.wp
        n, p, _ = points.shape
        pts = np.ascontiguousarray(points, dtype=np.float64)
        out = np.empty_like(pts)
        if n == 0 or p == 0:
            return out
        blocks = stacked_blocks(transforms)
        blks = self._array(blocks, wp.vec4)
        for a, b in _ranges(n, 2 * pts[0].nbytes):
            src = self._array(pts[a:b], wp.vec2d)
            dst = self._array(out[a:b], wp.vec2d) if self.on_cpu else wp.empty((b - a, p), wp.vec2d, self.device)
            self.launch(self.k.batch_map_points, (b - a) * p, None, [blks, self._which(blocks, a, b), src, dst])
            if not self.on_cpu:
                out[a:b] = dst.numpy()
        return out
