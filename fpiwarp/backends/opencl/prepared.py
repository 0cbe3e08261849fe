"""Prepared image warps of the ``"opencl"`` backend: one job per kind of call.

A :class:`ClJob` holds what does not change between calls of one kind
(image shape and dtype, output shape, order, mode, cval, antialiasing and
the map's kind): its own kernel object with its arguments set, its own
device buffers for the source and (small) outputs, the launch shape. A
call copies the image in without waiting, launches, and reads the output
back: one wait per call. On a CPU, large outputs are written in place and
sources read in place (USE_HOST_PTR), with no copy: at 4K float32 RGB the
upload was a fifth of the call. The kernel never reads past a
source's last byte (uint8/uint16 pixels narrower than the 32-bit word it
loads them as included: see FW_WORD_TAIL in fpiwarp_map.h), so the
caller's array needs no slack after it. The block buffer is the job's own too: a new
block is uploaded only when its bytes differ from the job's last one.

An output of :data:`RECYCLE_MIN_BYTES` or more is fresh memory from the
OS at every call (malloc maps blocks that large anew), whose pages the
kernel's first writes fault in and the OS zeroes: a sixth of a 4K float32
RGB call. The job keeps its last :data:`SPARE_OUTPUTS` such outputs and
returns one again once nothing else refers to it
(:meth:`ClJob._spare_unused`: its caller dropped it, and every view of
it), so a loop that keeps each result until the next call
(``out = warper(frame)``) reuses two blocks of memory; a result still held
is never touched.

:class:`BoundMap` is the backend's ``bind``: the map's parameter block is
packed and checked once, and each kind of call keeps its job.
"""

import sys
import weakref

import numpy as np

from ...block.coarse import coarse_shape
from ...block.coarse_choice import takes_coarse_pass
from ...block.layout import COARSE_FLOATS
from ...errors import SizeLimitError
from ..lru import LruCache
from .pyramid import levels_needed
from .tiles import global_size, has_newton, tiled_program

#: Bytes allocated past an uploaded source image: sampling reads a pixel of
#: up to 4 bytes as one 32-bit word, which stays inside any image of 4 bytes
#: or more (FW_WORD_TAIL) but may run past a smaller one.
IMAGE_SLACK = 4
#: Outputs smaller than this are written to a kept device buffer and copied
#: out: wrapping each new output array in a buffer (zero copy) costs about
#: a millisecond of driver set-up per call on PoCL, more than the copy.
ZERO_COPY_MIN_BYTES = 1 << 20
#: A Newton map's warp runs the coarse pass (fpiwarp/block/coarse.py) first
#: where the block's rule picks it for the map and output shape
#: (fpiwarp/block/coarse_choice.py); False: each pixel solves alone (read
#: when a job is looked up, a batch launched or a device warp's map set:
#: benchmarks compare the two, benchmarks/local_speed.py).
COARSE_PASS = True
#: The build option of a warp taking the coarse pass (warp_image then
#: reads the records coarse_pass writes: kernels/opencl/fpiwarp.cl).
COARSE_OPTION = "-DFW_COARSE=1"
#: The index of warp_image_aa's first pyramid argument (after cval).
PYRAMID_ARG = 8
#: Jobs kept per backend (plain calls) and per bound map, least recently used dropped.
MAX_JOBS = 4
#: Outputs of this many bytes or more are recycled (see the module
#: docstring); None: never. glibc's malloc serves blocks under 32 MiB from
#: its heap, whose pages stay mapped between calls (a 4K RGB uint8 output,
#: 25 MB, costs 0.2 ms to touch), and maps larger ones anew each time (a
#: 4K RGB float32 output, 100 MB: 6 ms of page zeroing on one core, more
#: inside the kernel's two threads, plus the unmapping when it is freed).
#: Each job keeps SPARE_OUTPUTS such outputs alive (up to MAX_JOBS jobs per bound map).
RECYCLE_MIN_BYTES = 32 << 20
#: Recycled outputs a job keeps: two, so that the result before last is
#: free again while the caller holds the last one.
SPARE_OUTPUTS = 2


class _SpareProbe:
    """An object held by one attribute alone, counted as
    :meth:`ClJob._spare_unused` counts its spare (same expression)."""

    def __init__(self):
        self._spares = [np.empty(0)]

    def count(self, i):
        return sys.getrefcount(self._spares[i])


#: The reference count :meth:`ClJob._spare_unused` reads for a spare that
#: only the job holds (interpreters count stack references differently);
#: None where the interpreter has no exact reference counts (recycling is
#: off): other than CPython, and CPython without its GIL (free-threaded
#: builds count references per thread).
_UNUSED_REFS = _SpareProbe().count(0) if hasattr(sys, "getrefcount") and \
    sys.implementation.name == "cpython" and getattr(sys, "_is_gil_enabled", lambda: True)() else None


def job_key(image, output_shape, order, mode, cval, antialias, kind, coarse=False):
    """What a job is made for; calls with equal keys share it."""
    return (image.shape, image.dtype.str, tuple(output_shape), int(order), mode,
            tuple(float(v) for v in cval), bool(antialias), kind, bool(coarse))


def takes_coarse(kind, antialias, block, output_shape):
    """Whether a warp of float32 ``block`` (its kind ``kind``, ``kind_options``)
    to ``output_shape`` (rows, cols) takes the coarse pass: a Newton map,
    not antialiased, while COARSE_PASS (read at each call: benchmarks
    toggle it), where the block's rule picks it (``takes_coarse_pass``)."""
    return (COARSE_PASS and not antialias and has_newton(kind)
            and takes_coarse_pass(block, output_shape[1], output_shape[0], "opencl"))


def records_bytes(output_shape, count=1):
    """Bytes of the coarse pass's records of ``count`` warps to
    ``output_shape`` (rows, cols), and the nodes (nx, ny) of one."""
    ny, nx = coarse_shape(output_shape[1], output_shape[0])
    return 4 * COARSE_FLOATS * nx * ny * count, (nx, ny)


def nodes_global(local_x, nx, ny):
    """coarse_pass's global size over nx x ny nodes: whole groups of ``local_x``."""
    return -(-nx * ny // local_x) * local_x


class JobCache(LruCache):
    """An LRU of :class:`ClJob` by :func:`job_key`."""

    def __init__(self, size=MAX_JOBS):
        super().__init__(size)

    def get(self, backend, image, output_shape, order, mode, cval, antialias, kind, block):
        """The job of a warp of float32 ``block`` (of kind ``kind``): with or
        without the coarse pass as :func:`takes_coarse` picks for it."""
        coarse = takes_coarse(kind, antialias, block, output_shape)
        key = job_key(image, output_shape, order, mode, cval, antialias, kind, coarse)
        return self.lookup(key, lambda: ClJob(backend, image, output_shape, order, mode, cval, antialias, kind,
                                              coarse))


class ClJob:
    """A warp of one kind of call (see the module docstring); :meth:`run`
    under the backend's lock."""

    def __init__(self, backend, image, output_shape, order, mode, cval, antialias, kind, coarse=False):
        be = self.backend = backend
        cl = be._cl
        h, w, c = image.shape
        oh, ow = self.output_shape = tuple(output_shape)
        if max(h * w, oh * ow) * c >= 2**31:
            raise SizeLimitError(f"image too large for the opencl backend: {h}x{w}x{c} -> {oh}x{ow}x{c}")
        self.out_shape, self.dtype = (oh, ow, c), image.dtype
        name, options, self._local = tiled_program(be, image.dtype, c, order, mode, ow, antialias, kind)
        #: a Newton map's coarse pass (fpiwarp/block/coarse.py): its kernel, the records' buffer
        self._coarse = None
        if coarse:  # takes_coarse's choice for the job's maps
            options = (*options, COARSE_OPTION)
        program = be.kernel(name, options).program
        self._kernel = cl.Kernel(program, name)  # its own: arguments stay set between calls
        self._global = global_size(self._local, (oh, ow))
        mf = cl.mem_flags
        #: on a CPU the kernel reads the source in place (no upload, at any
        #: size: wrapping the caller's array is cheaper than the copy command,
        #: 30 us of a 0.19 ms 256² RGB call): it never reads past the last
        #: byte of a source of IMAGE_SLACK bytes or more
        self._src_in_place = be.zero_copy and image.nbytes >= IMAGE_SLACK
        self._src = cl.Buffer(be.context, mf.READ_ONLY, 4 if self._src_in_place else image.nbytes + IMAGE_SLACK)
        self._block = None
        self._block_bytes = None
        nbytes = oh * ow * c * image.dtype.itemsize
        self._zero_copy = be.zero_copy and nbytes >= ZERO_COPY_MIN_BYTES
        self._dst = None if self._zero_copy else cl.Buffer(be.context, mf.WRITE_ONLY, max(nbytes, 4))
        #: the last outputs returned, kept to be reused (RECYCLE_MIN_BYTES), oldest first
        self._recycle = RECYCLE_MIN_BYTES is not None and _UNUSED_REFS is not None and \
            nbytes >= RECYCLE_MIN_BYTES
        self._spares = []
        cval4 = np.zeros(1, dtype=cl.cltypes.float4)
        for i, v in enumerate(cval):
            cval4[0][i] = v
        args = [None, self._src, np.int32(w), np.int32(h), self._dst, np.int32(ow), np.int32(oh), cval4[0]]
        #: antialiased: the source's pyramid is the backend's kept one of
        #: these pixels (:attr:`~.backend.Backend.host_pyramids`), set at each call
        self._antialias = antialias
        self._options = options
        #: (a weak reference to the pyramid the kernel's arguments name, its levels built then)
        self._pyramid_set = (lambda: None, 0)
        if antialias:
            args += [None, None, np.int32(0), np.int32(0), np.int32(1), None]
        if COARSE_OPTION in options:
            size, (nx, ny) = records_bytes((oh, ow))
            self._records = cl.Buffer(be.context, mf.READ_WRITE, size)
            self._coarse = cl.Kernel(program, "coarse_pass")
            self._coarse.set_args(None, self._records, np.int32(nx), np.int32(ny))
            self._coarse_global = (nodes_global(self._local[0], nx, ny),)
            args += [self._records, np.int32(nx), np.int32(ny)]
        self._kernel.set_args(*args)

    def set_block(self, block):
        """Point the kernel at float32 ``block``, uploaded only when its
        bytes differ from this job's last block."""
        data = block.tobytes()
        if data == self._block_bytes:
            return
        be = self.backend
        cl = be._cl
        if self._block is None or self._block.size != max(block.nbytes, 4):
            self._block = cl.Buffer(be.context, cl.mem_flags.READ_ONLY, max(block.nbytes, 4))
            self._kernel.set_arg(0, self._block)
            if self._coarse is not None:
                self._coarse.set_arg(0, self._block)
        cl.enqueue_copy(be.queue, self._block, block, is_blocking=False)
        self._block_bytes = data

    def run(self, image, inverse=None):
        """Warp ``image`` (of the job's shape and dtype) by the block set
        last; returns a new array. Antialiased, ``inverse`` (the block's
        map) bounds the pyramid levels built (:func:`levels_needed`; None:
        all)."""
        be = self.backend
        cl, queue = be._cl, be.queue
        if self._src_in_place:  # held until the kernel is done: an argument does not keep its buffer
            src = cl.Buffer(be.context, cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=image)
            self._kernel.set_arg(1, src)
        else:
            src = self._src
            cl.enqueue_copy(queue, self._src, image, is_blocking=False)
        pyramid = be.host_pyramids.get(image) if self._antialias else None
        if pyramid is not None:  # a kept pyramid has the levels of earlier calls: only missing ones are built
            if not pyramid.complete:
                upto = pyramid.top if inverse is None else levels_needed(inverse, self.output_shape, pyramid.top)
                pyramid.build(self._options, src, upto)
            self._set_pyramid(pyramid)
        # a partial pyramid's flag is read with the output (one wait)
        partial = pyramid if pyramid is not None and not pyramid.complete else None
        out = self._launch(queue, partial)
        if partial is not None and partial.needs_more():  # a footprint past the estimate: all levels, again
            partial.build(self._options, src)
            self._set_pyramid(partial)
            out = self._launch(queue)
        if self._src_in_place:
            self._kernel.set_arg(1, self._src)  # the caller's image is not kept
            del src
        return out

    def _output(self):
        """A new output array: one of the job's spares that nothing else
        refers to any more (and whose shape, dtype and flags its caller left
        as they were), else a new one, kept as a spare when recycled."""
        spares = self._spares
        for i in range(len(spares)):
            if self._spare_unused(i):  # counted before any local refers to it
                spare = spares[i]
                if spare.shape == self.out_shape and spare.dtype == self.dtype and spare.flags.c_contiguous \
                        and spare.flags.writeable and not weakref.getweakrefcount(spare):
                    spares.append(spares.pop(i))  # the newest now
                    return spare
                del spare
        out = np.empty(self.out_shape, dtype=self.dtype)
        if self._recycle:
            spares.append(out)
            del spares[:-SPARE_OUTPUTS]  # the oldest, if any, is its holder's now
        return out

    def _spare_unused(self, i):
        """Whether the job's reference is the only one to its spare ``i``
        (the count of :class:`_SpareProbe`, the same expression)."""
        return sys.getrefcount(self._spares[i]) <= _UNUSED_REFS

    def _set_pyramid(self, pyramid):
        """Point the kernel at ``pyramid`` (its arguments follow cval),
        unless it already is, with as many levels."""
        named, built = self._pyramid_set
        if named() is not pyramid or built != pyramid.built:
            for i, arg in enumerate(pyramid.args(), start=PYRAMID_ARG):
                self._kernel.set_arg(i, arg)
            self._pyramid_set = (weakref.ref(pyramid), pyramid.built)

    def _launch(self, queue, pyramid=None):
        """Run the kernel as set into a new output array and read it back
        (and ``pyramid``'s need flag before it: :meth:`DevicePyramid.read_need`)."""
        cl, be = self.backend._cl, self.backend
        out = self._output()
        if self._zero_copy:  # the kernel writes `out` itself
            dst = cl.Buffer(be.context, cl.mem_flags.WRITE_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=out)
            self._kernel.set_arg(4, dst)
        if self._coarse is not None:  # the queue is in order: the records are written before the warp reads them
            cl.enqueue_nd_range_kernel(queue, self._coarse, self._coarse_global, (self._local[0],))
        cl.enqueue_nd_range_kernel(queue, self._kernel, self._global, self._local)
        if pyramid is not None:
            pyramid.read_need()
        if self._zero_copy:
            mapped, event = cl.enqueue_map_buffer(queue, dst, cl.map_flags.READ, 0, out.shape, out.dtype)
            event.wait()
            del mapped
            self._kernel.set_arg(4, None)
        else:
            cl.enqueue_copy(queue, out, self._dst)  # blocking: waits for the kernel and the copy
        return out


class BoundMap:
    """One map bound to the opencl backend (its ``bind``): the block of its
    inverse packed and checked once, a job per kind of call."""

    def __init__(self, backend, transform):
        self.backend = backend
        self.inverse = transform.inverse
        self.block = np.ascontiguousarray(self.inverse.params(), dtype=np.float32)
        self.kind = backend.block_kind(self.block)
        self._jobs = JobCache()

    def warp_image(self, image, output_shape, *, order, mode, cval, antialias=False):
        be = self.backend
        with be._lock:
            job = self._jobs.get(be, image, output_shape, order, mode, cval, antialias, self.kind, self.block)
            job.set_block(self.block)
            return job.run(image, self.inverse)
