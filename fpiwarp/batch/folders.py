"""Warping every image of a folder into another folder.

:func:`run_batch` works in parallel threads (or on a Dask cluster, see
:mod:`fpiwarp.batch.dask`), skips outputs that exist (so a rerun resumes),
writes each output atomically, and collects the files that fail in a
:class:`BatchSummary` instead of stopping. Temporary files that a killed
run left in the output folder are removed when older than
:data:`STALE_TEMP_SECONDS` and listed otherwise.

A backend whose capabilities say ``thread_safe`` (numpy) runs whole files
in worker threads; the others (GPU contexts belong to one thread) warp in
the calling thread while worker threads read and write.
"""

import collections
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

from PIL import Image

from ..errors import ArgumentError, FpiwarpError, OutputExistsError
from ..io.images import TEMP_SUFFIX, check_writable, is_temp_file, read_image, write_image
from ..io.orientation import check_choice as check_orientation
from ..io.pillow import check_damaged
from ..warping import Warper
from .files import FILE_ERRORS, FileOptions, process_file, reason_of

__all__ = ["STALE_TEMP_SECONDS", "BatchSummary", "list_inputs", "process_file", "run_batch"]

#: A temporary output file untouched for this long was left by a killed
#: run (a live write renames its file within seconds) and is removed.
STALE_TEMP_SECONDS = 3600


def one_line(text):
    """``text`` with newlines and other control characters escaped, so that
    a file name cannot break a one-line-per-file report."""
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in str(text))


@dataclass
class BatchSummary:
    """What a folder batch did: outputs written, skipped because they
    existed, (input, reason) for each file that failed, and temporary
    files left by an earlier, killed run (removed, or kept when recent)."""

    total: int = 0
    done: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    failed: list = field(default_factory=list)
    interrupted: bool = False
    removed_temps: list = field(default_factory=list)
    recent_temps: list = field(default_factory=list)
    #: Files of the input folder left out because their extension is not an
    #: image format's (notes.txt, ...): listed, not failed.
    ignored: list = field(default_factory=list)
    #: {input path: (width, height)} of the warped inputs.
    sizes: dict = field(default_factory=dict)

    @property
    def processed(self):
        return len(self.done) + len(self.skipped) + len(self.failed)

    @property
    def ok(self):
        return not self.failed and not self.interrupted

    def record(self, status, path, reason=None, size=None):
        if status == "done":
            self.done.append(path)
            if size is not None:
                self.sizes[path] = tuple(size)
        elif status == "skipped":
            self.skipped.append(path)
        else:
            self.failed.append((path, reason))

    def report(self):
        """Lines for the user: counts, then one line per failed file (names
        with newlines or other control characters escaped)."""
        counts = (
            f"{len(self.done)} warped, {len(self.skipped)} skipped (output exists), "
            f"{len(self.failed)} failed, of {self.total} files"
        )
        lines = [counts]
        if self.skipped:
            lines.append("skipped files already have an output; pass --overwrite to redo them")
        if self.interrupted:
            lines.append(f"interrupted: {self.total - self.processed} files not done; run again to resume")
        if self.removed_temps:
            lines.append(f"removed {len(self.removed_temps)} temporary files left by an interrupted run")
        for path in self.recent_temps:
            lines.append(f"temporary file of a run in progress or just killed: {one_line(path)} "
                         "(delete it if no other run writes to this folder)")
        lines += self.size_notes()
        for path in self.ignored:
            lines.append(f"ignored (not an image file; name it with --pattern or --ext to include it): "
                         f"{one_line(path)}")
        for path, reason in sorted(self.failed, key=lambda item: str(item[0])):
            prefix = f"{path}: "
            reason = reason[len(prefix):] if reason.startswith(prefix) else reason
            lines.append(f"failed: {one_line(path)}: {one_line(reason)}")
        return lines


    def size_notes(self):
        """One line per warped image whose size differs from the first's
        (in name order): the map's pixel coordinates applied to it as they are."""
        if len(set(self.sizes.values())) < 2:
            return []
        first = min(self.sizes)
        w0, h0 = self.sizes[first]
        return [
            f"size differs: {one_line(path)} is {w}x{h}, {one_line(first)} {w0}x{h0}; the map's pixel "
            "coordinates were applied as they are (give each size its own spec)"
            for path, (w, h) in sorted(self.sizes.items()) if (w, h) != (w0, h0)
        ]


def image_extensions():
    """The file extensions (lower case, with the dot) of the formats Pillow
    reads, which a folder batch takes by default."""
    Image.init()
    return {ext for ext, fmt in Image.registered_extensions().items() if fmt in Image.OPEN}


def _extension_set(extensions):
    if extensions is None:
        return None
    if isinstance(extensions, str):
        extensions = extensions.split(",")
    out = {("." + e.strip().lstrip(".")).lower() for e in extensions if e.strip().lstrip(".")}
    if not out:
        raise ArgumentError(f"extensions must name at least one extension like 'jpg,png', got {extensions!r}")
    return out


def list_inputs(input_dir, pattern=None, exclude=None, extensions=None, ignored=None):
    """Sorted files of ``input_dir`` matching the glob ``pattern`` (default
    every file at the top level; ``**/*`` recurses), without hidden files,
    fpiwarp's temporary files, and anything under ``exclude``.

    ``extensions`` (a list, or "jpg,png") keeps the files with one of them.
    Without ``pattern`` and ``extensions``, files whose extension is no
    image format's (notes.txt, a spec.json) are left out and appended to
    the list ``ignored`` when given; a pattern or extension that names
    them explicitly takes them (and they fail if they are not images)."""
    root = Path(input_dir)
    if not root.exists():
        raise FileNotFoundError(f"input folder does not exist: {root}")
    if not root.is_dir():
        raise NotADirectoryError(f"input is not a folder: {root}")
    if pattern is not None and (not pattern or Path(pattern).is_absolute()):
        raise ArgumentError(f"the pattern must be a glob relative to the input folder, like '*.jpg', got {pattern!r}")
    excluded = Path(exclude).resolve() if exclude is not None else None
    if excluded is not None and excluded not in root.resolve().parents and excluded != root.resolve():
        excluded_inside = excluded  # an output folder inside the input tree: skip what is in it
    else:
        excluded_inside = None  # the output folder holds the inputs (or is elsewhere): skip nothing
    wanted = _extension_set(extensions)
    images = image_extensions() if pattern is None and wanted is None else None
    found, left_out = [], []
    for path in root.glob(pattern or "*"):
        rel = path.relative_to(root)
        if any(part.startswith(".") for part in rel.parts) or is_temp_file(path) or not path.is_file():
            continue
        if excluded_inside is not None and excluded_inside in path.resolve().parents:
            continue
        if wanted is not None and path.suffix.lower() not in wanted:
            continue
        if images is not None and path.suffix.lower() not in images:
            left_out.append(str(path))
            continue
        found.append(path)
    if ignored is not None:
        ignored.extend(sorted(left_out))
    return sorted(found)


def plan(input_dir, output_dir, pattern, extensions=None, ignored=None):
    """[(input, output)] pairs; refuses any output that is an input."""
    inputs = list_inputs(input_dir, pattern, exclude=output_dir, extensions=extensions, ignored=ignored)
    root, out_root = Path(input_dir), Path(output_dir)
    if root.resolve() == out_root.resolve():
        raise ArgumentError("the output folder is the input folder; choose another (inputs are never modified)")
    pairs = [(p, out_root / p.relative_to(root)) for p in inputs]
    input_set = {p.resolve() for p in inputs}
    for _, out in pairs:
        if out.resolve() in input_set:
            raise ArgumentError(f"output {out} would replace an input file; choose an output folder outside the input")
    return pairs


def sweep_temporaries(output_dir, summary, now=None):
    """Remove the temporary files under ``output_dir`` older than
    :data:`STALE_TEMP_SECONDS`; note them, and the younger ones, in ``summary``."""
    now = time.time() if now is None else now
    for path in sorted(Path(output_dir).rglob(f"*{TEMP_SUFFIX}")):
        if not is_temp_file(path) or not path.is_file():
            continue
        try:
            if now - path.stat().st_mtime > STALE_TEMP_SECONDS:
                path.unlink()
                summary.removed_temps.append(str(path))
            else:
                summary.recent_temps.append(str(path))
        except FileNotFoundError:  # its run just renamed or removed it
            continue


def run_batch(
    transform,
    input_dir,
    output_dir,
    *,
    pattern=None,
    jobs=1,
    overwrite=False,
    backend=None,
    order=1,
    mode="constant",
    cval=0,
    output_shape=None,
    progress=None,
    scheduler=None,
    summary=None,
    backend_options=None,
    orientation="apply",
    antialias=False,
    extensions=None,
    damaged="refuse",
):
    """Warp every image file of ``input_dir`` into ``output_dir``.

    The command line's ``fpiwarp batch SPEC INPUT_DIR OUTPUT_DIR``. Outputs
    keep the input's relative path, name, format, dtype, channels and
    metadata, and are written atomically; inputs are never modified.

    Parameters
    ----------
    transform : Transform
        One map for every file (source to output coordinates, x = column,
        y = row).
    input_dir, output_dir : str or path-like
        The folders; ``output_dir`` is created if needed.
    pattern : str, optional
        A glob pattern the files must match (default: every file whose
        extension is an image format's; the others, such as notes.txt, are
        listed in ``summary.ignored`` and the report, not failed).
    extensions : str or list of str, optional
        Only files with these extensions ("jpg,png" or ["jpg", "png"]).
    damaged : {"refuse", "accept"}, optional
        As in :func:`fpiwarp.read_image`: damaged files fail (default) or
        are decoded as far as they go.
    jobs : int, optional
        Threads working in parallel, with at most a few images in memory
        per thread (backends that are not thread safe run in this thread).
    overwrite : bool, optional
        Redo existing outputs; by default they are kept and counted as
        skipped, so a rerun resumes.
    backend, order, mode, cval, output_shape, backend_options, antialias
        As in :func:`fpiwarp.warp_image`.
    progress : callable, optional
        ``progress(summary)`` is called after each file.
    scheduler : str or distributed.Client, optional
        Run the files on a Dask cluster (``pip install 'fpiwarp[dask]'``)
        whose workers see both folders at the same paths.
    summary : BatchSummary, optional
        Filled in place instead of a new one.
    orientation : {"apply", "stored"}, optional
        The EXIF orientation rule of :func:`fpiwarp.read_image`: "apply"
        (default) warps each photo as viewers show it.

    Returns
    -------
    BatchSummary
        What was written, skipped and failed. Files that cannot be read or
        written are recorded as failed and the others processed. One map
        serves every size: an image whose size differs from the first's
        (in name order) is warped with the map's pixel coordinates as they
        are, and the report says so (``summary.size_notes()``).

    Raises
    ------
    ArgumentError
        ``jobs`` below 1, and bad warp options (before any file is read).
    KeyboardInterrupt
        Re-raised after the files in progress are finished or cleaned up;
        the summary is marked interrupted.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import fpiwarp
    >>> from fpiwarp.batch.folders import run_batch
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> (root / "in").mkdir()
    >>> for name in ("a.png", "b.png"):
    ...     fpiwarp.write_image(root / "in" / name, np.zeros((8, 8), np.uint8))
    >>> f = fpiwarp.FPI([[0, 0], [7, 0], [7, 7], [0, 7]], [[1, 0], [7, 1], [6, 7], [0, 6]])
    >>> run_batch(f, root / "in", root / "out").report()[0]
    '2 warped, 0 skipped (output exists), 0 failed, of 2 files'
    >>> run_batch(f, root / "in", root / "out").report()[0]        # a rerun skips them
    '0 warped, 2 skipped (output exists), 0 failed, of 2 files'
    """
    if int(jobs) < 1:
        raise ArgumentError(f"jobs must be at least 1, got {jobs}")
    check_orientation(orientation)
    check_damaged(damaged)
    options = FileOptions(overwrite=bool(overwrite), orientation=orientation, damaged=damaged)
    warper = Warper(transform, output_shape, order=order, mode=mode, cval=cval, backend=backend,
                    backend_options=backend_options, antialias=antialias)
    summary = BatchSummary() if summary is None else summary
    pairs = plan(input_dir, output_dir, pattern, extensions, summary.ignored)
    Path(output_dir).mkdir(parents=True, exist_ok=True)
    summary.total = len(pairs)
    sweep_temporaries(output_dir, summary)

    def record(result):
        summary.record(*result)
        if progress is not None:
            progress(summary)

    try:
        if scheduler is not None:
            from .dask import run_on_dask

            run_on_dask(pairs, warper, options, scheduler, record)
        elif warper.capabilities.thread_safe:
            _run_in_worker_threads(pairs, warper, options, int(jobs), record)
        else:
            _run_in_this_thread(pairs, warper, options, int(jobs), record)
    except KeyboardInterrupt:
        summary.interrupted = True
        raise
    return summary


def _run_in_worker_threads(pairs, warper, options, jobs, record):
    """Whole files (read, warp, write) in ``jobs`` threads; at most ``jobs``
    files are queued beyond those running, bounding memory."""
    pool = ThreadPoolExecutor(jobs, thread_name_prefix="fpiwarp")
    inflight = set()
    try:
        for src, dst in pairs:
            _wait_below(inflight, 2 * jobs, record)
            inflight.add(pool.submit(process_file, src, dst, warper, options))
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
    """Reading one file in a worker thread for a backend bound to one thread."""

    def __init__(self, src, dst, options):
        self.src, self.dst = src, dst
        if not options.overwrite and dst.is_file():
            self.result = ("skipped", str(src), None)
            return
        self.result = None
        try:
            self.image, self.info = read_image(src, orientation=options.orientation, with_info=True,
                                               damaged=options.damaged)
            channels = 1 if self.image.ndim == 2 else self.image.shape[2]
            check_writable(dst, self.image.dtype, channels, self.info)
        except FILE_ERRORS as exc:
            self.result = ("failed", str(src), reason_of(exc))


def _write(read, out, options):
    try:
        read.dst.parent.mkdir(parents=True, exist_ok=True)
        write_image(read.dst, out, read.info, overwrite=options.overwrite)
        return "done", str(read.src), None, (read.size[1], read.size[0])
    except OutputExistsError:
        return "skipped", str(read.src), None
    except FILE_ERRORS as exc:
        return "failed", str(read.src), reason_of(exc)


def _run_in_this_thread(pairs, warper, options, jobs, record):
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
                reads.append(pool.submit(_Read, pair[0], pair[1], options))
            if not reads:
                break
            read = reads.popleft().result()
            if read.result is not None:
                record(read.result)
                continue
            try:
                out = warper(read.image)
            except FpiwarpError as exc:
                record(("failed", str(read.src), reason_of(exc)))
                continue
            read.size = read.image.shape[:2]
            del read.image
            _wait_below(writes, jobs, record)
            writes.add(pool.submit(_write, read, out, options))
        for fut in _in_completion_order(writes):
            record(fut.result())
    except KeyboardInterrupt:
        _finish_started(pool, writes, record)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
