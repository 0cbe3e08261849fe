"""Reuse of host sources' pyramids (fpiwarp.sampling.pyramid.SourcePyramids).

A 1920 × 1080 RGB uint8 picture warped by the FPI shrink of the antialias
benchmark (benchmarks/antialias.py ``fpi_shrink``) on one backend, timed
interleaved in one process (best of several rounds): the plain warp, the
antialiased warp reading the kept pyramid (every call after the first of
one picture), and the antialiased warp with the kept pyramids cleared
before each call (a build per call: what the opencl backend did before
issue 29's reuse). Ratios are against the plain warp.

    python3 -m benchmarks.pyramid_reuse [--backend opencl] [--shrink 8] [--repeats 7]
"""

import argparse

import numpy as np

import fpiwarp
from fpiwarp.backends import get_backend

from . import common
from .antialias import COST_SIZE, fpi_shrink


def measure(backend="opencl", shrink=8, repeats=7):
    """{case: best seconds} and the ratios to the plain warp."""
    h, w = COST_SIZE
    image = np.random.default_rng(0).integers(0, 256, size=(h, w, 3), dtype=np.uint8)
    transform, shape = fpi_shrink(h, w, shrink)
    kept = get_backend(backend).host_pyramids

    def rebuilt():
        kept.clear()
        return fpiwarp.warp_image(image, transform, shape, backend=backend, antialias=True)

    calls = {
        "plain": lambda: fpiwarp.warp_image(image, transform, shape, backend=backend),
        "antialias, pyramid reused": lambda: fpiwarp.warp_image(image, transform, shape, backend=backend,
                                                                 antialias=True),
        "antialias, pyramid built per call": rebuilt,
    }
    times, results = common.interleaved(calls, repeats)
    assert np.array_equal(results["antialias, pyramid reused"], results["antialias, pyramid built per call"])
    best = common.bests(times)
    return best, {name: best[name] / best["plain"] for name in best}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backend", default="opencl")
    parser.add_argument("--shrink", type=float, default=8)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    info = common.machine_facts(backends=False)
    best, ratios = measure(args.backend, args.shrink, args.repeats)
    print(f"{args.backend}, 1920x1080 RGB uint8, FPI shrink 1/{args.shrink:g}, best of {args.repeats} interleaved:")
    for name in best:
        print(f"  {name:36s} {common.fmt_time(best[name]):>10s}  {ratios[name]:.2f}x plain")
    print(common.machine_line(info))


if __name__ == "__main__":
    main()
