"""Run the benchmarks: ``python3 -m benchmarks [--quick] [--out DIR] [--only speed|quality|antialias|arrays|batch]``.

Writes into DIR (default: benchmarks/results next to this file), with
stable names so a rerun replaces the previous results:

- machine.json: CPU model, ISA, PoCL device, cores, load, library
  versions, backend devices (:func:`benchmarks.common.machine_facts`);
- speed.md, speed.json, speed_scaling.png: times and ratios to the peers;
- quality.md, quality.json, quality_fig8.png, quality_fig11.png: the
  §5.1 distortion table and the Fig. 8 / Fig. 11 pictures;
- antialias.md, antialias.json, antialias_crops.png: antialiasing's PSNR
  against a supersampled reference beside the peers, and its cost;
- arrays.md, arrays.json: warp_image end to end from numpy and from
  device-resident arrays (pyopencl, Warp, JAX, textures) vs the kernel alone;
- batch.md, batch.json: stacks in one warp_batch call against the
  per-image loop, per backend (:mod:`benchmarks.batch_stacks`).

``--quick`` is a smoke run of a few seconds (small sizes, coarse grids)
that exercises every code path; its numbers mean little.
"""

import argparse
import os
import sys
import time
from pathlib import Path

from . import antialias, arrays, batch_stacks, quality, speed
from .common import RESULTS as DEFAULT_OUT
from .common import machine_facts, machine_markdown, write_file, write_json, write_text


def parse_args(argv):
    parser = argparse.ArgumentParser(prog="python3 -m benchmarks", description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes: a smoke run of a few seconds")
    parser.add_argument(
        "--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default: {DEFAULT_OUT.name}/ beside this file)"
    )
    parser.add_argument("--only", choices=("speed", "quality", "antialias", "arrays", "batch"),
                        help="run one part only")
    parser.add_argument(
        "--backends",
        type=lambda s: [b for b in s.split(",") if b],
        help="comma-separated fpiwarp backends to time (default: every available one)",
    )
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    info = machine_facts()
    info["mode"] = "quick" if args.quick else "full"
    machine_md = machine_markdown(info)

    def log(msg):
        print(msg, flush=True)

    if args.only in (None, "speed"):
        import fpiwarp

        backends = args.backends
        if backends is not None:
            unknown = [b for b in backends if b not in fpiwarp.backend_status()]
            if unknown:
                sys.exit(f"unknown backend(s) {unknown}; choose from {sorted(fpiwarp.backend_status())}")
        settings = speed.Settings.quick(backends) if args.quick else speed.Settings.full(backends)
        t0 = time.perf_counter()
        results = speed.run(settings, log=log)
        info["speed_wall_s"] = round(time.perf_counter() - t0, 1)
        write_text(out / "speed.md", speed.markdown(results, settings, machine_md))
        write_json(out / "speed.json", {"machine": info, "results": speed.to_json(results)})
        from . import plots

        write_file(out / "speed_scaling.png", lambda p: plots.speed_scaling(results, p, dpi=50 if args.quick else 90))

    if args.only in (None, "quality"):
        t0 = time.perf_counter()
        if args.quick:  # two of each kind, on a coarse grid
            configs = [c for c in quality.CONFIGS if c.name in ("fig8 col1", "dart")]
            result = quality.run(40, configs, quality.CONSTRAINED_CONFIGS[::2], log=log)
        else:
            result = quality.run(200, log=log)
        info["quality_wall_s"] = round(time.perf_counter() - t0, 1)
        write_text(out / "quality.md", quality.markdown(result, machine_md))
        write_json(out / "quality.json", {"machine": info, **quality.to_json(result)})
        from . import plots

        n, dpi = (16, 50) if args.quick else (64, 80)
        write_file(out / "quality_fig8.png", lambda p: plots.fig8(result, p, n=n, dpi=dpi))
        if result.get("constrained"):
            write_file(out / "quality_fig11.png", lambda p: plots.fig11(result, p, n=n, dpi=dpi))

    if args.only in (None, "antialias"):
        t0 = time.perf_counter()
        result = antialias.run(quick=args.quick, log=log, backends=args.backends)
        info["antialias_wall_s"] = round(time.perf_counter() - t0, 1)
        write_text(out / "antialias.md", antialias.markdown(result, machine_md))
        write_json(out / "antialias.json", {"machine": info, **antialias.to_json(result)})
        write_file(out / "antialias_crops.png", lambda p: antialias.figure(result, p, dpi=50 if args.quick else 90))

    if args.only in (None, "arrays"):
        t0 = time.perf_counter()
        rows = arrays.run(quick=args.quick, backends=args.backends, log=log)
        info["arrays_wall_s"] = round(time.perf_counter() - t0, 1)
        write_text(out / "arrays.md", arrays.markdown(rows, machine_md))
        write_json(out / "arrays.json", {"machine": info, "results": rows})

    if args.only in (None, "batch"):
        t0 = time.perf_counter()
        result = batch_stacks.run(quick=args.quick, backends=args.backends, log=log)
        info["batch_wall_s"] = round(time.perf_counter() - t0, 1)
        write_text(out / "batch.md", batch_stacks.markdown(result, machine_md))
        write_json(out / "batch.json", {"machine": info, **result})

    try:
        info["load_average_at_end"] = [round(v, 2) for v in os.getloadavg()]
    except OSError:
        pass
    info["wall_s"] = round(time.perf_counter() - t_start, 1)
    write_json(out / "machine.json", info)
    log(f"wrote {out} in {info['wall_s']} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
