"""Prepared image warps of the ``"warp"`` backend: one job per kind of call.

A :class:`WarpJob` holds what does not change between calls of one kind
(image shape and dtype, output shape, order, mode, cval and the map's
kind): the kernel specialized for it (:mod:`fpiwarp.kernels.nvwarp.factory`),
the bands of rows a CPU call is split into, and the recorded launches
(``wp.launch(..., record_cmd=True)``), so a call only points the launches at
this image and output and replays them. :class:`BoundMap` is the
backend's ``bind``: the map's parameter block is packed, checked and
uploaded once, and each kind of call keeps its job.
"""

import itertools

import numpy as np

from ...block import describe
from ...block.sampling_rules import MODES
from ..lru import LruCache

#: Jobs kept per backend (plain calls) and per bound map, least recently used dropped.
MAX_JOBS = 8


def job_key(image, output_shape, order, mode, cval, kind_key):
    """What a job is made for; calls with equal keys share it."""
    return (image.shape, image.dtype.str, tuple(output_shape), int(order), mode,
            tuple(float(v) for v in cval), kind_key)


class JobCache(LruCache):
    """An LRU of :class:`WarpJob` by :func:`job_key`."""

    def __init__(self, size=MAX_JOBS):
        super().__init__(size)

    def get(self, backend, block, image, output_shape, order, mode, cval, kind_key):
        key = job_key(image, output_shape, order, mode, cval, kind_key)
        return self.lookup(key, lambda: WarpJob(backend, block, image, output_shape, order, mode, cval, kind_key))


class WarpJob:
    """A warp of one kind of call: kernel, bands and recorded launches.

    ``block`` is the device array the kernel reads the map from (its
    values may change between calls, its kind may not). :meth:`run` warps
    one image; use it under the backend's lock.
    """

    def __init__(self, backend, block, image, output_shape, order, mode, cval, kind_key):
        be = self.backend = backend
        wp = be._wp
        self.output_shape = oh, ow = tuple(output_shape)
        self.channels = image.shape[2]
        self.dtype = image.dtype
        self._scalar = wp.dtype_from_numpy(image.dtype)
        cv = np.zeros(4, dtype=np.float32)
        cv[: self.channels] = cval
        mode = MODES.index(mode)
        kernel = be.image_kernel(kind_key, order, mode, self.channels, image.dtype)
        bands = be.band_count(oh, ow)
        cuts = [oh * b // bands for b in range(bands + 1)]
        src = be._to_device("image", image, self._scalar)
        out = self._output()
        tail = [image.shape[0], oh, 0, int(order), mode, wp.vec4(*cv.tolist())]
        self._launches = [
            wp.launch(kernel, dim=be.image_dims(r1 - r0, ow),
                      inputs=[block, be.first, src, out[1], *tail, *be.no_pyramid, r0], device=be.device,
                      record_cmd=True)
            for r0, r1 in itertools.pairwise(cuts)
        ]

    def _output(self):
        """(numpy result or None, device array) for one call's output."""
        be, wp = self.backend, self.backend._wp
        shape = (*self.output_shape, self.channels)
        if be._on_cpu:
            result = np.empty(shape, dtype=self.dtype)
            return result, wp.array(result, dtype=self._scalar, device="cpu", copy=False)
        return None, be._buffer("warped", shape, self._scalar)

    def run(self, image):
        """Warp ``image`` (of the job's shape and dtype); a new output array."""
        be = self.backend
        src = be._to_device("image", image, self._scalar)
        result, out = self._output()
        for launch in self._launches:
            launch.set_param_at_index(2, src)
            launch.set_param_at_index(3, out)
        be.run_launches(self._launches)
        return result if result is not None else out.numpy()


class BoundMap:
    """One map bound to the warp backend (its ``bind``): the block of its
    inverse packed, checked and uploaded once, a job per kind of call."""

    def __init__(self, backend, transform):
        wp = backend._wp
        self.backend, self.transform = backend, transform
        block = np.ascontiguousarray(transform.inverse.params(), dtype=np.float32)
        self.kind_key = backend.kernels.kind_key(describe(block))
        self._block = wp.array(block[None], dtype=wp.vec4, device=backend.device)  # blocks (1, rows)
        self._jobs = JobCache()

    def warp_image(self, image, output_shape, *, order, mode, cval, antialias=False):
        be = self.backend
        if antialias:  # the antialiased kernel is not specialized: the plain path
            return be.warp_image(image, self.transform, output_shape, order=order, mode=mode, cval=cval,
                                 antialias=True)
        with be._lock:
            job = self._jobs.get(be, self._block, image, output_shape, order, mode, cval, self.kind_key)
            return job.run(image)
