"""Batches on the ``"warp"`` backend: many images (point sets) per launch.

Plain image batches run the kernels specialized per kind of map that
single images run (:func:`fpiwarp.kernels.warp_kinds.batch_kernel`, the
same per-pixel function): the maps are grouped by kind of block (each
stage's core and regions, as the opencl backend groups them) and each
group is one launch over its images, reading block ``which[k]`` of the
group's blocks stacked in one (B, rows, 4) array (rows: the longest
block's; one map for all images is one block that every image reads).
N maps of one kind are one launch; k kinds are k launches. Antialiased
batches and point sets run the generic kernels of
:mod:`fpiwarp.kernels.warp_batch` (as single calls do), one launch for any
mix of kinds. On the CPU device every launch is split, like one tall
image, into one band of rows per thread of the backend's pool.

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
    return _padded(blocks)


def kind_groups(transforms, n):
    """The maps of a batch of ``n`` images grouped by kind of block: a list
    of (kind key (each stage's core and regions, as
    :func:`fpiwarp.kernels.warp_kinds.kind_key`), blocks (B, rows, 4)
    float32 padded to the longest, images (K,) int32: the group's images,
    image ``images[k]`` warped by block k, or block 0 where B is 1). One
    map gives one group of all ``n`` images reading one block. A block no kernel knows raises
    ValueError (:func:`describe`) first."""
    blocks = [np.ascontiguousarray(t.params(), dtype=np.float32) for t in transforms]
    keys = [tuple((s.core, s.n_regions) for s in describe(b).stages) for b in blocks]
    if len(blocks) == 1:
        return [(keys[0], blocks[0][None], np.arange(n, dtype=np.int32))]
    groups = {}
    for i, key in enumerate(keys):
        groups.setdefault(key, []).append(i)
    return [(key, _padded([blocks[i] for i in idx]), np.asarray(idx, dtype=np.int32)) for key, idx in groups.items()]


def _padded(blocks):
    """(B, rows, 4) float32: ``blocks`` padded with zero rows to the longest."""
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
        n, h, w, c = stack.shape
        oh, ow = output_shape
        out = np.empty((n, oh, ow, c), dtype=stack.dtype)
        cv = np.zeros(4, dtype=np.float32)
        cv[:c] = cval
        if antialias:
            self._antialias(stack, transforms, out, order, MODES.index(mode), wp.vec4(*cv.tolist()))
            return out
        from fpiwarp.kernels import warp_kinds  # noqa: PLC0415 - Warp imported with the backend

        scalar = wp.dtype_from_numpy(stack.dtype)
        # images are row offsets into (N·H, W, C) arrays (see warp_kinds.batch_kernel)
        whole = (self._array(stack.reshape(n * h, w, c), scalar), self._array(out.reshape(n * oh, ow, c), scalar))\
            if self.on_cpu else None
        for key, blocks, images in kind_groups([t.inverse for t in transforms], n):
            kernel = warp_kinds.batch_kernel(key, order, c, MODES.index(mode), stack.dtype)
            step = int(len(blocks) > 1)
            for a, b in _ranges(len(images), stack[0].nbytes + out[0].nbytes):
                blks = self._array(blocks[a * step: b * step + 1 - step], wp.vec4)
                idx = images[a:b]
                if self.on_cpu:
                    src, dst = whole
                else:  # this chunk's images copied in, numbered 0..b-a
                    src = self._array(stack[idx].reshape((b - a) * h, w, c), scalar)
                    dst = wp.empty(((b - a) * oh, ow, c), scalar, self.device)
                    idx = np.arange(b - a, dtype=np.int32)
                inputs = [blks, self._array(idx, wp.int32), src, dst, h, oh, step, wp.vec4(*cv.tolist())]
                self.launch(kernel, (b - a) * oh, ow, inputs)
                if not self.on_cpu:
                    out[images[a:b]] = dst.numpy().reshape(b - a, oh, ow, c)
        return out

    def _antialias(self, stack, transforms, out, order, mode, cval):
        """The antialiased batch (generic kernel, as the single image's) into ``out``."""
        wp = self.wp
        n, oh, ow, _ = out.shape
        scalar = wp.dtype_from_numpy(stack.dtype)
        tail = [int(order), mode, cval, _TOP[stack.dtype]]
        blocks = stacked_blocks([t.inverse for t in transforms])
        blks = self._array(blocks, wp.vec4)
        for a, b in _ranges(n, stack[0].nbytes + out[0].nbytes):
            src = self._array(stack[a:b], scalar)
            dst = self._array(out[a:b], scalar) if self.on_cpu else wp.empty(out[a:b].shape, scalar, self.device)
            self.launch(self.k.batch_antialias, (b - a) * oh, ow, [blks, self._which(blocks, a, b), src, dst, *tail])
            if not self.on_cpu:
                out[a:b] = dst.numpy()

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
