"""Speed workloads beyond the FPI's scaling tables (see :mod:`benchmarks.speed`).

- ``warp_image local``: a ``LocalDeformation`` (edges 1 and 3 of a quad in
  the middle of the frame: a Newton inverse of a paired thin-plate
  spline inside, similarities beyond the two edges) and a ``ConstrainedFPI``
  of the image corners (edges 0 and 2, Newton inverse everywhere) warped
  per backend, uint8 RGB, beside the FPI warp of the same image on the same
  backend. The ratio of a map's row is to **that backend's FPI warp**
  (the issue's target: a local deformation at most 2× the FPI); the FPI
  rows carry their ratio to ``cv2.remap`` with precomputed maps.
- ``warp_image overhead``: small FPI warps (64² and 256² uint8 RGB), where
  fixed costs per call dominate: each backend's plain ``warp_image``, and
  the prepared form ``fpiwarp.Warper`` called on the image, beside
  ``cv2.remap`` with precomputed maps (the ratio baseline).
- ``preview frame`` rows (with the gl backend, in the local table): one
  frame of the preview's exact picture (:class:`fpiwarp.viewer.Renderer`,
  ``method="pixel"``) drawn into an offscreen framebuffer and waited for,
  the map already uploaded: the FPI's and the ``LocalDeformation``'s (the
  issue's target for the latter: at most 60 ms at 1080p on llvmpipe).
"""

import dataclasses

import numpy as np

import fpiwarp
from fpiwarp.warping import Warper

from .speed import IMAGE_BASELINE, _add_ratios, _brief, _measure, corner_quads, table, test_image

LOCAL_SIZES = [(1080, 1920), (2160, 3840)]
QUICK_LOCAL_SIZES = [(96, 128)]
OVERHEAD_SIZES = [(64, 64), (256, 256)]
#: Repeats of one overhead measurement (within the settings' time budget):
#: calls of 0.05-2 ms need hundreds for a best time that is not a first
#: call's (cold caches, a driver's worker threads waking up); the image
#: tables' 7 repeats read the 256² Warper 2-3x slower than it runs.
OVERHEAD_REPEATS = 300
MAPS = ("LocalDeformation", "ConstrainedFPI")


def local_deformation(height, width):
    """Edges 1 and 3 of a quad over the middle fifth of the frame held to
    similarities; its corners moved by 2-6 % of the size."""
    w, h = width - 1.0, height - 1.0
    src = np.array([[0.4 * w, 0.3 * h], [0.6 * w, 0.3 * h], [0.6 * w, 0.7 * h], [0.4 * w, 0.7 * h]])
    dst = src + np.array([[0.02 * w, -0.05 * h], [0.03 * w, 0.02 * h], [-0.02 * w, 0.06 * h], [0.01 * w, -0.03 * h]])
    return fpiwarp.LocalDeformation(src, dst, edges=(1, 3))


def constrained_fpi(height, width):
    src, dst = corner_quads(height, width)
    return fpiwarp.ConstrainedFPI(src, dst, edges=(0, 2))


def _remap_precomputed(image, transform):
    import cv2

    maps = fpiwarp.source_positions(transform, image.shape[:2]).astype(np.float32)
    mx, my = np.ascontiguousarray(maps[..., 0]), np.ascontiguousarray(maps[..., 1])
    return lambda: cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _warp(image, transform, name):
    return lambda: fpiwarp.warp_image(image, transform, order=1, mode="constant", backend=name)


def _preview_frame(image, transform):
    """One exact preview frame (Renderer, method "pixel") of ``transform``
    into an offscreen framebuffer, waited for; the objects live as long as
    the returned callable."""
    from fpiwarp.backends import get_backend
    from fpiwarp.viewer import Renderer

    ctx = get_backend("gl").warper.ctx
    height, width = image.shape[:2]
    renderer = Renderer(ctx, order=1, warper=get_backend("gl").warper, method="pixel")
    tex = ctx.texture((width, height), 4, dtype="f1")
    fbo = ctx.framebuffer(color_attachments=[tex])
    renderer.set_image(image)
    renderer.set_transform(transform)

    def frame():
        fbo.use()
        renderer.draw((0, 0, width, height), y_down=True)
        ctx.finish()

    frame.keep = (renderer, tex, fbo)
    return frame


def run_local(sizes, settings, backends, rng, log=print):
    """``warp_image local`` rows: each map per backend, ratio to its FPI."""
    results, last = [], {}
    for height, width in sizes:
        image = test_image(height, width, "uint8", rng)
        fpi = fpiwarp.FPI(*corner_quads(height, width))
        maps = {"LocalDeformation": local_deformation(height, width), "ConstrainedFPI": constrained_fpi(height, width)}
        impls = {IMAGE_BASELINE: ("peer", _remap_precomputed(image, fpi))}
        for name in backends:
            impls[f"fpiwarp {name} FPI"] = ("backend", _warp(image, fpi, name))
            for label, transform in maps.items():
                impls[f"fpiwarp {name} {label}"] = ("backend", _warp(image, transform, name))
        if "gl" in backends:
            impls["fpiwarp gl preview frame FPI"] = ("backend", _preview_frame(image, fpi))
            impls["fpiwarp gl preview frame LocalDeformation"] = (
                "backend", _preview_frame(image, maps["LocalDeformation"]))
        label = f"{height}x{width}"
        rows = _measure("warp_image local", label, height * width, "uint8", impls, settings, last)
        _add_ratios(rows, IMAGE_BASELINE)
        for name in backends:
            fpi_row = rows[f"fpiwarp {name} FPI"]
            for m in MAPS:
                row = rows[f"fpiwarp {name} {m}"]
                row.ratio = row.seconds / fpi_row.seconds if row.seconds and fpi_row.seconds else None
        if "gl" in backends:
            fpi_row, row = rows["fpiwarp gl preview frame FPI"], rows["fpiwarp gl preview frame LocalDeformation"]
            row.ratio = row.seconds / fpi_row.seconds if row.seconds and fpi_row.seconds else None
        results.extend(rows.values())
        log(f"warp_image local {label:>9s}: " + _brief(rows))
    return results


def run_overhead(sizes, settings, backends, rng, log=print):
    """``warp_image overhead`` rows: plain call and Warper per backend."""
    if settings.max_repeats > 1:  # not the quick smoke run
        settings = dataclasses.replace(settings, max_repeats=max(settings.max_repeats, OVERHEAD_REPEATS))
    results, last = [], {}
    for height, width in sizes:
        image = test_image(height, width, "uint8", rng)
        fpi = fpiwarp.FPI(*corner_quads(height, width))
        impls = {IMAGE_BASELINE: ("peer", _remap_precomputed(image, fpi))}
        for name in backends:
            impls[f"fpiwarp {name}"] = ("backend", _warp(image, fpi, name))
            warper = Warper(fpi, order=1, mode="constant", backend=name)
            impls[f"fpiwarp {name} Warper"] = ("backend", lambda warper=warper, image=image: warper(image))
        label = f"{height}x{width}"
        rows = _measure("warp_image overhead", label, height * width, "uint8", impls, settings, last)
        _add_ratios(rows, IMAGE_BASELINE)
        results.extend(rows.values())
        log(f"warp_image overhead {label:>9s}: " + _brief(rows))
    return results


def markdown_parts(results):
    """The sections of speed.md for these workloads (empty when not run)."""
    parts = []
    if any(r.workload == "warp_image local" for r in results):
        parts += [
            "",
            "## warp_image, local deformations (uint8 RGB)",
            "",
            "A `LocalDeformation` (edges 1 and 3 of a quad over the middle of the frame) and a `ConstrainedFPI`",
            "(edges 0 and 2 of the image corners): Newton inverses of a thin-plate spline of 31 center pairs",
            "per pixel, seeded from the block's table of exact inverses.",
            "Their ratio is to **the FPI warp on the same backend** (target: at most 2×); the FPI rows'",
            f"ratio is to `{IMAGE_BASELINE}`. The `gl preview frame` rows: one exact frame of the preview",
            "(`fpiwarp.viewer.Renderer`, method \"pixel\", offscreen, waited for; target for the local",
            "deformation at 1080p: at most 60 ms), the LocalDeformation's ratio to the FPI's frame.",
            "",
            table(results, "warp_image local", "uint8"),
        ]
    if any(r.workload == "warp_image overhead" for r in results):
        parts += [
            "",
            "## warp_image, per-call overhead (small FPI warps, uint8 RGB)",
            "",
            f"Plain `warp_image` and the prepared `fpiwarp.warping.Warper`; ratios to `{IMAGE_BASELINE}`.",
            "",
            table(results, "warp_image overhead", "uint8"),
        ]
    return parts
