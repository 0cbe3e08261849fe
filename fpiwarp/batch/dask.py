"""Folder batches on a Dask cluster: each file is a task on a worker.

Workers read and write the files themselves, so they must see the input
and output folders at the same paths. A bounded window of tasks is in
flight; each worker keeps the warper (and its bound map) of the run.
"""

import collections
import threading
import uuid
from pathlib import Path

from ..errors import MissingDependencyError
from .files import process_file

__all__ = ["DASK_CONNECT_TIMEOUT", "run_on_dask"]

#: How long to try reaching a Dask scheduler before giving up.
DASK_CONNECT_TIMEOUT = "10s"

_WORKER_WARPERS = collections.OrderedDict()
_WORKER_LOCK = threading.Lock()


def _dask_task(token, warper, src, dst, options):
    """One file on a Dask worker; the warper (and its cached map) is kept
    per worker process for the run identified by ``token``."""
    with _WORKER_LOCK:
        warper = _WORKER_WARPERS.setdefault(token, warper)
        while len(_WORKER_WARPERS) > 2:
            _WORKER_WARPERS.popitem(last=False)
    return process_file(Path(src), Path(dst), warper, options)


def _dask_client(scheduler):
    try:
        from distributed import Client
    except ImportError:
        raise MissingDependencyError("--scheduler needs Dask: pip install 'dask[distributed]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    try:
        return Client(scheduler, timeout=DASK_CONNECT_TIMEOUT), True
    except (OSError, TimeoutError) as exc:
        raise ConnectionError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from None


def run_on_dask(pairs, warper, options, scheduler, record):
    """Run the (input, output) ``pairs`` as tasks on the cluster at
    ``scheduler`` (an address or a ``distributed.Client``); ``record`` each
    result as it arrives."""
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
            fut = client.submit(_dask_task, token, warper, src, dst, options, pure=False)
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
