"""Warping many images with one map: arrays, stacks and folders.

* :func:`warp_images` is a generator: arrays or file paths in, warped
  arrays out, one at a time (bounded memory).
* :func:`warp_batch` warps an (N, H, W[, C]) stack with one map for all or
  one map per image.
* :func:`run_batch` warps every image of a folder into another folder, in
  parallel threads or on a Dask cluster, skipping outputs that exist
  (so a rerun resumes), writing each output atomically, and collecting the
  files that fail in a :class:`BatchSummary` instead of stopping.

The map is solved once. On the numpy backend the source position of every
output pixel is also computed once per output size and shared by all
images of that size (and, in :func:`warp_batch`, sampled for all images of
a stack in one pass); other backends get one ``warp_image`` call per image.
"""

import collections
import os
import sys
import threading
import time
import uuid
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._errors import InverseNotConvergedError
from ._sampling import MODES, ORDERS, sample, to_dtype
from ._transform import Transform
from ._warp import check_cval, check_image, check_output_shape, warp_image
from .backends import get_backend
from .backends.numpy_backend import source_positions
from .io import ImageError, OutputExistsError, check_writable, is_temp_file, read_image, write_image

__all__ = ["BatchSummary", "Warper", "list_inputs", "run_batch", "warp_batch", "warp_images"]

#: Output pixels sampled per chunk on the numpy path, as in the numpy backend.
CHUNK_PIXELS = 1 << 19
#: Source-position maps kept per Warper (one per output size).
MAP_CACHE_SIZE = 2
#: How long to try reaching a Dask scheduler before giving up.
DASK_CONNECT_TIMEOUT = "10s"


class Warper:
    """One map and its warp options, ready to warp many images.

    Options are checked once here, with the errors of
    :func:`fpiwarp.warp_image`. Calling the warper on an image returns what
    ``warp_image(image, transform, output_shape, ...)`` returns; on the
    numpy backend the source positions are computed once per output size
    and reused (thread-safe).
    """

    def __init__(self, transform, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy"):
        if not isinstance(transform, Transform):
            raise TypeError(f"transform must be an fpiwarp map (FPI, Compound, ...), got {type(transform).__name__}")
        if order not in ORDERS:
            raise ValueError(f"order must be one of {ORDERS}, got {order!r}")
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if np.ndim(cval) > 1:
            raise ValueError(f"cval must be a number or one per channel, got {cval!r}")
        get_backend(backend)  # fail now if unknown or unavailable
        self.transform, self.output_shape = transform, output_shape
        self.order, self.mode, self.cval, self.backend = order, mode, cval, backend
        self._lock = threading.Lock()
        self._maps = collections.OrderedDict()

    def __getstate__(self):  # picklable for Dask workers: no lock, no cache
        state = self.__dict__.copy()
        del state["_lock"], state["_maps"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()
        self._maps = collections.OrderedDict()

    def positions(self, shape):
        """Source (x, y) of every output pixel, float64 (rows, cols, 2)."""
        with self._lock:
            if shape in self._maps:
                self._maps.move_to_end(shape)
                return self._maps[shape]
        oh, ow = shape
        grid = np.empty((oh, ow, 2))
        grid[..., 0] = np.arange(ow, dtype=np.float64)
        grid[..., 1] = np.arange(oh, dtype=np.float64)[:, None]
        pos = source_positions(self.transform.inverse, grid)
        pos.flags.writeable = False
        with self._lock:
            self._maps[shape] = pos
            while len(self._maps) > MAP_CACHE_SIZE:
                self._maps.popitem(last=False)
        return pos

    def __call__(self, image):
        if self.backend != "numpy":
            return warp_image(
                image,
                self.transform,
                self.output_shape,
                order=self.order,
                mode=self.mode,
                cval=self.cval,
                backend=self.backend,
            )
        img, squeeze = check_image(image)
        cval = check_cval(self.cval, img.shape[2])
        shape = tuple(check_output_shape(self.output_shape, img))
        out = _sample_all(img, self.positions(shape), self.order, self.mode, cval)
        return out[:, :, 0] if squeeze else out


def _sample_all(img, pos, order, mode, cval):
    """Sample (H, W, C) img at pos (rows, cols, 2) in row chunks."""
    oh, ow = pos.shape[:2]
    out = np.empty((oh, ow, img.shape[2]), dtype=img.dtype)
    rows = max(1, CHUNK_PIXELS // ow)
    for r0 in range(0, oh, rows):
        r1 = min(oh, r0 + rows)
        values = sample(img, pos[r0:r1, :, 0], pos[r0:r1, :, 1], order, mode, cval)
        out[r0:r1] = to_dtype(values, img.dtype)
    return out


def _as_image(item):
    if isinstance(item, (str, os.PathLike)):
        return read_image(item)[0]
    return item


def warp_images(images, transform, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy"):
    """Warp each of ``images`` (arrays, or paths of image files) by
    ``transform``; yield the warped arrays in order, one at a time.

    Options as in :func:`fpiwarp.warp_image`; they are checked before the
    first image is read. Same-size images share the map's evaluation.
    """
    warper = Warper(transform, output_shape, order=order, mode=mode, cval=cval, backend=backend)
    return (warper(_as_image(item)) for item in images)


def warp_batch(images, transforms, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy"):
    """Warp a stack of same-size images, (N, H, W) or (N, H, W, C).

    ``transforms`` is one map for all images or a sequence of N maps, one
    per image. Returns an (N, rows, cols[, C]) array of the input's dtype.
    With one map on the numpy backend all N images are sampled in a single
    pass over the map (as one image with N·C channels).
    """
    stack = np.asarray(images) if not isinstance(images, np.ndarray) else images
    if stack.ndim not in (3, 4) or stack.shape[0] == 0:
        raise ValueError(f"images must be a non-empty (N, H, W) or (N, H, W, C) array, got shape {stack.shape}")
    first, squeeze = check_image(stack[0])
    n, (h, w, c) = stack.shape[0], first.shape
    if isinstance(transforms, Transform):
        maps = None
        warper = Warper(transforms, output_shape, order=order, mode=mode, cval=cval, backend=backend)
    else:
        maps = list(transforms)
        if len(maps) != n:
            raise ValueError(f"got {len(maps)} maps for {n} images; give one map or one per image")
        warpers = [Warper(t, output_shape, order=order, mode=mode, cval=cval, backend=backend) for t in maps]
    backend_obj = get_backend(backend)
    if hasattr(backend_obj, "warp_batch"):  # a backend with a batched device call
        shape = check_output_shape(output_shape, first)
        out = backend_obj.warp_batch(
            np.ascontiguousarray(stack.reshape(n, h, w, c)),
            [transforms] if maps is None else maps,
            tuple(shape),
            order=order,
            mode=mode,
            cval=check_cval(cval, c),
        )
    elif maps is None and backend == "numpy":
        shape = tuple(check_output_shape(output_shape, first))
        cvals = np.tile(check_cval(cval, c), n)
        wide = np.ascontiguousarray(stack.reshape(n, h, w, c).transpose(1, 2, 0, 3)).reshape(h, w, n * c)
        flat = _sample_all(wide, warper.positions(shape), order, mode, cvals)
        out = flat.reshape(shape[0], shape[1], n, c).transpose(2, 0, 1, 3)
    else:
        chosen = [warper] * n if maps is None else warpers
        out = np.stack([chosen[i](stack[i].reshape(h, w, c)) for i in range(n)])
    out = np.ascontiguousarray(out)
    return out[..., 0] if squeeze else out


# --------------------------------------------------------------------------
# Folders


@dataclass
class BatchSummary:
    """What a folder batch did: outputs written, skipped because they
    existed, and (input, reason) for each file that failed."""

    total: int = 0
    done: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    failed: list = field(default_factory=list)
    interrupted: bool = False

    @property
    def processed(self):
        return len(self.done) + len(self.skipped) + len(self.failed)

    @property
    def ok(self):
        return not self.failed and not self.interrupted

    def record(self, status, path, reason=None):
        if status == "done":
            self.done.append(path)
        elif status == "skipped":
            self.skipped.append(path)
        else:
            self.failed.append((path, reason))

    def report(self):
        """Lines for the user: counts, then one line per failed file."""
        counts = (
            f"{len(self.done)} warped, {len(self.skipped)} skipped (output exists), "
            f"{len(self.failed)} failed, of {self.total} files"
        )
        lines = [counts]
        if self.skipped:
            lines.append("skipped files already have an output; pass --overwrite to redo them")
        if self.interrupted:
            lines.append(f"interrupted: {self.total - self.processed} files not done; run again to resume")
        for path, reason in sorted(self.failed, key=lambda item: str(item[0])):
            prefix = f"{path}: "
            lines.append(f"failed: {path}: {reason[len(prefix):] if reason.startswith(prefix) else reason}")
        return lines


def list_inputs(input_dir, pattern=None, exclude=None):
    """Sorted files of ``input_dir`` matching the glob ``pattern`` (default
    every file at the top level; ``**/*`` recurses), without hidden files,
    fpiwarp's temporary files, and anything under ``exclude``."""
    root = Path(input_dir)
    if not root.exists():
        raise FileNotFoundError(f"input folder does not exist: {root}")
    if not root.is_dir():
        raise NotADirectoryError(f"input is not a folder: {root}")
    if pattern is not None and (not pattern or Path(pattern).is_absolute()):
        raise ValueError(f"the pattern must be a glob relative to the input folder, like '*.jpg', got {pattern!r}")
    excluded = Path(exclude).resolve() if exclude is not None else None
    if excluded is not None and excluded not in root.resolve().parents and excluded != root.resolve():
        excluded_inside = excluded  # an output folder inside the input tree: skip what is in it
    else:
        excluded_inside = None  # the output folder holds the inputs (or is elsewhere): skip nothing
    found = []
    for path in root.glob(pattern or "*"):
        rel = path.relative_to(root)
        if any(part.startswith(".") for part in rel.parts) or is_temp_file(path) or not path.is_file():
            continue
        if excluded_inside is not None and excluded_inside in path.resolve().parents:
            continue
        found.append(path)
    return sorted(found)


def _plan(input_dir, output_dir, pattern):
    """[(input, output)] pairs; refuses any output that is an input."""
    inputs = list_inputs(input_dir, pattern, exclude=output_dir)
    root, out_root = Path(input_dir), Path(output_dir)
    if root.resolve() == out_root.resolve():
        raise ValueError("the output folder is the input folder; choose another (inputs are never modified)")
    pairs = [(p, out_root / p.relative_to(root)) for p in inputs]
    input_set = {p.resolve() for p in inputs}
    for _, out in pairs:
        if out.resolve() in input_set:
            raise ValueError(f"output {out} would replace an input file; choose an output folder outside the input")
    return pairs


def _process(src, dst, warper, overwrite):
    """Warp one file; return (status, input path, reason)."""
    try:
        if not overwrite and dst.exists():
            return "skipped", str(src), None
        image, info = read_image(src)
        dtype, channels = image.dtype, (1 if image.ndim == 2 else image.shape[2])
        check_writable(dst, dtype, channels, info)
        out = warper(image)
        dst.parent.mkdir(parents=True, exist_ok=True)
        write_image(dst, out, info, overwrite=overwrite)
        return "done", str(src), None
    except OutputExistsError:
        return "skipped", str(src), None
    except (ImageError, OSError, ValueError, InverseNotConvergedError) as exc:
        return "failed", str(src), _reason(exc)


def _reason(exc):
    text = str(exc)
    if isinstance(exc, OSError) and exc.strerror:
        text = exc.strerror
    return text if isinstance(exc, (ImageError, OSError, ValueError)) else f"{type(exc).__name__}: {text}"


def run_batch(
    transform,
    input_dir,
    output_dir,
    *,
    pattern=None,
    jobs=1,
    overwrite=False,
    backend="numpy",
    order=1,
    mode="constant",
    cval=0,
    output_shape=None,
    progress=None,
    scheduler=None,
    summary=None,
):
    """Warp every image file of ``input_dir`` into ``output_dir``.

    Outputs keep the input's relative path, name, format, dtype, channels
    and metadata. Existing outputs are kept (and counted as skipped) unless
    ``overwrite``. Files that cannot be read or written are recorded as
    failed and the others processed. ``jobs`` threads work in parallel
    with at most a few images in memory per thread; ``scheduler`` (a Dask
    scheduler address or a ``distributed.Client``) runs the files on a Dask
    cluster instead, whose workers must see both folders at the same paths.
    ``progress(summary)`` is called after each file. Returns the
    :class:`BatchSummary` (or fills ``summary``); on KeyboardInterrupt the
    files in progress are finished or cleaned up, the summary is marked
    interrupted and the interrupt re-raised.
    """
    if int(jobs) < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    warper = Warper(transform, output_shape, order=order, mode=mode, cval=cval, backend=backend)
    pairs = _plan(input_dir, output_dir, pattern)
    Path(output_dir).mkdir(parents=True, exist_ok=True)
    summary = BatchSummary() if summary is None else summary
    summary.total = len(pairs)

    def record(result):
        summary.record(*result)
        if progress is not None:
            progress(summary)

    try:
        if scheduler is not None:
            _run_dask(pairs, warper, overwrite, scheduler, record)
        elif backend == "numpy":
            _run_threads(pairs, warper, overwrite, int(jobs), record)
        else:
            _run_device(pairs, warper, overwrite, int(jobs), record)
    except KeyboardInterrupt:
        summary.interrupted = True
        raise
    return summary


def _run_threads(pairs, warper, overwrite, jobs, record):
    """Whole files (read, warp, write) in ``jobs`` threads; at most ``jobs``
    files are queued beyond those running, bounding memory."""
    pool = ThreadPoolExecutor(jobs, thread_name_prefix="fpiwarp")
    inflight = set()
    try:
        for src, dst in pairs:
            _wait_below(inflight, 2 * jobs, record)
            inflight.add(pool.submit(_process, src, dst, warper, overwrite))
        for fut in _in_completion_order(inflight):
            record(fut.result())
    except KeyboardInterrupt:
        _finish_started(pool, inflight, record)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _wait_below(futures, limit, record):
    """Record finished futures, taking them out of the set, until fewer than
    ``limit`` are in flight (the set shrinks as each one is recorded, so an
    interruption never counts a file twice)."""
    while len(futures) >= limit:
        finished, _ = wait(futures, return_when=FIRST_COMPLETED)
        for fut in finished:
            futures.discard(fut)
            record(fut.result())


def _finish_started(pool, futures, record):
    """After Ctrl-C: drop queued files, let started ones finish (each write
    is atomic), and count what they did."""
    pool.shutdown(wait=True, cancel_futures=True)
    for fut in futures:
        if fut.done() and not fut.cancelled() and fut.exception() is None:
            record(fut.result())


def _in_completion_order(futures):
    pending = set(futures)
    while pending:
        finished, pending = wait(pending, return_when=FIRST_COMPLETED)
        yield from finished


class _Read:
    """Reading one file in a worker thread for a device backend."""

    def __init__(self, src, dst, overwrite):
        self.src, self.dst = src, dst
        if not overwrite and dst.exists():
            self.result = ("skipped", str(src), None)
            return
        self.result = None
        try:
            self.image, self.info = read_image(src)
            channels = 1 if self.image.ndim == 2 else self.image.shape[2]
            check_writable(dst, self.image.dtype, channels, self.info)
        except (ImageError, OSError, ValueError) as exc:
            self.result = ("failed", str(src), _reason(exc))


def _write(read, out, overwrite):
    try:
        read.dst.parent.mkdir(parents=True, exist_ok=True)
        write_image(read.dst, out, read.info, overwrite=overwrite)
        return "done", str(read.src), None
    except OutputExistsError:
        return "skipped", str(read.src), None
    except (ImageError, OSError, ValueError) as exc:
        return "failed", str(read.src), _reason(exc)


def _run_device(pairs, warper, overwrite, jobs, record):
    """Reading and writing in ``jobs`` threads, warping in this thread:
    GPU contexts (GL above all) belong to the thread that made them."""
    pool = ThreadPoolExecutor(jobs, thread_name_prefix="fpiwarp-io")
    reads = collections.deque()
    writes = set()
    todo = iter(pairs)
    try:
        while True:
            while len(reads) < jobs + 1:
                pair = next(todo, None)
                if pair is None:
                    break
                reads.append(pool.submit(_Read, pair[0], pair[1], overwrite))
            if not reads:
                break
            read = reads.popleft().result()
            if read.result is not None:
                record(read.result)
                continue
            try:
                out = warper(read.image)
            except (ValueError, InverseNotConvergedError) as exc:
                record(("failed", str(read.src), _reason(exc)))
                continue
            del read.image
            _wait_below(writes, jobs, record)
            writes.add(pool.submit(_write, read, out, overwrite))
        for fut in _in_completion_order(writes):
            record(fut.result())
    except KeyboardInterrupt:
        _finish_started(pool, writes, record)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


# --------------------------------------------------------------------------
# Dask

_WORKER_WARPERS = collections.OrderedDict()
_WORKER_LOCK = threading.Lock()


def _dask_task(token, warper, src, dst, overwrite):
    """One file on a Dask worker; the warper (and its cached map) is kept
    per worker process for the run identified by ``token``."""
    with _WORKER_LOCK:
        warper = _WORKER_WARPERS.setdefault(token, warper)
        while len(_WORKER_WARPERS) > 2:
            _WORKER_WARPERS.popitem(last=False)
    return _process(Path(src), Path(dst), warper, overwrite)


def _dask_client(scheduler):
    try:
        from distributed import Client
    except ImportError:
        raise ImportError("--scheduler needs Dask: pip install 'dask[distributed]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    try:
        return Client(scheduler, timeout=DASK_CONNECT_TIMEOUT), True
    except (OSError, TimeoutError) as exc:
        raise ConnectionError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from None


def _run_dask(pairs, warper, overwrite, scheduler, record):
    """Each file is a task on the cluster; a bounded window of tasks is in
    flight. Workers read and write the files themselves."""
    from distributed import as_completed

    client, owned = _dask_client(scheduler)
    token = uuid.uuid4().hex
    window = max(4, 2 * sum(client.nthreads().values()))
    todo = iter(pairs)
    futures = []
    try:

        def submit():
            pair = next(todo, None)
            if pair is None:
                return None
            src, dst = (str(Path(p).absolute()) for p in pair)
            fut = client.submit(_dask_task, token, warper, src, dst, overwrite, pure=False)
            futures.append(fut)
            return fut

        first = [f for f in (submit() for _ in range(window)) if f is not None]
        queue = as_completed(first)
        for fut in queue:
            record(fut.result())
            nxt = submit()
            if nxt is not None:
                queue.add(nxt)
    except KeyboardInterrupt:
        client.cancel([f for f in futures if not f.done()])
        raise
    finally:
        if owned:
            client.close()


# --------------------------------------------------------------------------
# Progress


class Progress:
    """A progress bar on a terminal stream (tqdm when installed, else a
    one-line text bar); silent when the stream is not a terminal."""

    def __init__(self, total, stream=None, enabled=None):
        self.stream = stream if stream is not None else sys.stderr
        self.total = total
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.start = time.monotonic()
        self._bar = None
        if self.enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                pass
            else:
                self._bar = tqdm(total=total, file=self.stream, unit="img", leave=False)

    def __call__(self, summary):
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(summary.processed - self._bar.n)
            return
        done, total = summary.processed, max(self.total, 1)
        width = 30
        filled = int(width * done / total)
        rate = done / max(time.monotonic() - self.start, 1e-9)
        line = f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{self.total} files, {rate:.1f}/s"
        if summary.failed:
            line += f", {len(summary.failed)} failed"
        self.stream.write(line)
        self.stream.flush()

    def close(self):
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.close()
        else:
            self.stream.write("\r\033[K")
            self.stream.flush()
