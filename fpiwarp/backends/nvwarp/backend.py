"""The ``"warp"`` backend: NVIDIA Warp kernels on CUDA or Warp's CPU device.

The map is packed once on the host (:meth:`fpiwarp.Transform.params`) and
uploaded as an array of ``vec4`` rows; the kernels, made by
:mod:`fpiwarp.kernels.nvwarp.factory` for each kind of map and of sampling,
are compiled once per device and cached on disk by Warp (its default cache
directory, or ``WARP_CACHE_PATH``).

Device choice: the ``device`` argument of :class:`Backend`, else the
environment variable ``FPIWARP_WARP_DEVICE`` (``"cpu"``, ``"cuda:0"``, ...),
else ``cuda:0`` when CUDA is available and ``cpu`` otherwise.

Warp's CPU device runs each launch on one thread, so on the CPU a large
call is split into bands of rows (ranges of points) launched from a small
thread pool, and its image kernels run a thread per output row (on CUDA a
thread per pixel); Warp releases the GIL while a CPU kernel runs. The number of
threads comes from the ``threads`` argument, else ``FPIWARP_WARP_THREADS``,
else the CPUs this process may use.

On the CPU the kernels read and write the caller's numpy arrays in place
(no copies); on CUDA the device buffers are kept and reused while calls
keep the same shape.

Antialiased warps read the source's pyramid (:mod:`.pyramid`), built on
the device by a Warp kernel: once per prepared job (:class:`DeviceWarp`)
and per batch, and for numpy sources kept across calls while the pixels
are unchanged (:class:`~fpiwarp.sampling.pyramid.SourcePyramids`), so many maps over one
image build its levels once.
"""

import contextlib
import ctypes
import itertools
import logging
import operator
import os
import threading
import time
import weakref
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ...block import MAX_ROWS, describe
from ...block.sampling_rules import MODES
from ...errors import ArgumentError
from ...sampling.pyramid import SourcePyramids
from .prepared import BoundMap, JobCache
from .pyramid import DevicePyramid

#: Environment variable naming the Warp device, e.g. "cpu" or "cuda:0".
DEVICE_ENV = "FPIWARP_WARP_DEVICE"
#: Environment variable with the number of CPU threads (CPU device only).
THREADS_ENV = "FPIWARP_WARP_THREADS"
#: Below this many work items a CPU call is one launch on the calling thread.
MIN_ITEMS_PER_THREAD = 1 << 14

_init_lock = threading.Lock()
_log = logging.getLogger("fpiwarp")
#: A kernel whose load took longer than this, where Warp's cache could not be
#: looked at beforehand, is reported after the fact.
SLOW_LOAD_S = 2.0


@contextlib.contextmanager
def _quiet_native_stderr():
    """Silence C-level stderr while Warp initializes on a machine without a
    CUDA driver, where its native library prints a warning we do not need."""
    try:
        ctypes.CDLL("libcuda.so.1")
        has_driver = True
    except OSError:
        has_driver = False
    if has_driver:
        yield
        return
    try:
        saved = os.dup(2)
    except OSError:  # pragma: no cover - no stderr to silence
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def _warp():
    """Import and initialize Warp quietly, once; return the module."""
    import warp as wp

    with _init_lock:
        wp.config.quiet = True  # Warp < 1.10
        if hasattr(wp, "LOG_WARNING"):
            wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
        with _quiet_native_stderr():
            wp.init()
    return wp


def warp_module():
    """Warp, imported and initialized quietly (once); for modules that
    hand this backend Warp arrays (:mod:`fpiwarp.arrays`)."""
    return _warp()


def _launch_block_dim(device):
    """The block dimension wp.launch loads a module with (1 on the CPU)."""
    return 1 if device.is_cpu else 256


def _will_compile(wp, module, device):
    """True when loading ``module`` on ``device`` compiles it (no binary in
    Warp's kernel cache), False when it is loaded or cached, None when this
    Warp version does not say (its cache layout is Warp's own)."""
    block_dim = _launch_block_dim(device)
    try:
        if module.execs.get((device.context, block_dim)) is not None:
            return False
        folder = os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier(block_dim))
        return not os.path.exists(os.path.join(folder, module._get_compile_output_name(device, block_dim=block_dim)))
    except Exception:  # noqa: BLE001 - a private layout of Warp's: unknown, said after the load instead
        return None


def load_kernel(wp, kernel, device):
    """Load ``kernel`` on ``device`` (compiled, or read from Warp's disk
    cache), saying so in one line of the "fpiwarp" logger when it really
    compiles: Warp's first compile of a kernel takes seconds (10-20 s on a
    small CPU) and must not land on a first call silently."""
    compiling = _will_compile(wp, kernel.module, device)
    name = kernel.key.rsplit(".", 1)[-1]
    if compiling:
        _log.warning("fpiwarp: compiling the Warp kernel %s for %s, once: Warp caches it on disk "
                     "(%s), so later runs load it in milliseconds", name, device, wp.config.kernel_cache_dir)
    start = time.perf_counter()
    kernel.module.load(device, _launch_block_dim(device))
    took = time.perf_counter() - start
    if compiling is None and took > SLOW_LOAD_S:
        _log.warning("fpiwarp: loading the Warp kernel %s for %s took %.1f s (compiled; Warp caches it on disk)",
                     name, device, took)
    return kernel


def _device_name(wp, device=None):
    """The device to use: argument, else the environment, else cuda:0 or cpu."""
    name = device or os.environ.get(DEVICE_ENV, "").strip()
    if not name:
        return "cuda:0" if wp.get_cuda_device_count() > 0 else "cpu"
    known = [str(d) for d in wp.get_devices()]
    if name not in known:
        raise ArgumentError(f"Warp device {name!r} is not available here; choose from {known}")
    return name


def _thread_count(threads=None):
    """Threads for CPU launches: argument, else the environment, else the CPUs."""
    source = "threads"
    if threads is None:
        value = os.environ.get(THREADS_ENV, "").strip()
        if not value:
            try:
                return len(os.sched_getaffinity(0))
            except AttributeError:  # pragma: no cover - not Linux
                return os.cpu_count() or 1
        source, threads = THREADS_ENV, value
    try:
        count = int(threads) if isinstance(threads, str) else operator.index(threads)
    except (TypeError, ValueError):
        count = 0
    if isinstance(threads, bool) or count < 1:
        raise ArgumentError(f"{source} must be a positive integer, got {threads!r}")
    return count


def probe():
    """None if Warp imports and the chosen device exists, else why not."""
    try:
        import warp  # noqa: F401
    except ImportError:
        return "warp-lang is not installed"
    wp = _warp()
    try:
        name = _device_name(wp)
    except ValueError as exc:
        return f"{exc} (set by {DEVICE_ENV})"
    try:
        _thread_count()
    except ValueError as exc:
        return str(exc)
    if name == "cpu" and not wp.is_cpu_available():
        return "Warp's CPU device is not available (its LLVM compiler could not load)"
    return None


class Backend:
    """Evaluate maps with Warp kernels on one device (see the module docstring).

    Parameters
    ----------
    device : str, optional
        A Warp device name such as ``"cpu"`` or ``"cuda:0"``; default from
        ``FPIWARP_WARP_DEVICE``, else CUDA when present, else the CPU.
    threads : int, optional
        CPU threads for large calls on the CPU device; default from
        ``FPIWARP_WARP_THREADS``, else the CPUs this process may use.

    Each kernel is loaded (compiled, or read from Warp's disk cache) on its
    first use on this device, with a one-line notice when it compiles
    (:func:`load_kernel`).
    """

    name = "warp"

    def __init__(self, device=None, threads=None):
        self._wp = wp = _warp()
        self.device = wp.get_device(_device_name(wp, device))
        self._on_cpu = self.device.is_cpu
        self.threads = _thread_count(threads) if self._on_cpu else 1
        from fpiwarp.kernels.nvwarp import factory

        self.kernels = factory
        self._loaded = set()  # keys of the kernels loaded on this device (each on first use)
        self._lock = threading.Lock()
        self._pool = ThreadPoolExecutor(self.threads, "fpiwarp-warp") if self.threads > 1 else None
        if self._pool is not None:  # its idle threads end with the backend object
            weakref.finalize(self, self._pool.shutdown, wait=False)
        # the kernels read blocks (B, rows): one map is B = 1, read by image (point set) 0 through ``first``
        self._block = wp.zeros((1, MAX_ROWS), dtype=wp.vec4, device=self.device)
        self._block_staging = self._block if self._on_cpu else wp.zeros_like(self._block, device="cpu", pinned=True)
        self._block_host = self._block_staging.numpy()[0]  # a (rows, 4) float32 view of host memory
        self.first = wp.zeros(1, dtype=wp.int32, device=self.device)
        # what plain image kernels get for the pyramid arguments only antialiased ones read
        self.no_pyramid = [wp.zeros((1, 1, 1), dtype=wp.float32, device=self.device),
                           wp.zeros(1, dtype=wp.vec3i, device=self.device)]
        self._buffers = {}
        self._jobs = JobCache()  # prepared jobs of plain warp_image calls
        #: antialiasing's pyramids of recent host sources (the one rule of every backend)
        self.host_pyramids = SourcePyramids(lambda pixels, src: self.pyramid([(src, 0)], *pixels.shape))
        self.block_kind = None  # what the kernels specialize on, of the block uploaded last
        self._batch_runner = None  # the batch kernels, loaded on first use

    def __repr__(self):
        return f"<fpiwarp warp backend on {self.device}, {self.threads} thread(s)>"

    def band_count(self, rows, cols=None):
        """Bands of rows a launch over (rows, cols) is split into: one per
        thread on the CPU where each gets enough work, else one."""
        return min(self.threads, max(1, rows * (cols or 1) // MIN_ITEMS_PER_THREAD))

    def run_launches(self, launches):
        """Replay recorded launches (``Launch.launch``), from the thread pool
        when there are several (the bands of one call)."""
        if len(launches) == 1:
            launches[0].launch()
            return
        for future in [self._pool.submit(launch.launch) for launch in launches]:
            future.result()

    def image_spec(self, kind, order, mode, channels, dtype, *, strided=False, antialias=False):
        """The :class:`~fpiwarp.kernels.nvwarp.factory.ImageKernel` of this
        device: a thread per row on the CPU, per pixel on CUDA."""
        return self.kernels.image_spec(kind, order, mode, channels, dtype, strided=strided, rows=self._on_cpu,
                                       antialias=antialias)

    def image_kernel(self, kind, order, mode, channels, dtype, *, strided=False, antialias=False):
        """The image kernel of :meth:`image_spec`, loaded on this device."""
        return self._loaded_kernel(self.kernels.image_kernel(
            self.image_spec(kind, order, mode, channels, dtype, strided=strided, antialias=antialias)))

    def point_kernel(self, sets=False):
        """The point kernel (``sets``: of (N, P) point sets), loaded on this device."""
        return self._loaded_kernel(self.kernels.point_kernel(self.kernels.PointKernel(sets=sets)))

    def pyramid_kernel(self, dtype, channels):
        """The pyramid level kernel reading ``dtype`` of ``channels`` channels, loaded on this
        device (a thread per row on the CPU, per texel on CUDA)."""
        return self._loaded_kernel(self.kernels.pyramid_kernel(dtype, rows=self._on_cpu, channels=channels))

    def pyramid(self, sources, height, width, channels):
        """The :class:`~.pyramid.DevicePyramid` of ``sources`` ((Warp array, first row) of H × W
        images), built on this device now."""
        return DevicePyramid(self, sources, height, width, channels)

    def _loaded_kernel(self, kernel):
        if kernel.key not in self._loaded:
            load_kernel(self._wp, kernel, self.device)
            self._loaded.add(kernel.key)
        return kernel

    def launch_image(self, kernel, rows, cols, inputs, launch=None):
        """Launch an image kernel of :meth:`image_spec` over ``rows`` output
        rows of ``cols`` pixels (in bands of rows on the CPU) through
        ``launch`` (default :meth:`_launch`)."""
        launch = launch or self._launch
        if self._on_cpu:
            launch(kernel, rows, None, inputs, cols)
        else:
            launch(kernel, rows, cols, inputs)

    def image_dims(self, rows, cols):
        """The launch dimensions of an image kernel of :meth:`image_spec`."""
        return rows if self._on_cpu else (rows, cols)

    def _launch(self, kernel, rows, cols, inputs, row_items=None):
        """Launch ``kernel`` over (rows, cols), or over rows when cols is None
        (each row ``row_items`` items of work, for the bands); the kernel's
        last input is the first row. On the CPU, large launches are split
        into one band of rows per thread."""
        wp = self._wp
        bands = self.band_count(rows, cols or row_items)

        def launch(r0, r1):
            dim = r1 - r0 if cols is None else (r1 - r0, cols)
            wp.launch(kernel, dim=dim, inputs=[*inputs, r0], device=self.device)

        if bands == 1:
            launch(0, rows)
            return
        cuts = [rows * b // bands for b in range(bands + 1)]
        futures = [self._pool.submit(launch, r0, r1) for r0, r1 in itertools.pairwise(cuts)]
        for future in futures:
            future.result()

    def _upload_block(self, transform):
        """Write the map's parameter block into the persistent device buffer
        (on CUDA through a pinned host copy of it). A block no kernel knows
        raises ValueError before the upload (:func:`fpiwarp.block.describe`)."""
        block = transform.params()
        kind = describe(block)
        rows = block.shape[0]
        self._block_host[:rows] = block
        if not self._on_cpu:
            self._wp.copy(self._block, self._block_staging, count=rows)
        self.block_kind = self.kernels.kind_key(kind)
        return self._block

    def _buffer(self, key, shape, dtype):
        """A device array kept across calls while ``key``'s shape and dtype hold."""
        wp = self._wp
        arr = self._buffers.get(key)
        if arr is None or arr.shape != shape or arr.dtype != dtype:
            arr = wp.empty(shape, dtype=dtype, device=self.device)
            self._buffers[key] = arr
        return arr

    def _to_device(self, key, data, dtype):
        """``data`` on the device: aliased on the CPU, copied into a kept buffer on CUDA."""
        wp = self._wp
        if self._on_cpu:
            return wp.array(data, dtype=dtype, device="cpu", copy=False)
        shape = data.shape[:-1] if dtype is wp.vec2d else data.shape
        arr = self._buffer(key, shape, dtype)
        arr.assign(data)
        return arr

    def map_points(self, transform, points):
        """Map float64 (..., 2) points; float64 out, float32 arithmetic on the device."""
        wp = self._wp
        shape = points.shape
        flat = np.ascontiguousarray(points.reshape(-1, 2), dtype=np.float64)
        n = flat.shape[0]
        if n == 0:
            return np.empty(shape, dtype=np.float64)
        with self._lock:
            blk = self._upload_block(transform)
            src = self._to_device("points", flat, wp.vec2d)
            if self._on_cpu:
                result = np.empty_like(flat)
                out = wp.array(result, dtype=wp.vec2d, device="cpu", copy=False)
            else:
                out = self._buffer("mapped", (n,), wp.vec2d)
            self._launch(self.point_kernel(), n, None, [blk, self.first, src, out])
            if not self._on_cpu:
                result = out.numpy()
        return result.reshape(shape)

    def warp_image(self, image, transform, output_shape, *, order, mode, cval, antialias=False):
        """Backward warp: each output pixel samples the source at ``transform.inverse``
        (antialiased: averaged over its footprint, see fpiwarp.sampling.antialias)."""
        with self._lock:
            if not antialias:  # a job per kind of call (kernel specialized for the map's kind)
                block = self._upload_block(transform.inverse)
                job = self._jobs.get(self, block, image, output_shape, order, mode, cval, self.block_kind)
                return job.run(image)
            job = self.prepare_warp(image, output_shape, order=order, mode=mode, cval=cval, antialias=antialias)
            job.set_map(transform)
            job.launch()
            return job.read()

    def warp_into(self, image, transform, output_shape, out, *, order, mode, cval, antialias=False):
        """:meth:`warp_image` on Warp arrays of this device: ``image``
        (H, W, C) read and ``out`` (rows, cols, C) written in place, any
        strides; returns ``out`` (on CUDA without waiting for the kernel)."""
        with self._lock:
            job = self.prepare_warp(image, output_shape, order=order, mode=mode, cval=cval, antialias=antialias,
                                    out=out)
            job.set_map(transform)
            job.launch()
        return out

    def map_points_into(self, transform, points, out):
        """:meth:`map_points` on Warp arrays of ``vec2d`` of this device,
        read and written in place; returns ``out``."""
        with self._lock:
            blk = self._upload_block(transform)
            if points.shape[0]:
                self._launch(self.point_kernel(), points.shape[0], None, [blk, self.first, points, out])
        return out

    def bind(self, transform):
        """``transform`` prepared for many images (:class:`~.warp_prepared.BoundMap`):
        its block packed and uploaded once."""
        return BoundMap(self, transform)

    def batches(self):
        """The :class:`~fpiwarp.backends.nvwarp.batch.BatchRunner` of this
        backend; its kernels are made on first use."""
        from .batch import BatchRunner  # noqa: PLC0415

        with self._lock:
            if self._batch_runner is None:
                self._batch_runner = BatchRunner(self)
        return self._batch_runner

    def warp_batch(self, stack, transforms, output_shape, *, order, mode, cval, antialias=False, transfer=None):
        """A validated (N, H, W, C) stack warped by one map or one map per
        image in one launch per kind (see :mod:`fpiwarp.backends.nvwarp.batch`;
        ``transfer``: how a stack reaches a CUDA device, "serial" or "pipelined")."""
        runner = self.batches()
        with self._lock:
            return runner.warp_batch(stack, transforms, output_shape, order=order, mode=mode, cval=cval,
                                     antialias=antialias, transfer=transfer)

    def map_points_batch(self, transforms, points):
        """float64 (N, P, 2) point sets mapped by one map or one map each, in one launch."""
        runner = self.batches()
        with self._lock:
            return runner.map_points_batch(transforms, points)

    def warp_batch_into(self, stack, transforms, output_shape, out, *, order, mode, cval, antialias=False):
        """:meth:`warp_batch` on Warp arrays of this device: ``stack``
        (N, H, W, C) read and ``out`` (N, rows, cols, C) written in place,
        any strides; returns ``out`` (on CUDA without waiting)."""
        del output_shape  # out's
        runner = self.batches()
        with self._lock:
            return runner.warp_arrays(stack, out, transforms, order=order, mode=mode, cval=cval, antialias=antialias)

    def map_points_batch_into(self, transforms, points, out):
        """:meth:`map_points_batch` on (N, P) ``vec2d`` Warp arrays of this
        device, in place; returns ``out``."""
        runner = self.batches()
        with self._lock:
            return runner.map_points_arrays(transforms, points, out)

    def prepare_warp(self, image, output_shape, *, order, mode, cval, antialias=False, out=None):
        """A :class:`DeviceWarp`: ``image`` on the device (aliased on the
        CPU) and the output allocated, ready to warp by one map after
        another with the kernel alone (what :meth:`warp_image` does once;
        benchmarks time its steps). Arguments as :meth:`warp_image` receives them.

        ``image`` may also be a Warp array (H, W, C) on this backend's
        device, any strides, and ``out`` one of (rows, cols, C) of its
        dtype: both are used in place (:mod:`fpiwarp.arrays`)."""
        return DeviceWarp(self, image, output_shape, order, mode, cval, antialias, out)


class DeviceWarp:
    """One image on the device, warped by :meth:`set_map` then :meth:`launch`.

    The buffers are the backend's kept ones (on CUDA), so the job is valid
    until the next call on the backend; use it from one thread. An
    antialiased job takes the image's pyramid when it is made (a Warp
    array's built then, a numpy image's kept across calls while its pixels
    are unchanged: :class:`~fpiwarp.sampling.pyramid.SourcePyramids`) and reads it in every
    launch: it warps the image as it was then (as on CUDA, where the image
    is copied then); make a new job after changing the image.
    """

    def __init__(self, backend, image, output_shape, order, mode, cval, antialias=False, out=None):
        be = self.backend = backend
        wp = be._wp
        oh, ow = self.output_shape = output_shape
        channels = image.shape[2]
        resident = isinstance(image, wp.array)  # a Warp array on this device (fpiwarp.arrays): read in place
        dtype = np.dtype(wp.dtype_to_numpy(image.dtype)) if resident else image.dtype
        scalar = wp.dtype_from_numpy(dtype)
        cv = np.zeros(4, dtype=np.float32)
        cv[:channels] = cval
        self._src = image if resident else be._to_device("image", image, scalar)
        if out is not None:  # a Warp array of (oh, ow, channels) on this device: written in place
            self._result, self._out = None, out
        elif be._on_cpu:
            self._result = np.empty((oh, ow, channels), dtype=dtype)
            self._out = wp.array(self._result, dtype=scalar, device="cpu", copy=False)
        else:
            self._result = None
            self._out = be._buffer("warped", (oh, ow, channels), scalar)
        self._kernel = None  # chosen by set_map, for the map's kind
        self._tail = [image.shape[0], oh, 0, int(order), MODES.index(mode), wp.vec4(*cv.tolist())]
        self._sampling = (int(order), MODES.index(mode), channels, dtype)
        self._pyramid = be.no_pyramid
        if antialias:  # one kernel for every map, order and mode, which it reads at run time
            self._kernel = be.image_kernel(None, None, None, None, dtype, antialias=True)
            pyramid = (be.pyramid([(self._src, 0)], *image.shape) if resident
                       else be.host_pyramids.get(image, self._src))
            self._pyramid = pyramid.args
        self._antialias = antialias
        self._block = None

    def set_map(self, transform):
        """Upload the parameter block of ``transform.inverse`` (the map from
        output to source)."""
        be = self.backend
        self._block = be._upload_block(transform.inverse)
        if not self._antialias:
            self._kernel = be.image_kernel(be.block_kind, *self._sampling)

    def launch(self):
        """Run the kernel over the output (on CUDA without waiting for it)."""
        oh, ow = self.output_shape
        self.backend.launch_image(self._kernel, oh, ow, [self._block, self.backend.first, self._src, self._out,
                                                         *self._tail, *self._pyramid])

    def finish(self):
        """Wait until the launched kernels are done."""
        self.backend._wp.synchronize_device(self.backend.device)

    def read(self):
        """The output as a numpy array (copied back on CUDA)."""
        return self._result if self._result is not None else self._out.numpy()
