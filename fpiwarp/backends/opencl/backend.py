"""The "opencl" backend: the parameter block evaluated by OpenCL kernels.

pyopencl runs ``kernels/fpiwarp.cl`` (math in ``kernels/fpiwarp_map.h``)
on one OpenCL device: PoCL on a CPU, or any OpenCL GPU. The map's
parameter block (:mod:`fpiwarp.block`) goes to the device as a
``__constant float4`` buffer. Programs are built once per context and set
of build options and cached, never per set of map values: the options name
the kind of map (each stage's header row: core, number of TPS centers,
regions, Newton steps, see :func:`kind_options`; a block no kernel knows is
refused by :func:`fpiwarp.block.describe` before anything is launched) and,
for images, the kind
of sampling (dtype, channels, order, border mode). Knowing the kind at
build time unrolls the stage loop, which lets PoCL vectorize the map
across work-items; on CPUs the sampling is written in 8-lane vector types
(:data:`VECTOR_LANES_CPU`), as PoCL does not vectorize it by itself.
Kernel objects are fetched once per program; device buffers are reused
across calls of the same shape.

Choosing a device
-----------------
The environment variable ``FPIWARP_OPENCL_DEVICE`` (or the ``device``
argument of :class:`Backend`) is a case-insensitive substring matched
against ``"platform name: device name"`` and, to tell apart two
platforms of the same name (Debian's PoCL beside the PyPI one), against
the platform's version string. Without it the choice is deterministic:
GPUs first, then accelerators, then CPUs, each sorted by platform name,
platform version and device name.
"""

import os
import threading

import numpy as np

from ... import resources
from ...block import describe
from ...block.codegen import opencl_preamble
from ...block.sampling_rules import MODES
from ...errors import BackendUnavailableError, SizeLimitError
from ...sampling.pyramid import SourcePyramids
from ..lru import LruCache
from . import build_cache
from .prepared import (
    COARSE_OPTION,
    IMAGE_SLACK,
    ZERO_COPY_MIN_BYTES,
    BoundMap,
    JobCache,
    nodes_global,
    records_bytes,
    takes_coarse,
)
from .pyramid import DevicePyramid
from .tiles import global_size, tiled_program

ENV_DEVICE = "FPIWARP_OPENCL_DEVICE"
_SOURCE, _HEADER = "opencl/fpiwarp.cl", "opencl/fpiwarp_map.h"
_CTYPES = {np.dtype(np.uint8): "uchar", np.dtype(np.uint16): "ushort", np.dtype(np.float32): "float"}
#: Work-group width (pixels of one row, or points) on CPUs and on other
#: devices, capped by the device's limit. On PoCL every work-group costs a
#: fixed overhead, so CPUs get large groups; GPUs prefer small ones.
LOCAL_X_CPU, LOCAL_X_OTHER = 1024, 128
#: warp_image's groups are one row wide at most: a narrower output takes the
#: smallest of these widths that covers a row (each a build of its own), so
#: that a 64 px row does not run 960 padding work-items.
NARROW_LOCAL_X = (64, 256)
#: Wider rows get groups of a multiple of this width (see :func:`launch_width`);
#: each width is a build of its own, so widths come in steps.
GROUP_STEP = 64
#: On CPUs warp_image samples 8 pixels per work-item in 8-lane vector types
#: (AVX registers): PoCL does not vectorize the sampling across work-items.
#: A device whose native float vector is 16 wide runs 16 where the tuner
#: measured them faster (:func:`.tuning.lanes_for`). map_points reads 8
#: points per work-item.
VECTOR_LANES_CPU = 8
def _import_cl():
    import pyopencl as cl  # noqa: PLC0415 - optional dependency, imported lazily
    import pyopencl.cltypes  # noqa: F401, PLC0415 - make_float4

    return cl


def _device_label(platform, device):
    return f"{platform.name.strip()}: {device.name.strip()}"


def list_devices():
    """All (label, platform, device) triples in the deterministic default
    order (GPUs, accelerators, CPUs; then platform name, version, device)."""
    cl = _import_cl()
    kinds = [cl.device_type.GPU, cl.device_type.ACCELERATOR, cl.device_type.CPU]
    found = []
    for platform in cl.get_platforms():
        try:
            devices = platform.get_devices()
        except cl.Error:  # a platform without devices
            continue
        for device in devices:
            rank = next((i for i, k in enumerate(kinds) if device.type & k), len(kinds))
            key = (rank, platform.name, platform.version, device.name)
            found.append((key, _device_label(platform, device), platform, device))
    found.sort(key=lambda item: item[0])
    return [(label, platform, device) for _, label, platform, device in found]


def choose_device(wanted=None):
    """The (label, device) to use; ``wanted`` defaults to $FPIWARP_OPENCL_DEVICE."""
    if wanted is None:
        wanted = os.environ.get(ENV_DEVICE) or None
    devices = list_devices()
    if not devices:
        raise RuntimeError("no OpenCL platform with a device found (install a driver, e.g. pocl-opencl-icd)")
    if wanted is None:
        label, _, device = devices[0]
        return label, device
    needle = wanted.lower()
    for label, platform, device in devices:
        if needle in label.lower() or needle in platform.version.lower():
            return label, device
    names = "; ".join(label for label, _, _ in devices)
    raise RuntimeError(f"no OpenCL device matches {wanted!r} (from {ENV_DEVICE} or device=); found: {names}")


#: A program every OpenCL compiler builds: the probe's test that the device's
#: compiler works here (PoCL 3.0-rc2 from PyPI on an AVX-512 CPU fails every
#: build with "unknown target CPU 'generic'").
PROBE_SOURCE = "__kernel void fw_probe(__global float *a) { a[get_global_id(0)] = 1.0f; }"


def build_failure(exc, label):
    """The one-line reason of a failed build (``exc`` from pyopencl), naming the device."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    errors = [line for line in lines if line.lower().startswith(("error", "fatal"))]
    detail = (errors or lines[-1:] or [type(exc).__name__])[0]
    detail = detail.split(".cl:", 1)[-1].lstrip("0123456789: ") if ".cl:" in detail else detail
    for prefix in ("fatal error:", "error:"):
        detail = detail[len(prefix):].strip() if detail.lower().startswith(prefix) else detail
    return f"the OpenCL device {label!r} cannot build fpiwarp's kernels ({detail[:200]})"


def probe():
    """None if an OpenCL device can run the kernels here, else why not: a
    driver, a device, and a compiler that builds a test program for it."""
    try:
        cl = _import_cl()
    except ImportError as exc:
        return f"pyopencl is not installed ({exc})"
    try:
        label, device = choose_device()
        context = cl.Context([device])
    except Exception as exc:  # driver errors come in many types
        return str(exc)
    try:
        cl.Program(context, PROBE_SOURCE).build()
    except Exception as exc:  # noqa: BLE001 - a compiler that fails for this CPU: not available, with the reason
        return build_failure(exc, label)
    return None


def program_source():
    """The block contract's generated #defines, then fpiwarp.cl with
    fpiwarp_map.h pasted in place of its #include, so the program builds
    the same from a source tree and from a wheel."""
    text = resources.source("kernels", _SOURCE)
    include = f'#include "{_HEADER.rsplit("/", 1)[-1]}"'
    if include not in text:
        raise RuntimeError(f"{_SOURCE} no longer includes {_HEADER}")
    return opencl_preamble() + text.replace(include, resources.source("kernels", _HEADER), 1)


def kind_options(kind):
    """Build options naming the kind of map (a :class:`fpiwarp.block.BlockKind`):
    each stage's header row (core, n_centers, n_regions, newton_iters).
    Values never enter them."""
    return tuple(
        f"-DFW_KIND_{k}={','.join(str(v) for v in stage.header)}" for k, stage in enumerate(kind.stages)
    )


def launch_width(backend, width):
    """Work-group width of warp_image for outputs ``width`` px wide: the
    narrowest of :data:`NARROW_LOCAL_X` that covers a row; wider rows are
    cut into the fewest groups of at most the backend's width, each a
    multiple of :data:`GROUP_STEP` px, so that a row runs few padding
    work-items (a 3840 px row in groups of 1024 ran 256 that redid its last
    pixel; four groups of 960 run none)."""
    fits = [x for x in NARROW_LOCAL_X if width <= x < backend.local_x and x % backend.lanes == 0]
    if fits:
        return fits[0]
    groups = -(-width // backend.local_x)
    step = GROUP_STEP if backend.local_x % GROUP_STEP == 0 else backend.local_x
    return min(backend.local_x, -(-width // (groups * step)) * step)


def sampling_options(dtype, channels, order, mode):
    """Build options (defines) for warp_image on one kind of sampling."""
    dtype = np.dtype(dtype)
    top = np.iinfo(dtype).max if dtype.kind == "u" else 0
    return (
        f"-DFW_T={_CTYPES[dtype]}",
        f"-DFW_C={int(channels)}",
        f"-DFW_INT={int(dtype.kind == 'u')}",
        f"-DFW_TOP={top}",
        f"-DFW_ORDER={int(order)}",
        f"-DFW_MODE={MODES.index(mode)}",
    )


class Backend:
    """map_points and warp_image on one OpenCL device.

    Parameters
    ----------
    device : str, optional
        Substring of ``"platform name: device name"`` (or of the platform
        version); default ``$FPIWARP_OPENCL_DEVICE``, else the first device
        in the deterministic order of :func:`list_devices`.
    """

    name = "opencl"
    #: Options every build gets (no fast-math: results must match the reference).
    BASE_OPTIONS = ()

    def __init__(self, device=None):
        cl = _import_cl()
        self._cl = cl
        self.device_label, self.device = choose_device(device)
        self.context = cl.Context([self.device])
        self.queue = cl.CommandQueue(self.context)
        self._source = program_source()
        #: points travel as float64 where the device reads doubles (no host conversions)
        self.has_fp64 = "cl_khr_fp64" in self.device.extensions
        self._point_options = ("-DFW_POINT=double", "-DFW_POINT_DOUBLE=1") if self.has_fp64 else ()
        is_cpu = bool(self.device.type & cl.device_type.CPU)
        #: on a CPU device, map_points runs on the caller's arrays in place
        #: (USE_HOST_PTR) instead of copying 32 bytes per point in and out,
        #: and warp_image writes its output array in place
        self.zero_copy = is_cpu and bool(self.device.host_unified_memory)
        self.local_x = min(LOCAL_X_CPU if is_cpu else LOCAL_X_OTHER, self.device.max_work_group_size)
        vectors = is_cpu and self.local_x % VECTOR_LANES_CPU == 0
        #: pixels one work-item samples at once, in vector types (see fpiwarp_map.h); set below
        self.lanes = VECTOR_LANES_CPU if vectors else 1
        if vectors:  # map_points reads and writes 8 points per work-item as vectors (fpiwarp.cl)
            self._point_options += ("-DFW_POINT_VN=8",)
        self._kernels = {}  # build options -> {kernel name: Kernel}
        self._buffers = {}  # (role, nbytes) -> Buffer
        self._block_cache = None  # (block bytes, its buffer, kind options) of the last upload
        self._kinds = LruCache(16)  # block bytes -> kind options, of recent blocks
        self._jobs = JobCache()  # prepared jobs of plain warp_image calls
        #: antialiasing's device pyramids of recent host sources (the one rule of
        #: every backend), their levels built as calls need them
        self.host_pyramids = SourcePyramids(lambda pixels: DevicePyramid(self, *pixels.shape))
        self._lock = threading.Lock()
        if vectors:
            from .tuning import lanes_for  # noqa: PLC0415

            self.lanes = lanes_for(self)

    def __repr__(self):
        return f"<fpiwarp opencl backend on {self.device_label!r}>"

    def tune(self, force=False):
        """Measure this device's warp_image tile once (:mod:`.tuning`; kept on
        disk); ``force`` measures again. Returns the measurement, or None
        when it was measured before."""
        from . import tuning  # noqa: PLC0415

        if tuning.tuned(self) and not force:
            return None
        return tuning.tune(self)

    # -- programs, kernels and buffers, all cached --------------------------
    def kernel(self, name, options=()):
        """Kernel ``name`` of the program built with ``options``; builds and
        fetches once per options."""
        options = tuple(self.BASE_OPTIONS) + tuple(options)
        kernels = self._kernels.get(options)
        if kernels is None:
            program = self._build(options)
            kernels = {k.function_name: k for k in program.all_kernels()}
            self._kernels[options] = kernels
        return kernels[name]

    def _build(self, options):
        """The program built with ``options``: from this device's binary in the
        disk cache (:mod:`.build_cache`) when there is one, else from source
        (then stored). A build that fails marks the backend failed and raises
        BackendUnavailableError with the compiler's first error."""
        cl = self._cl
        cached = build_cache.load(self, options)
        if cached is not None:
            try:
                return cl.Program(self.context, [self.device], [cached]).build(options=list(options))
            except cl.Error:  # a stale or foreign binary: built from source below
                build_cache.forget(self, options)
        try:
            program = cl.Program(self.context, self._source).build(options=list(options))
        except cl.Error as exc:
            from .. import mark_failed  # noqa: PLC0415

            reason = build_failure(exc, self.device_label)
            mark_failed("opencl", reason)
            raise BackendUnavailableError(f"backend 'opencl' is unavailable: {reason}; choose another backend "
                                          f"or another device ({ENV_DEVICE})") from None
        build_cache.store(self, options, program)
        return program

    def _buffer(self, role, nbytes):
        """A device buffer for ``role`` of exactly ``nbytes``, reused across
        calls; one per role (a new size replaces the old buffer)."""
        key = (role, nbytes)
        buf = self._buffers.get(key)
        if buf is None:
            for old in [k for k in self._buffers if k[0] == role]:
                del self._buffers[old]
            buf = self._cl.Buffer(self.context, self._cl.mem_flags.READ_WRITE, max(nbytes, 4))
            self._buffers[key] = buf
        return buf

    def _upload_block(self, transform, block=None):
        """Upload the block of ``transform`` (``block``: its float32 block,
        already packed); return it and its kind options. A block no kernel
        knows raises ValueError before the upload."""
        if block is None:
            block = np.ascontiguousarray(transform.params(), dtype=np.float32)
        data = block.tobytes()
        cached = self._block_cache
        if cached is not None and cached[0] == data:  # unchanged: no upload
            return cached[1], cached[2]
        options = kind_options(describe(block))
        buf = self._buffer("block", block.nbytes)
        self._cl.enqueue_copy(self.queue, buf, block)
        self._block_cache = (data, buf, options)
        return buf, options

    # -- the backend interface ---------------------------------------------
    def map_points(self, transform, points):
        shape = points.shape
        dtype = np.float64 if self.has_fp64 else np.float32
        pts = np.ascontiguousarray(points.reshape(-1, 2), dtype=dtype)
        n = pts.shape[0]
        out = np.empty((n, 2), dtype=dtype)
        if n == 0:
            return out.astype(np.float64).reshape(shape)
        if n >= 2**30:
            raise SizeLimitError(f"at most 2**30 points per call on the opencl backend, got {n}")
        with self._lock:
            block, kind = self._upload_block(transform)
            kern = self.kernel("map_points", kind + self._point_options + (f"-DFW_LOCAL_X={self.local_x}",))
            if self.zero_copy:
                mf = self._cl.mem_flags
                src = self._cl.Buffer(self.context, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=pts)
                dst = self._cl.Buffer(self.context, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=out)
            else:
                src = self._buffer("points_in", pts.nbytes)
                dst = self._buffer("points_out", out.nbytes)
                self._cl.enqueue_copy(self.queue, src, pts)
            kern.set_args(block, src, dst, np.int32(n))
            total = -(-n // self.local_x) * self.local_x
            self._cl.enqueue_nd_range_kernel(self.queue, kern, (total,), (self.local_x,))
            self._read_back(dst, out)
        return out.astype(np.float64, copy=False).reshape(shape)

    #: Bytes allocated past a source image (see IMAGE_SLACK).
    image_slack = IMAGE_SLACK
    #: Build options naming a kind of map (see :func:`kind_options`).
    kind_options = staticmethod(kind_options)

    @property
    def point_options(self):
        """Build options of map_points' point type (double where the device has fp64)."""
        return self._point_options

    def warp_batch(self, stack, transforms, output_shape, *, order, mode, cval, antialias=False, transfer=None):
        """A validated (N, H, W, C) stack warped by one map or one map per
        image, one launch per kind of map (see :mod:`.opencl_batch`)."""
        from . import batch as opencl_batch  # noqa: PLC0415 - loaded with the first batch

        with self._lock:
            return opencl_batch.warp_batch(self, stack, transforms, output_shape, order=order, mode=mode, cval=cval,
                                           antialias=antialias, transfer=transfer)

    def map_points_batch(self, transforms, points):
        """float64 (N, P, 2) point sets mapped by one map or one map each."""
        from . import batch as opencl_batch  # noqa: PLC0415 - loaded with the first batch

        with self._lock:
            return opencl_batch.map_points_batch(self, transforms, points)

    def _read_back(self, dst, out, zero_copy=None):
        """Make the kernel's results visible in ``out`` and wait for them:
        on a zero-copy buffer (``out`` is its host memory) mapping does it,
        otherwise a copy."""
        if self.zero_copy if zero_copy is None else zero_copy:
            mapped, event = self._cl.enqueue_map_buffer(
                self.queue, dst, self._cl.map_flags.READ, 0, out.shape, out.dtype
            )
            event.wait()
            del mapped
        else:
            self._cl.enqueue_copy(self.queue, out, dst)
        self.queue.finish()

    def block_kind(self, block):
        """The kind options of float32 ``block``, remembered by its bytes for
        the last few blocks; ValueError for a block no kernel knows."""
        return self._kinds.lookup(block.tobytes(), lambda: kind_options(describe(block)))

    def image_program(self, dtype, channels, order, mode, width, antialias, kind):
        """(kernel name, build options, work-group width) of warp_image for
        one kind of call: ``kind`` (:func:`kind_options`), sampling, and
        outputs ``width`` px wide."""
        local_x = launch_width(self, width)
        options = (*kind, *sampling_options(dtype, channels, order, mode), f"-DFW_LOCAL_X={local_x}",
                   f"-DFW_VN={self.lanes}")
        if antialias:  # antialiased programs (FW_AA) have the kernel warp_image_aa besides warp_image
            return "warp_image_aa", (*options, "-DFW_AA=1"), local_x
        return "warp_image", options, local_x

    def warp_image(self, image, transform, output_shape, *, order, mode, cval, antialias=False):
        block = np.ascontiguousarray(transform.inverse.params(), dtype=np.float32)
        with self._lock:
            job = self._jobs.get(self, image, output_shape, order, mode, cval, antialias, self.block_kind(block), block)
            job.set_block(block)
            return job.run(image, transform.inverse)

    def bind(self, transform):
        """``transform`` prepared for many images (:class:`~.opencl_prepared.BoundMap`):
        its block packed and checked once."""
        return BoundMap(self, transform)

    def warp_into(self, image, transform, output_shape, out, *, order, mode, cval, antialias=False):
        """:meth:`warp_image` on ``pyopencl.array.Array`` s of this context
        (see :meth:`prepare_warp`), read and written in place; returns
        ``out`` once the kernel is enqueued on :attr:`queue`."""
        with self._lock:
            job = self.prepare_warp(image, output_shape, order=order, mode=mode, cval=cval, antialias=antialias,
                                    out=out)
            job.set_map(transform)
            job.launch()
        return out

    def map_points_into(self, transform, points, out):
        """:meth:`map_points` on (n, 2) ``pyopencl.array.Array`` s of
        :attr:`point_dtype` in this context, in place; returns ``out``."""
        n = points.shape[0]
        if n >= 2**30:
            raise SizeLimitError(f"at most 2**30 points per call on the opencl backend, got {n}")
        with self._lock:
            block, kind = self._upload_block(transform)
            if n:
                kern = self.kernel("map_points", kind + self._point_options + (f"-DFW_LOCAL_X={self.local_x}",))
                kern.set_args(block, points.data, out.data, np.int32(n))
                total = -(-n // self.local_x) * self.local_x
                self._cl.enqueue_nd_range_kernel(self.queue, kern, (total,), (self.local_x,))
        return out

    @property
    def point_dtype(self):
        """The dtype the device reads points in: float64 where it has doubles."""
        return np.dtype(np.float64 if self.has_fp64 else np.float32)

    def prepare_warp(self, image, output_shape, *, order, mode, cval, antialias=False, out=None):
        """A :class:`DeviceWarp`: ``image`` uploaded and the output allocated
        on the device, ready to warp by one map after another with the
        kernel alone (what :meth:`warp_image` does once; benchmarks time
        its steps). Arguments as :meth:`warp_image` receives them.

        ``image`` may also be a ``pyopencl.array.Array`` (H, W, C),
        C-contiguous, in this backend's context with :data:`IMAGE_SLACK`
        bytes after it in its buffer, and ``out`` one of (rows, cols, C):
        the kernel reads and writes them in place (:mod:`fpiwarp.arrays`)."""
        return DeviceWarp(self, image, output_shape, order, mode, cval, antialias, out)


class DeviceWarp:
    """One image on the device, warped by :meth:`set_map` then :meth:`launch`.

    The buffers are the backend's kept ones, so the job is valid until the
    next call on the backend; use it from one thread.
    """

    def __init__(self, backend, image, output_shape, order, mode, cval, antialias=False, out=None):
        be, cl = backend, backend._cl
        h, w, c = image.shape
        oh, ow = output_shape
        if max(h * w, oh * ow) * c >= 2**31:
            raise SizeLimitError(f"image too large for the opencl backend: {h}x{w}x{c} -> {oh}x{ow}x{c}")
        self.backend, self.image_shape, self.output_shape = be, (h, w, c), (oh, ow)
        self.out = np.empty((oh, ow, c), dtype=image.dtype) if out is None else out
        self._cval4 = cl.cltypes.make_float4(*(list(cval) + [0.0] * (4 - c)))
        self._sampling = (image.dtype, c, order, mode, ow, antialias)  # chosen with the map's kind by set_map
        self.local = None  # the work-group tile, with the kernel
        #: the source is this job's own copy (a host image), so its pyramid
        #: (antialiased) is built once; a device array's at every launch
        self._own_source = isinstance(image, np.ndarray)
        if self._own_source:
            self._src = be._buffer("image_in", image.nbytes + IMAGE_SLACK)
            cl.enqueue_copy(be.queue, self._src, image)
        else:  # a device array (fpiwarp.arrays): read in place
            self._src = image.data
        self._pyramid = DevicePyramid(be, h, w, c) if antialias else None
        self._options = None
        self._zero_copy = be.zero_copy and self.out.nbytes >= ZERO_COPY_MIN_BYTES
        if out is not None:  # a device array: written in place, read() returns it
            self._dst, self._zero_copy = out.data, None
        elif self._zero_copy:  # the kernel writes `out` itself
            mf = cl.mem_flags
            self._dst = cl.Buffer(be.context, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=self.out)
        else:
            self._dst = be._buffer("image_out", self.out.nbytes)
        self._kernel = None
        self._coarse = None  # a Newton map's coarse pass (set_map), enqueued before the warp

    def set_map(self, transform):
        """Upload the parameter block of ``transform.inverse`` (the map
        from output to source) and select the kernel built for its kind."""
        be = self.backend
        (h, w, _), (oh, ow) = self.image_shape, self.output_shape
        host_block = np.ascontiguousarray(transform.inverse.params(), dtype=np.float32)
        block, kind = be._upload_block(transform.inverse, host_block)
        name, options, self.local = tiled_program(be, *self._sampling, kind)
        coarse = takes_coarse(kind, self._pyramid is not None, host_block, (oh, ow))
        if coarse:  # as the host warp's job (prepared.ClJob)
            options = (*options, COARSE_OPTION)
        kern = be.kernel(name, options)
        self._options = options
        extra = self._pyramid.args() if self._pyramid is not None else ()
        self._coarse = None
        if coarse:
            size, (nx, ny) = records_bytes((oh, ow))
            records = be._buffer("coarse", size)
            self._coarse = be.kernel("coarse_pass", options)  # of warp_image's program
            self._coarse.set_args(block, records, np.int32(nx), np.int32(ny))
            self._coarse_global = (nodes_global(self.local[0], nx, ny),)
            extra = (records, np.int32(nx), np.int32(ny))
        kern.set_args(block, self._src, np.int32(w), np.int32(h), self._dst, np.int32(ow), np.int32(oh), self._cval4,
                      *extra)
        self._kernel = kern

    def launch(self):
        """Enqueue the kernel over the output; returns its event without
        waiting (on a profiling queue it times the kernel alone)."""
        be = self.backend
        pyramid = self._pyramid
        if pyramid is not None and (pyramid.built < pyramid.top or not self._own_source):
            pyramid.reset()
            pyramid.build(self._options, self._src)
            self._kernel.set_arg(11, np.int32(pyramid.built))
        if self._coarse is not None:  # the queue is in order: the records are written before the warp reads them
            be._cl.enqueue_nd_range_kernel(be.queue, self._coarse, self._coarse_global, (self.local[0],))
        return be._cl.enqueue_nd_range_kernel(be.queue, self._kernel, global_size(self.local, self.output_shape),
                                              self.local)

    def finish(self):
        """Wait until the launched kernels are done."""
        self.backend.queue.finish()

    def read(self):
        """The output as a numpy array (waits for the kernel); a device
        ``out`` is returned as it is, without waiting."""
        if self._zero_copy is not None:
            self.backend._read_back(self._dst, self.out, self._zero_copy)
        return self.out
