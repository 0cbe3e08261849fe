"""Batches on the ``"warp"`` backend: many images (point sets) per launch.

Image batches run the image kernels that single images run (one image is
a batch of one: :func:`fpiwarp.kernels.nvwarp.factory.image_kernel`, the
same stage walk and sampler): the maps are grouped by kind of block (each
stage's core and regions, as the opencl backend groups them) and each
group is one launch over its images, reading block ``which[k]`` of the
group's blocks stacked in one (B, rows, 4) array (rows: the longest
block's; one map for all images is one block that every image reads).
N maps of one kind are one launch; k kinds are k launches. Antialiased
batches and point sets run the kernels that read each stage's kind from
the block (as single calls do), one launch for any mix of kinds;
antialiased batches first build each image's pyramid, one for a stack of
one source (stride 0 between its images: :func:`pyramid_sources`). On the
CPU device every launch is split, like one tall image, into one band of
rows per thread of the backend's pool, and image kernels run a thread per
output row.

Device arrays: :meth:`BatchRunner.warp_arrays` and
:meth:`BatchRunner.map_points_arrays` read and write Warp arrays of the
backend's device in place, any strides (:mod:`fpiwarp.arrays` views
torch, CuPy, JAX and DLPack stacks as such, channels-first ones as
transposed views): contiguous stacks run the row-offset batch kernel,
others the kernel of the same key with ``strided`` (the same stage walk
and sampler on sub-array views). Nothing is chunked or copied.

Host stacks: on the CPU the kernels read and write the caller's numpy
arrays in place (aliased). On CUDA the stack goes in chunks of at most
:data:`CHUNK_BYTES` of input plus output (at least one image), each
copied in, warped and copied out, one after the other (``transfer=
"serial"``, the default) or overlapped (``"pipelined"``:
:class:`PipelinedTransfers`); larger batches are never refused.
"""

import numpy as np

from ...block import describe
from ...block.many import BlockStack, inverses
from ...block.sampling_rules import MODES

#: Bytes of input plus output of one chunk of a host stack on CUDA.
CHUNK_BYTES = 256 << 20
#: Chunk size of the pipelined transfers (small enough that a batch is a
#: few chunks whose copies overlap their neighbours' kernels).
PIPELINE_CHUNK_BYTES = 32 << 20
#: The ways a host stack may reach a CUDA device (``transfer=``).
TRANSFERS = ("serial", "pipelined")

def stacked_blocks(transforms):
    """(N or 1, rows, 4) float32 blocks of ``transforms``, each padded with
    zero rows to the longest; a block no kernel knows raises ValueError."""
    stack = BlockStack.of(transforms)
    stack.groups(lambda kind: None)  # describes each distinct kind once: refuses what no kernel knows
    return stack.array


def kind_groups(transforms, n):
    """The maps of a batch of ``n`` images grouped by kind of block: a list
    of (kind key (each stage's core and regions, as
    :func:`fpiwarp.kernels.nvwarp.factory.kind_key`), blocks (B, rows, 4)
    float32 padded to the longest, images (K,) int32: the group's images,
    image ``images[k]`` warped by block k, or block 0 where B is 1). One
    map gives one group of all ``n`` images reading one block. A block no kernel knows raises
    ValueError (:func:`describe`) first. The blocks are packed together and
    each distinct kind described once (:class:`fpiwarp.block.many.BlockStack`)."""
    from fpiwarp.kernels.nvwarp.factory import kind_key  # noqa: PLC0415 - Warp imported with the backend

    stack = BlockStack.of(transforms)
    if len(stack) == 1:
        return [(kind_key(describe(stack.array[0])), stack.array, np.arange(n, dtype=np.int32))]
    return [(key, stack.take(idx)[1], idx) for key, idx in stack.groups(kind_key)]


def _ranges(n, item_bytes):
    return _ranges_of(n, item_bytes, CHUNK_BYTES)


def _ranges_of(n, item_bytes, limit):
    """[start, stop) ranges of at most ``limit`` bytes (at least one item each) covering ``n`` items."""
    per = max(1, limit // max(item_bytes, 1))
    return [(a, min(n, a + per)) for a in range(0, n, per)]


def row_view(wp, arr):
    """(N·H, W, C) view of an (N, H, W, C) Warp array whose images follow
    each other at H rows' stride (any contiguous stack), else None."""
    n, h, w, c = arr.shape
    s = arr.strides
    if n > 1 and s[0] != h * s[1]:
        return None
    return wp.array(ptr=arr.ptr, dtype=arr.dtype, shape=(n * h, w, c), strides=s[1:], device=arr.device)


def pyramid_sources(stack, rows):
    """The images a batch's pyramid is built from: (Warp array, first row)
    each, from the (N, H, W, C) ``stack`` or its (N·H, W, C) view ``rows``
    (None for strides that have none); one for a stack of one source
    (stride 0 between images: one pyramid for every map)."""
    n, h = stack.shape[0], stack.shape[1]
    if n > 1 and stack.strides[0] == 0:
        return [(stack[0], 0)]
    if rows is not None:
        return [(rows, i * h) for i in range(n)]
    return [(stack[i], 0) for i in range(n)]


class BatchRunner:
    """Batches on one Warp backend (its module ``wp``, device, kernels and
    banded launchers)."""

    def __init__(self, backend, on_cpu=None):
        self.backend = backend
        self.wp, self.device = backend._wp, backend.device
        # whether host stacks are aliased (Warp's CPU device) or copied in chunks (CUDA; ``on_cpu=False``
        # runs that path on the CPU device, for tests)
        self.on_cpu = backend._on_cpu if on_cpu is None else on_cpu
        self.launch = backend._launch  # (kernel, rows, cols, inputs, row_items): the backend's banded launcher
        self.pipelined = None  # the pipelined transfers' streams and buffers, made on first use

    def _array(self, data, dtype):
        """``data`` on the device: aliased on the CPU, copied on CUDA."""
        if self.on_cpu:
            return self.wp.array(data, dtype=dtype, device="cpu", copy=False)
        return self.wp.array(data, dtype=dtype, device=self.device)

    def _which(self, blocks, a, b):
        idx = np.zeros(b - a, dtype=np.int32) if blocks.shape[0] == 1 else np.arange(a, b, dtype=np.int32)
        return self._array(idx, self.wp.int32)

    def warp_batch(self, stack, transforms, output_shape, *, order, mode, cval, antialias=False, transfer=None):
        """(N, rows, cols, C) from a validated (N, H, W, C) numpy stack and
        one map or one map per image (:meth:`warp_arrays` on the CPU's
        aliases of the caller's arrays; on CUDA chunk by chunk, copied in
        and out: ``transfer`` "serial" (default) or "pipelined", see
        :class:`PipelinedTransfers`)."""
        wp = self.wp
        n, h, w, c = stack.shape
        oh, ow = output_shape
        out = np.empty((n, oh, ow, c), dtype=stack.dtype)
        scalar = wp.dtype_from_numpy(stack.dtype)
        options = {"order": order, "mode": mode, "cval": cval, "antialias": antialias}
        if transfer not in (None, *TRANSFERS):
            raise ValueError(f"transfer must be one of {TRANSFERS}, got {transfer!r}")
        if self.on_cpu:
            self.warp_arrays(self._array(stack, scalar), self._array(out, scalar), transforms, **options)
            return out
        if transfer == "pipelined":
            self.pipelined = self.pipelined or PipelinedTransfers(self)
            return self.pipelined.run(stack, out, transforms, options)
        for a, b in _ranges(n, stack[0].nbytes + out[0].nbytes):
            src = wp.array(stack[a:b], dtype=scalar, device=self.device)
            dst = wp.empty((b - a, oh, ow, c), scalar, self.device)
            self.warp_arrays(src, dst, transforms if len(transforms) == 1 else transforms[a:b], **options)
            out[a:b] = dst.numpy()
        return out

    def warp_arrays(self, src, dst, transforms, *, order, mode, cval, antialias=False):
        """Warp (N, H, W, C) Warp array ``src`` into (N, rows, cols, C)
        ``dst``, both on this device with any strides, read and written in
        place: one launch per kind of map (one for antialiased batches).
        Returns ``dst`` (on CUDA without waiting for the kernels)."""
        wp, be = self.wp, self.backend
        n, h, _, c = src.shape
        oh, ow = dst.shape[1], dst.shape[2]
        dtype = np.dtype(wp.dtype_to_numpy(src.dtype))
        cv = np.zeros(4, dtype=np.float32)
        cv[:c] = cval
        rows = (row_view(wp, src), row_view(wp, dst))  # images as row offsets, where the strides allow
        strided = None in rows
        arrays = [src, dst] if strided else list(rows)
        tail = [h, oh]
        sampling = (int(order), MODES.index(mode))
        pyramid = be.no_pyramid
        if antialias:  # one launch for every kind, as for one image
            blocks = stacked_blocks(inverses(transforms))
            groups = [(None, blocks, np.arange(n, dtype=np.int32))]
            pyramid = be.pyramid(pyramid_sources(src, rows[0]), h, src.shape[2], c).args
        else:
            groups = kind_groups(inverses(transforms), n)
        for key, blocks, images in groups:
            spec = (None, None, None) if antialias else (key, *sampling)
            kernel = be.image_kernel(*spec, None if antialias else c, dtype, strided=strided, antialias=antialias)
            inputs = [self._array(blocks, wp.vec4), self._array(images, wp.int32), *arrays, *tail,
                      int(len(blocks) > 1), *sampling, wp.vec4(*cv.tolist()), *pyramid]
            be.launch_image(kernel, len(images) * oh, ow, inputs, self.launch)
        return dst

    def map_points_batch(self, transforms, points):
        """float64 (N, P, 2) point sets mapped by one map or one each."""
        wp = self.wp
        n, p, _ = points.shape
        pts = np.ascontiguousarray(points, dtype=np.float64)
        out = np.empty_like(pts)
        if n == 0 or p == 0:
            return out
        if self.on_cpu:
            self.map_points_arrays(transforms, self._array(pts, wp.vec2d), self._array(out, wp.vec2d))
            return out
        for a, b in _ranges(n, 2 * pts[0].nbytes):
            src = wp.array(pts[a:b], dtype=wp.vec2d, device=self.device)
            dst = wp.empty((b - a, p), wp.vec2d, self.device)
            self.map_points_arrays(transforms if len(transforms) == 1 else transforms[a:b], src, dst)
            out[a:b] = dst.numpy()
        return out

    def map_points_arrays(self, transforms, points, out):
        """(N, P) ``vec2d`` Warp arrays of this device, any strides:
        ``out[i]`` = ``points[i]`` mapped by ``transforms[i]`` (or all by
        one map), in one launch; returns ``out`` (on CUDA without waiting)."""
        n, p = points.shape
        if n and p:
            be = self.backend
            blocks = stacked_blocks(transforms)
            kernel = be.point_kernel(sets=True)
            inputs = [self._array(blocks, self.wp.vec4), self._which(blocks, 0, n), points, out]
            self.launch(kernel, n * p, None, inputs)
        return out


class PipelinedTransfers:
    """Host stacks through a CUDA device with copies overlapping kernels:
    chunks of :data:`PIPELINE_CHUNK_BYTES` go through two slots, each a
    stream with pinned host staging and device buffers for one chunk in
    and out (kept across calls while the shapes hold). Chunk i is copied
    into its slot's pinned buffer (a host memcpy), then uploaded, warped
    and downloaded on the slot's stream, while the other slot's chunk
    runs on the other stream; a slot is drained (waited for, its pinned
    output copied out) before it is reused. Results equal the serial
    path's (the same :meth:`BatchRunner.warp_arrays`)."""

    def __init__(self, runner):
        self.runner, self.key, self.slots = runner, None, []

    def _slots(self, per, image, output, scalar):
        wp, device = self.runner.wp, self.runner.device
        key = (per, image, output, scalar)
        if key != self.key:
            self.slots = [{"stream": wp.Stream(device),
                           "pin_in": wp.empty((per, *image), dtype=scalar, device="cpu", pinned=True),
                           "pin_out": wp.empty((per, *output), dtype=scalar, device="cpu", pinned=True),
                           "src": wp.empty((per, *image), dtype=scalar, device=device),
                           "dst": wp.empty((per, *output), dtype=scalar, device=device),
                           "pending": None} for _ in range(2)]
            self.key = key
        return self.slots

    def _drain(self, slot, out):
        """Wait for the slot's last chunk and copy its output out of pinned memory."""
        if slot["pending"] is not None:
            event, a, b = slot["pending"]
            self.runner.wp.synchronize_event(event)
            out[a:b] = slot["pin_out"].numpy()[: b - a]
            slot["pending"] = None

    def run(self, stack, out, transforms, options):
        """``out`` (N, rows, cols, C) from ``stack`` (N, H, W, C), pipelined."""
        wp = self.runner.wp
        n = stack.shape[0]
        chunks = _ranges_of(n, stack[0].nbytes + out[0].nbytes, PIPELINE_CHUNK_BYTES)
        per = chunks[0][1] - chunks[0][0]
        slots = self._slots(per, stack.shape[1:], out.shape[1:], wp.dtype_from_numpy(stack.dtype))
        for i, (a, b) in enumerate(chunks):
            slot = slots[i % 2]
            self._drain(slot, out)
            m, stream = b - a, slot["stream"]
            slot["pin_in"].numpy()[:m] = stack[a:b]
            wp.copy(slot["src"][:m], slot["pin_in"][:m], stream=stream)
            with wp.ScopedStream(stream):
                self.runner.warp_arrays(slot["src"][:m], slot["dst"][:m],
                                        transforms if len(transforms) == 1 else transforms[a:b], **options)
            wp.copy(slot["pin_out"][:m], slot["dst"][:m], stream=stream)
            slot["pending"] = (stream.record_event(), a, b)
        for slot in slots:
            self._drain(slot, out)
        return out
