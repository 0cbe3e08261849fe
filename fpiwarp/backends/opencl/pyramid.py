"""The source pyramid of the ``"opencl"`` backend's antialiased warps.

The levels >= 1 of :mod:`fpiwarp.sampling.pyramid` (the numpy reference:
sizes, 2 × 2 means with clamped indices) are built on the device by the
kernels ``pyramid_first`` (level 1, from the source in its own type) and
``pyramid_next`` (each further level from the one before, float32), all in
one float32 buffer: level k's texels from element ``levels[k].x`` on,
``levels[k].y`` × ``levels[k].z`` texels of C channels. ``warp_image_aa``
reads them (see fpiwarp.cl). A stack of sources (a batch) gets one
pyramid per image, :attr:`DevicePyramid.items` elements apart.

A pyramid may be built up to a level (:meth:`DevicePyramid.build`): a
single warp builds the levels its footprints need by
:func:`levels_needed`'s estimate, and the kernel flags a pixel that needs
one past them (``need``), which the caller then builds before running the
kernel again; a pyramid of a source that cannot change (a prepared job's
own copy) is built once, whole, and reused by every warp of it.
"""

import numpy as np

from ...sampling.antialias import footprint_edges, pyramid_levels, tap_counts
from ...sampling.pyramid import level_sizes

#: Output pixels per axis where :func:`levels_needed` samples the footprint.
ESTIMATE_GRID = 17
#: :func:`levels_needed` counts footprints this much longer than those on its
#: grid, for what lies between its points: a level more than the grid's
#: (a margin of 2) built level 1 at every FPI shrink of 1/2, which reads only
#: level 0 (a third of the antialiased call's time at 1/8).
ESTIMATE_MARGIN = 1.25
#: Work-group of the pyramid kernels (texels of a level, x by y): on PoCL
#: a group costs a fixed overhead, so groups are large.
HALVE_LOCAL = (128, 4)


def levels_needed(inverse, output_shape, top):
    """The coarsest pyramid level (0..``top``) an antialiased warp through
    ``inverse`` (output -> source) into ``output_shape`` reads, estimated on
    an ESTIMATE_GRID² grid of its pixels from footprints ESTIMATE_MARGIN
    times theirs (a kernel needing more says so: see the module docstring)."""
    rows, cols = output_shape
    ys, xs = np.meshgrid(np.linspace(0, rows - 1, ESTIMATE_GRID), np.linspace(0, cols - 1, ESTIMATE_GRID),
                         indexing="ij")
    with np.errstate(all="ignore"):
        try:
            _, fz, fzb = inverse.wirtinger(xs.ravel() + 1j * ys.ravel())
        except (ArithmeticError, ValueError):  # a map the grid cannot evaluate: every level
            return top
    ex, ey = footprint_edges(fz, fzb)
    ex, ey = ex * ESTIMATE_MARGIN, ey * ESTIMATE_MARGIN
    multi = (tap_counts(ex) > 1) | (tap_counts(ey) > 1)
    if not multi.any():
        return 0
    k, u = pyramid_levels(ex[multi], ey[multi], top)
    return int(min(top, (k + (u > 0)).max()))


class DevicePyramid:
    """Device buffers for the levels >= 1 of ``count`` sources of h × w × c
    (their level table and a flag the kernel sets when it needs more
    levels than were built), built by :meth:`build`."""

    def __init__(self, backend, h, w, c, count=1):
        cl = backend._cl
        self.backend = backend
        self.sizes = level_sizes(h, w)
        self.top = len(self.sizes) - 1
        table = np.zeros((len(self.sizes), 4), dtype=np.int32)
        table[0] = (0, w, h, 0)
        offset = 0
        for k, (lh, lw) in enumerate(self.sizes[1:], start=1):
            table[k] = (offset, lw, lh, 0)
            offset += lh * lw * c
        self.table, self.channels, self.count = table, c, count
        self.items = max(offset, 1)
        mf = cl.mem_flags
        self.buffer = cl.Buffer(backend.context, mf.READ_WRITE, 4 * self.items * count)
        self.levels = cl.Buffer(backend.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=table)
        self.need = cl.Buffer(backend.context, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=np.zeros(1, np.int32))
        self.built = 0
        self.chunk = None  # a batch's: the images [a, b) built last
        self._flag = self._flag_read = None  # the flag's host copy and its pending read (read_need)

    def build(self, options, src, upto=None, queue=None, src_items=None, wait_for=None, count=None):
        """Enqueue the levels built + 1 .. ``upto`` (default: all) of the
        sources in ``src`` (a device buffer, one image per ``src_items``
        elements; the first ``count``, default all) with the kernels of the
        program of ``options`` on ``queue`` (default: the backend's), the
        first after ``wait_for``."""
        be = self.backend
        cl, queue = be._cl, queue or be.queue
        upto = self.top if upto is None else min(int(upto), self.top)
        (h, w), c = self.sizes[0], self.channels
        for k in range(self.built + 1, upto + 1):
            (ph, pw), (lh, lw) = self.sizes[k - 1], self.sizes[k]
            if k == 1:
                kern, source, source_at = be.kernel("pyramid_first", options), src, 0
                source_items = h * w * c if src_items is None else src_items
            else:
                kern, source, source_at, source_items = be.kernel("pyramid_next", options), self.buffer, \
                    int(self.table[k - 1, 0]), self.items
            kern.set_args(source, np.int32(source_at), np.int32(pw), np.int32(ph), self.buffer,
                          np.int32(self.table[k, 0]), np.int32(lw), np.int32(lh), np.int32(source_items),
                          np.int32(self.items))
            gx, gy = min(HALVE_LOCAL[0], -(-lw // 8) * 8), min(HALVE_LOCAL[1], lh)
            cl.enqueue_nd_range_kernel(queue, kern, (-(-lw // gx) * gx, -(-lh // gy) * gy, count or self.count),
                                       (gx, gy, 1), wait_for=wait_for if k == self.built + 1 else None)
        self.built = max(self.built, upto)

    def reset(self):
        """Forget the levels built (the source changed)."""
        self.built = 0
        self.chunk = None

    def args(self):
        """warp_image_aa's pyramid arguments (after cval): the levels, the
        level table, top, built, the elements per image and the flag."""
        return (self.buffer, self.levels, np.int32(self.top), np.int32(self.built), np.int32(self.items),
                self.need)

    @property
    def complete(self):
        """Whether every level is built: no kernel then asks for more (its
        levels end at top), nor needs :func:`levels_needed`'s estimate."""
        return self.built >= self.top

    def read_need(self):
        """Enqueue the read of the flag the kernels enqueued before set
        (without waiting: an output read after it, on the same in-order
        queue, waits for both); :meth:`needs_more` then answers."""
        cl = self.backend._cl
        self._flag = np.zeros(1, np.int32)
        self._flag_read = cl.enqueue_copy(self.backend.queue, self._flag, self.need, is_blocking=False)

    def needs_more(self):
        """Whether the last kernels asked for levels past :attr:`built`
        (waits for them, or for the read :meth:`read_need` enqueued);
        clears the flag."""
        if self._flag_read is None:
            self.read_need()
        self._flag_read.wait()
        flag, self._flag_read = self._flag, None
        if flag[0]:
            self.backend._cl.enqueue_copy(self.backend.queue, self.need, np.zeros(1, np.int32))
        return bool(flag[0])

