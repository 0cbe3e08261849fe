"""warp_batch against its loop on each backend, wall and CPU time (issue 24).

The ``64 maps`` case of :mod:`benchmarks.batch_stacks` (64 images of 512²
RGB uint8, 64 different FPIs, bilinear): the per-image loop of
``fpiwarp.warp_image`` and one ``fpiwarp.warp_batch`` call on each backend
given, all interleaved round by round in one process. Each call's wall
time and its process CPU time (every thread's: PoCL's, Warp's and
llvmpipe's workers run in this process) are recorded; the table gives the
best of the rounds, and the load average at the start and the end. CPU
time holds up better than wall time on a shared machine.

``--before`` adds the opencl batch as it was before issue 24's fix: its
kernels built from the kernels' source with the batch item selected by
``get_global_id(2)`` instead of ``get_group_id(2)`` (``FW_BATCH_SELECT``
in ``kernels/opencl/fpiwarp.cl``), so old and new are measured side by
side. Every batch is checked bit for bit against its loop.

Run: ``python3 -m benchmarks.batch_loop [--quick] [--rounds N]
[--backends opencl,warp,gl] [--before] [--out DIR]``; writes
``batch_loop.md`` and ``.json`` under ``--out`` (default
``benchmarks/results``).
"""

import argparse
import contextlib
import os
import sys
import time
from pathlib import Path

import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend

from .batch_stacks import FULL, QUICK, maps_case
from .common import RESULTS, machine_facts, machine_markdown, write_json, write_text

BACKENDS = ("opencl", "warp", "gl")
#: The batch item's selection in the kernels' source, after and before the fix.
SELECT_AFTER = "size_t fw_z = get_group_id(2), fw_n = which[fw_z];"
SELECT_BEFORE = "size_t fw_z = get_global_id(2), fw_n = which[fw_z];"
BEFORE = "opencl, before (get_global_id)"
_BUILT_BEFORE = {}  # id(backend) -> {options: {name: kernel}} of the programs built with SELECT_BEFORE


@contextlib.contextmanager
def global_id_batches(backend):
    """Within the block, the opencl ``backend``'s batch programs (built with
    ``-DFW_BATCH=1``) are built from the source with :data:`SELECT_BEFORE`."""
    import pyopencl as cl  # noqa: PLC0415 - optional dependency

    if SELECT_AFTER not in backend._source:
        raise RuntimeError("the kernels' source no longer selects batch items as SELECT_AFTER says")
    source, plain = backend._source.replace(SELECT_AFTER, SELECT_BEFORE), backend.kernel
    built = _BUILT_BEFORE.setdefault(id(backend), {})

    def kernel(name, options=()):
        if "-DFW_BATCH=1" not in options:
            return plain(name, options)
        options = tuple(backend.BASE_OPTIONS) + tuple(options)
        if options not in built:
            program = cl.Program(backend.context, source).build(options=list(options))
            built[options] = {k.function_name: k for k in program.all_kernels()}
        return built[options][name]

    backend.kernel = kernel
    try:
        yield
    finally:
        del backend.kernel


def calls(stack, maps, backends, before):
    """{(backend label, "loop" or "batch"): a zero-argument call}."""
    out = {}
    for b in backends:
        out[b, "loop"] = lambda b=b: np.stack([fpiwarp.warp_image(im, t, backend=b) for im, t in zip(stack, maps)])
        out[b, "batch"] = lambda b=b: fpiwarp.warp_batch(stack, maps, backend=b)
    if before and "opencl" in backends:
        def old_batch():
            with global_id_batches(get_backend("opencl")):
                return fpiwarp.warp_batch(stack, maps, backend="opencl")
        out[BEFORE, "batch"] = old_batch
    return out


def run(backends=BACKENDS, quick=False, rounds=None, before=False, log=print):
    """One interleaved run; a dict for :func:`markdown` and JSON."""
    sizes = QUICK if quick else FULL
    available = fpiwarp.available_backends()
    backends = [b for b in backends if b in available]
    stack, maps = maps_case(sizes)
    fns = calls(stack, maps, backends, before)
    load_start = os.getloadavg()[0]
    results = {key: fn() for key, fn in fns.items()}  # warm-up: kernels built, buffers kept
    wall, cpu = {key: [] for key in fns}, {key: [] for key in fns}
    for _ in range(rounds or sizes["repeats"]):
        for key, fn in fns.items():
            w0, c0 = time.perf_counter(), time.process_time()
            results[key] = fn()
            wall[key].append(time.perf_counter() - w0)
            cpu[key].append(time.process_time() - c0)
    rows = []
    for label, part in fns:
        loop = "opencl" if label == BEFORE else label
        rows.append({"backend": label, "part": part, "wall_s": min(wall[label, part]), "cpu_s": min(cpu[label, part]),
                     "wall_median_s": float(np.median(wall[label, part])),
                     "equal": bool(np.array_equal(results[label, part], results[loop, "loop"]))})
        log(f"{label} {part}: wall {rows[-1]['wall_s'] * 1e3:.1f} ms, CPU {rows[-1]['cpu_s'] * 1e3:.1f} ms")
    n, h, w = sizes["stack"]
    return {"case": f"{n} x {w}x{h} RGB uint8, {n} FPIs, bilinear", "rounds": rounds or sizes["repeats"],
            "load_start": load_start, "load_end": os.getloadavg()[0], "rows": rows}


def markdown(result, machine_md=""):
    """The table of batch_loop.md: per backend, loop and batch, and their ratios."""
    by = {(r["backend"], r["part"]): r for r in result["rows"]}
    lines = ["# warp_batch against its loop: wall and CPU time", "", machine_md, "",
             f"{result['case']}; best of {result['rounds']} interleaved rounds in one process, load average "
             f"{result['load_start']:.2f} at the start, {result['load_end']:.2f} at the end. CPU time: the "
             "process's, all threads.", "",
             "| backend | loop wall | batch wall | loop / batch wall | loop CPU | batch CPU | loop / batch CPU | "
             "batch == loop |", "|---|---:|---:|---:|---:|---:|---:|:---:|"]
    for (label, part), r in by.items():
        if part != "batch":
            continue
        loop = by["opencl" if label == BEFORE else label, "loop"]
        cells = []
        for clock in ("wall_s", "cpu_s"):
            cells += [f"{loop[clock] * 1e3:.1f} ms", f"{r[clock] * 1e3:.1f} ms", f"{loop[clock] / r[clock]:.2f}x"]
        cells.append("yes" if r["equal"] else "NO")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small sizes, one round (a smoke run)")
    p.add_argument("--rounds", type=int, default=None)
    p.add_argument("--backends", default=",".join(BACKENDS))
    p.add_argument("--before", action="store_true", help="also the opencl batch as before issue 24's fix")
    p.add_argument("--out", default=str(RESULTS))
    args = p.parse_args(argv)
    info = machine_facts()
    result = run(tuple(b for b in args.backends.split(",") if b), args.quick, args.rounds, args.before)
    result["machine"] = info
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = markdown(result, machine_markdown(info))
    write_text(out / "batch_loop.md", text)
    write_json(out / "batch_loop.json", result)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
