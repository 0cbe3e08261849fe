"""Batches on the "opencl" backend: many images (or point sets) per launch.

The kernels of ``kernels/fpiwarp.cl`` built with ``-DFW_BATCH`` take a
third launch dimension: item z reads block z of a buffer of stacked
parameter blocks and image ``which[z]`` of a stacked source and output
(see ``FW_BATCH_SELECT`` there). Everything else is the single image's
code, so a batch equals the loop of :meth:`Backend.warp_image` bit for
bit.

Newton maps
-----------
A map with a Newton core takes the coarse pass as its single warp does
(:class:`.prepared.ClJob`, fpiwarp/block/coarse.py): each launch of such
maps is preceded by one ``coarse_pass`` launch over the nodes of all its
images (launch dimension 2 again), into one records buffer kept across
batches, item z's records from node z nx ny on, which warp_image's item z
reads. The backend's queue is in order: the records are written before
the warp reads them and rewritten only after.

Kinds of map
------------
A program is specialised for one kind of map (:func:`kind_options`), so
the maps of a batch are grouped by kind and each group runs as one
launch: a batch whose maps are all of one kind (one map for all, or N
FPIs of the same number of control points) is one launch; a batch
mixing k kinds is k launches. Nothing is refused for mixing kinds.

Bounds
------
A launch reads its blocks from ``__constant`` memory, so it holds at most
``max_constant_buffer_size // block bytes`` maps (a larger group is split
into launches of that many). The images go through device buffers in
chunks of at most :data:`CHUNK_BYTES` (and the device's
``max_mem_alloc_size``), never fewer than one image, so a batch is never
refused for its size if each image passes :mod:`fpiwarp.validation`.

Transfers
---------
On a device sharing host memory (PoCL on a CPU) the kernels read the
caller's stack and write its output in place (``USE_HOST_PTR``), a launch
per chunk of :data:`CHUNK_BYTES` (:func:`_run_in_place`). Antialiased
batches, non-contiguous stacks and images of under 4 bytes write in place
but have their sources copied chunk by chunk,
:data:`ZERO_COPY_CHUNK_BYTES_PER_UNIT` per compute unit (at least one
image), so that each launch's sources are in the caches. On other devices (a GPU) the batch goes in
chunks of :data:`PIPELINE_CHUNK_BYTES` through two sets of device buffers
and three queues, so that the upload of chunk i + 1 and the download of
chunk i - 1 overlap the kernels of chunk i (``transfer="pipelined"``;
``"serial"`` does the same on one queue, for comparison). No pinned
staging buffers yet: on a GPU the driver stages pageable numpy memory.

Device arrays
-------------
:class:`BatchLaunch` enqueues a batch's kernels on any device buffers
(the source from image a on, the output likewise): :func:`warp_arrays`
and :func:`map_points_arrays` run them on ``pyopencl.array.Array`` s
in place (:mod:`fpiwarp.arrays` batches), :func:`warp_batch` is the
host-array front end.
"""

import weakref

import numpy as np

from ...block import describe
from ...block.many import BlockStack, inverses
from .prepared import COARSE_OPTION, IMAGE_SLACK, nodes_global, records_bytes, takes_coarse
from .pyramid import DevicePyramid
from .tiles import global_size, tiled_program

#: Bytes of input plus output one chunk of a batch holds at most (each
#: chunk holds at least one image).
CHUNK_BYTES = 256 << 20
#: On a CPU device sharing host memory, bytes of input plus output per
#: launch and compute unit: a launch's sources stay in the cores' caches
#: while the kernel gathers from them. 64 x 512² RGB uint8, 64 maps, best
#: of 7 interleaved in one run: chunks of 2 MiB (one image) 113-130 ms,
#: 4 MiB 121-178 ms, 8-256 MiB 213-356 ms, the loop of warp_image
#: 178-200 ms (PoCL 3.1, pthread-skylake-avx512, 2 cores, 1 MiB L2 each).
#: Again with the batch kernels' group-id selection (fpiwarp.cl, FW_BATCH),
#: process CPU time, best of 11 interleaved (load 4-5): 1 image 114 ms,
#: 2 images 141 ms, 4 images 160 ms, 64 images 165 ms.
ZERO_COPY_CHUNK_BYTES_PER_UNIT = 1 << 20
#: Chunk size of the pipelined transfers: small enough that a batch is a
#: few chunks whose copies overlap the kernels of their neighbours.
PIPELINE_CHUNK_BYTES = 32 << 20
#: The ways a batch may reach the device (see the module docstring).
TRANSFERS = ("zero_copy", "pipelined", "serial")


_KEPT = weakref.WeakKeyDictionary()  # backend -> {role: Buffer}: device buffers kept across batches


def kept_buffer(backend, role, nbytes, flags):
    """A device buffer of at least ``nbytes`` for ``role``, kept across
    calls on ``backend`` (a larger need replaces it), as the backend
    keeps its own: allocating and first touching a chunk's buffer costs
    about as much as copying into it."""
    cl = _cl()
    kept = _KEPT.setdefault(backend, {})
    buf = kept.get(role)
    if buf is None or buf.size < nbytes:
        kept.pop(role, None)
        buf = kept[role] = cl.Buffer(backend.context, flags, max(nbytes, 4))
    return buf


def _cl():
    import pyopencl as cl  # noqa: PLC0415 - optional dependency, imported lazily

    return cl


def block_groups(transforms, n, kind_options):
    """Stacked float32 blocks by kind: a list of (kind options, block rows
    (0: one block shared by all images), blocks (k, rows, 4), image
    indices (k,) int32), the kind named by ``kind_options`` (the
    backend's). One map gives one group of all ``n`` images.
    A block no kernel knows raises ValueError (:func:`describe`) first.
    The blocks are packed together and each distinct kind described
    once (:class:`fpiwarp.block.many.BlockStack`)."""
    stack = BlockStack.of(transforms)
    if len(stack) == 1:
        return [(kind_options(describe(stack.array[0])), 0, stack.array, np.arange(n, dtype=np.int32))]
    return [(kind, *stack.take(idx), idx) for kind, idx in stack.groups(kind_options)]


def chunk_ranges(n, item_bytes, limit):
    """[start, stop) ranges of at most ``limit`` bytes of ``item_bytes``
    items each (at least one item per range) covering ``n`` items."""
    per = max(1, int(limit // max(item_bytes, 1)))
    return [(a, min(n, a + per)) for a in range(0, n, per)]


def constant_bytes(backend):
    """Bytes of ``__constant`` memory one launch's blocks may take."""
    return backend.device.max_constant_buffer_size


def _launches(backend, groups, a, b):
    """(kind options, block rows, blocks, chunk-relative image indices) of
    the launches for images [a, b): each kind's images in the chunk, split
    so that a launch's blocks fit the device's constant memory."""
    cap = constant_bytes(backend)
    for kind, rows, blocks, images in groups:
        keep = (images >= a) & (images < b)
        if not keep.any():
            continue
        sel, idx = (blocks, images[keep]) if rows == 0 else (blocks[keep], images[keep])
        per = len(idx) if rows == 0 else max(1, cap // (rows * 16))
        for s in range(0, len(idx), per):
            yield kind, rows, sel if rows == 0 else sel[s:s + per], (idx[s:s + per] - a).astype(np.int32)


def _small_buffer(cl, context, array):
    mf = cl.mem_flags
    return cl.Buffer(context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(array))


def default_transfer(backend):
    """"zero_copy" on a device sharing host memory, else "pipelined"."""
    return "zero_copy" if backend.zero_copy else "pipelined"


class BatchLaunch:
    """The kernels of one batch, ready to enqueue on device buffers.

    ``stack_shape`` (N, H, W, C) and ``dtype`` describe the images,
    ``transforms`` the user's maps (one or N; the kernels read their
    inverses). :meth:`enqueue` runs images [a, b) from any device buffer
    holding them from image a on (``src``, with ``backend.image_slack``
    bytes to spare past the last) into one for their outputs (``dst``):
    host arrays, kept buffers or a caller's device arrays alike.
    """

    def __init__(self, backend, stack_shape, dtype, transforms, output_shape, *, order, mode, cval,
                 antialias=False):
        cl = self.cl = _cl()
        n, self.h, self.w, c = stack_shape
        self.backend, (self.oh, self.ow) = backend, output_shape
        self.groups = block_groups(inverses(transforms), n, backend.kind_options)
        self.sampling = (dtype, c, order, mode, self.ow, antialias)
        self.cval4 = cl.cltypes.make_float4(*(list(cval) + [0.0] * (4 - c)))
        self.keep = []  # the launches' block and index buffers, alive as long as this object
        self.antialias = bool(antialias)
        self.pyramid = None  # antialiased: the pyramids of a chunk's images, rebuilt for each chunk

    def enqueue(self, queue, src, dst, a, b, wait_for=None):
        """Enqueue the launches of images [a, b) (one per kind, and per
        constant-memory load of blocks) after ``wait_for``; their events."""
        cl, be, events = self.cl, self.backend, []
        sizes = (np.int32(self.w), np.int32(self.h), dst, np.int32(self.ow), np.int32(self.oh), self.cval4)
        for kind, rows, blocks, which, coarse in self._by_choice(_launches(be, self.groups, a, b)):
            name, options, local = tiled_program(be, *self.sampling, kind)  # the single warp's tiles
            if coarse:  # as the single warp's job (prepared.ClJob)
                options = (*options, COARSE_OPTION)
            kern = be.kernel(name, (*options, "-DFW_BATCH=1"))
            extra = self._pyramid_args(queue, src, options, a, b, wait_for) if self.antialias else ()
            self.keep.append((_small_buffer(cl, be.context, blocks), _small_buffer(cl, be.context, which)))
            if coarse:
                node = be.kernel("coarse_pass", (*options, "-DFW_BATCH=1"))  # of warp_image's program
                extra = self._coarse_pass(queue, node, *self.keep[-1], rows, len(which), local[0])
            kern.set_args(self.keep[-1][0], src, *sizes, *extra, self.keep[-1][1], np.int32(rows))
            events.append(cl.enqueue_nd_range_kernel(queue, kern, (*global_size(local, (self.oh, self.ow)), len(which)),
                                                     (*local, 1), wait_for=wait_for))
        return events

    def _by_choice(self, launches):
        """The launches split by whether their maps take the coarse pass
        (:func:`~.prepared.takes_coarse`, per map as their single warps):
        (kind, rows, blocks, which, coarse), the maps taking it first."""
        shape = (self.oh, self.ow)
        for kind, rows, blocks, which in launches:
            if rows == 0:  # one block for all the images
                yield kind, rows, blocks, which, takes_coarse(kind, self.antialias, blocks[0], shape)
                continue
            coarse = np.array([takes_coarse(kind, self.antialias, blk, shape) for blk in blocks], bool)
            for choice in (True, False):
                if (coarse == choice).any():
                    yield kind, rows, blocks[coarse == choice], which[coarse == choice], choice

    def _coarse_pass(self, queue, node, blocks, which, rows, count, local_x):
        """Enqueue the coarse pass (kernel ``node``) of a launch's ``count`` maps (their
        ``blocks`` buffer, ``rows`` rows each) into one kept records buffer,
        item z's records from node z nx ny on; warp_image's records
        arguments. The queue is in order: the records are written before
        the launch's warp reads them, and after the last one read them."""
        size, (nx, ny) = records_bytes((self.oh, self.ow), count)
        records = kept_buffer(self.backend, "coarse", size, self.cl.mem_flags.READ_WRITE)
        node.set_args(blocks, records, np.int32(nx), np.int32(ny), which, np.int32(rows))
        self.cl.enqueue_nd_range_kernel(queue, node, (nodes_global(local_x, nx, ny), 1, count), (local_x, 1, 1))
        return records, np.int32(nx), np.int32(ny)

    def _pyramid_args(self, queue, src, options, a, b, wait_for):
        """The pyramid arguments of images [a, b) in ``src``, their levels
        enqueued on ``queue`` once per chunk (in order before its kernels)."""
        c = self.sampling[1]
        if self.pyramid is None or self.pyramid.count < b - a:
            self.pyramid = DevicePyramid(self.backend, self.h, self.w, c, count=b - a)
        if self.pyramid.chunk != (a, b):
            self.pyramid.reset()
            self.pyramid.build(options, src, queue=queue, wait_for=wait_for, count=b - a)
            self.pyramid.chunk = (a, b)
        return self.pyramid.args()


def warp_batch(backend, stack, transforms, output_shape, *, order, mode, cval, antialias=False, transfer=None):
    """Warp a validated (N, H, W, C) stack by one map or one per image
    (``transforms``: the user's maps; the kernels read their inverses);
    (N, rows, cols, C) of the stack's dtype. Call under the backend's lock."""
    cl = _cl()
    n = stack.shape[0]
    out = np.empty((n, *output_shape, stack.shape[3]), dtype=stack.dtype)
    transfer = transfer or default_transfer(backend)
    if transfer not in TRANSFERS:
        raise ValueError(f"transfer must be one of {TRANSFERS}, got {transfer!r}")
    job = BatchLaunch(backend, stack.shape, stack.dtype, transforms, output_shape, order=order, mode=mode, cval=cval,
                      antialias=antialias)
    chunks, in_place = chunk_plan(backend, stack, out[0].nbytes, transfer, antialias)
    if in_place:
        _run_in_place(cl, backend, stack, out, chunks, job.enqueue)
    elif transfer == "zero_copy":
        _run_zero_copy(cl, backend, stack, out, chunks, job.enqueue)
    else:
        _run_copies(cl, backend, stack, out, chunks, job.enqueue, transfer == "pipelined")
    return out


def warp_arrays(backend, src, dst, transforms, *, order, mode, cval, antialias=False):
    """Enqueue the warp of (N, H, W, C) ``pyopencl.array.Array`` ``src``
    (C-contiguous, ``backend.image_slack`` bytes to spare in its buffer)
    into (N, rows, cols, C) ``dst`` on the backend's queue, in place: one
    launch per kind of map, no chunks, no copies. Returns ``dst`` without
    waiting (takes the backend's lock)."""
    with backend._lock:
        job = BatchLaunch(backend, src.shape, src.dtype, transforms, dst.shape[1:3], order=order, mode=mode,
                          cval=cval, antialias=antialias)
        job.enqueue(backend.queue, src.data, dst.data, 0, src.shape[0])
    return dst


def chunk_plan(backend, stack, out_bytes, transfer, antialias=False):
    """How :func:`warp_batch` goes through ``stack`` (outputs of ``out_bytes``
    each) with ``transfer``: ([start, stop) ranges of its chunks, whether the
    kernels read the stack in place)."""
    limit = min(CHUNK_BYTES if transfer == "zero_copy" else PIPELINE_CHUNK_BYTES, backend.device.max_mem_alloc_size)
    in_place = transfer == "zero_copy" and reads_in_place(stack, antialias)
    if transfer == "zero_copy" and not in_place:
        limit = min(limit, ZERO_COPY_CHUNK_BYTES_PER_UNIT * max(1, backend.device.max_compute_units))
    return chunk_ranges(len(stack), stack[0].nbytes + out_bytes, limit), in_place


def reads_in_place(stack, antialias):
    """Whether a zero-copy batch reads ``stack`` in place (:func:`_run_in_place`):
    a C-contiguous stack of images of IMAGE_SLACK bytes or more (the
    kernel then never reads past an image's last byte, fpiwarp_map.h's
    FW_INTERIOR_TAIL), not antialiased (whose chunks build their pyramids
    in float32 beside them: small chunks keep those small)."""
    return stack.flags.c_contiguous and stack[0].nbytes >= IMAGE_SLACK and not antialias


def _run_in_place(cl, backend, stack, out, chunks, launch):
    """The kernels read the caller's stack and write its output in place
    (USE_HOST_PTR), a launch per chunk of :data:`CHUNK_BYTES` (so one for
    most batches), one wait at each chunk's end. Against the copied small
    chunks of :func:`_run_zero_copy`, best of 7-15 interleaved rounds in one
    process (PoCL 3.1, pthread-skylake-avx512, 2 cores, quiet): 64 x 512²
    RGB uint8 with 64 maps 74-82 against 80-89 ms (the loop of warp_image
    110-127 ms), 64 x 512² with one map 72 against 87 ms, 8 x 1080p 61
    against 74 ms, 256 x 128² 25.9 against 27.5 ms. Reading in place image
    by image was slower than the copies (99-122 ms at 64 x 512²): the
    waits between launches, not the cold source, cost the time."""
    for a, b in chunks:
        src = cl.Buffer(backend.context, cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=stack[a:b])
        _launch_into(cl, backend, src, out, a, b, launch)
    backend.queue.finish()


def _launch_into(cl, backend, src, out, a, b, launch):
    """The launches of images [a, b) from ``src`` writing ``out[a:b]`` in
    place (USE_HOST_PTR), made visible by a map; waits for them."""
    dst = cl.Buffer(backend.context, cl.mem_flags.WRITE_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=out[a:b])
    launch(backend.queue, src, dst, a, b, None)
    mapped, event = cl.enqueue_map_buffer(backend.queue, dst, cl.map_flags.READ, 0, out[a:b].shape, out.dtype)
    event.wait()
    del mapped


def _run_zero_copy(cl, backend, stack, out, chunks, launch):
    """Each chunk copied into one kept device buffer; the kernels write the
    caller's output in place (USE_HOST_PTR), made visible by a map.

    The chunks are small (:data:`ZERO_COPY_CHUNK_BYTES_PER_UNIT`): the copy
    leaves a chunk in the caches, where the kernel's gathers find it. One
    copy of the whole stack (50 MB for 64 images of 512² RGB) streamed it
    through the caches before the kernel read it again from memory: 0.53-0.68×
    the loop of warp_image, whose per-image copy then stayed in the cache.
    Reading the caller's stack in place was then no better than the loop
    (0.7-1.2×, a loaded machine); since the loop reads its sources in place
    too, the batches that can do so read in place (:func:`_run_in_place`),
    and this path is left to those that cannot."""
    mf, queue = cl.mem_flags, backend.queue
    per = chunks[0][1] - chunks[0][0]
    src = kept_buffer(backend, "in0", per * stack[0].nbytes + backend.image_slack, mf.READ_ONLY)
    for a, b in chunks:
        cl.enqueue_copy(queue, src, stack[a:b])
        _launch_into(cl, backend, src, out, a, b, launch)
    queue.finish()


def _run_copies(cl, backend, stack, out, chunks, launch, pipelined):
    """Chunks through two sets of device buffers: uploads, kernels and
    downloads on three queues ordered by events (pipelined), or all on
    the backend's queue one after the other."""
    mf, ctx = cl.mem_flags, backend.context
    per = chunks[0][1] - chunks[0][0]
    in_bytes, out_bytes = per * stack[0].nbytes + backend.image_slack, per * out[0].nbytes
    slots = [(kept_buffer(backend, f"in{k}", in_bytes, mf.READ_ONLY), kept_buffer(backend, f"out{k}", out_bytes,
                                                                                  mf.WRITE_ONLY))
             for k in range(2 if pipelined else 1)]
    up, down = (cl.CommandQueue(ctx), cl.CommandQueue(ctx)) if pipelined else (backend.queue, backend.queue)
    pending = [([], []) for _ in slots]  # per slot: (its last kernels, its last download)
    for i, (a, b) in enumerate(chunks):
        s = i % len(slots)
        src, dst = slots[s]
        kernels_before, download_before = pending[s]
        ev_up = cl.enqueue_copy(up, src, stack[a:b], is_blocking=False, wait_for=kernels_before or None)
        ev_k = launch(backend.queue, src, dst, a, b, [ev_up, *download_before])
        ev_down = cl.enqueue_copy(down, out[a:b], dst, is_blocking=False, wait_for=ev_k)
        pending[s] = (ev_k, [ev_down])
    for queue in {up, down, backend.queue}:
        queue.finish()


def map_points_batch(backend, transforms, points):
    """Map float64 (N, P, 2) ``points[i]`` by ``transforms[i]`` (or all by
    one map); float64 (N, P, 2). One launch per kind of map (and per
    constant-memory load of blocks, and per :data:`CHUNK_BYTES` of point
    sets). Call under the backend's lock."""
    cl = _cl()
    n, p, _ = points.shape
    dtype = np.float64 if backend.has_fp64 else np.float32
    pts = np.ascontiguousarray(points, dtype=dtype)
    out = np.empty_like(pts)
    if p == 0 or n == 0:
        return out.astype(np.float64)
    groups = block_groups(transforms, n, backend.kind_options)
    limit = min(CHUNK_BYTES, backend.device.max_mem_alloc_size)
    mf, ctx = cl.mem_flags, backend.context
    for a, b in chunk_ranges(n, pts[0].nbytes, limit):
        if backend.zero_copy:
            src = cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=pts[a:b])
            dst = cl.Buffer(ctx, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=out[a:b])
        else:
            src = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=pts[a:b])
            dst = cl.Buffer(ctx, mf.WRITE_ONLY, out[a:b].nbytes)
        keep = _enqueue_points(cl, backend, groups, src, dst, p, a, b)  # noqa: F841 - alive until read
        if backend.zero_copy:
            mapped, event = cl.enqueue_map_buffer(backend.queue, dst, cl.map_flags.READ, 0, out[a:b].shape, out.dtype)
            event.wait()
            del mapped
        else:
            cl.enqueue_copy(backend.queue, out[a:b], dst)
        backend.queue.finish()
    return out.astype(np.float64, copy=False)


def map_points_arrays(backend, transforms, points, out):
    """Enqueue the map of (N, P, 2) ``pyopencl.array.Array`` ``points``
    (C-contiguous, the device's point dtype) into ``out`` of the same
    shape on the backend's queue, in place: one launch per kind of map.
    Returns ``out`` without waiting (takes the backend's lock)."""
    n, p, _ = points.shape
    if n and p:
        groups = block_groups(transforms, n, backend.kind_options)
        with backend._lock:
            _enqueue_points(_cl(), backend, groups, points.data, out.data, p, 0, n)
    return out


def _enqueue_points(cl, backend, groups, src, dst, p, a, b):
    """Enqueue map_points over point sets [a, b) held in ``src`` from set a
    on: one launch per kind; returns the launches' small buffers."""
    options = backend.point_options + (f"-DFW_LOCAL_X={backend.local_x}", "-DFW_BATCH=1")
    total = -(-p // backend.local_x) * backend.local_x
    keep = []
    for kind, rows, blocks, which in _launches(backend, groups, a, b):
        kern = backend.kernel("map_points", kind + options)
        keep.append((_small_buffer(cl, backend.context, blocks), _small_buffer(cl, backend.context, which)))
        kern.set_args(keep[-1][0], src, dst, np.int32(p), keep[-1][1], np.int32(rows))
        cl.enqueue_nd_range_kernel(backend.queue, kern, (total, 1, len(which)), (backend.local_x, 1, 1))
    return keep
