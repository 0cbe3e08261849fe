"""The ``fpiwarp`` command: warp one image, a folder of images, or the demo.

``fpiwarp demo [OUTPUT]``
    warp the bundled sample picture with a 4-point warp of its corners.
``fpiwarp warp INPUT OUTPUT (--src ... --dst ... [--edges I,J] | --spec SPEC.json)``
    warp one image file.
``fpiwarp batch SPEC.json INPUT_DIR OUTPUT_DIR``
    warp every image of a folder, in parallel, resuming where a previous
    run stopped.
``fpiwarp backends``
    list the backends and why any of them cannot run here.
``fpiwarp preview IMAGE [--src ... --dst ... [--edges I,J] | --spec SPEC.json] [--screenshot OUT.png]``
    the interactive viewer (drag the target points); with ``--screenshot``
    one frame rendered offscreen (no display needed) and written.

A user's mistake (a degenerate quad, a bad spec, a missing file, an unknown
backend, an output that exists: an :class:`~fpiwarp.FpiwarpError` or an
``OSError``) gives one line on stderr and exit status 1; a wrong command
line status 2; Ctrl-C status 130. Any other exception is a bug in fpiwarp:
its traceback is shown, with a line saying so, and the status is 70.
Inputs are never modified and outputs are written atomically, so no
partial or temporary file is left behind.

``--output-shape`` is WIDTHxHEIGHT, as image sizes are usually written;
the Python API's ``output_shape`` is (rows, cols) = (HEIGHT, WIDTH).
"""

import argparse
import os
import sys
import traceback
from importlib import resources
from pathlib import Path

from .. import __version__
from ..backends import REGISTRY, backend_capabilities, backend_status
from ..batch.images import BatchSummary, Progress, list_inputs, run_batch
from ..errors import BackendUnavailableError, FpiwarpError, MissingDependencyError, OutputExistsError
from ..io.images import ORIENTATIONS, check_writable, read_image, write_image
from ..maps.fpi import FPI
from ..maps.local import on_picture
from ..metrics import grid
from ..sampling.sampler import MODES, ORDERS
from ..spec import load_spec
from ..warping import warp_image
from .arguments import (
    Parser,
    UsageError,
    check_output_path,
    join_numeric_options,
    parse_cval,
    parse_output_shape,
    transform_from_args,
)

#: The demo's target corners, as fractions of (width - 1, height - 1); the
#: source corners are the image's own, clockwise on screen from top left.
DEMO_DST = ((0.18, 0.14), (0.90, 0.02), (0.98, 0.90), (0.04, 0.96))
DEMO_OUTPUT = "warped-sample.png"

#: Exit status for an exception that is not a user's mistake (EX_SOFTWARE).
BUG_STATUS = 70
#: Samples per side of the input image over which ``warp`` reports the
#: largest distortion K of maps whose K is not one constant.
K_SAMPLES = 64

def _distortion_line(transform, image):
    """'K = ...' for ``warp``: the map's constant K, else its largest K
    over the input image (a K_SAMPLES x K_SAMPLES grid)."""
    k = getattr(transform, "K", None)
    if k is not None:
        return f"K = {float(k):.4f}"
    h, w = image.shape[:2]
    worst = float(transform.distortion(grid([[0, 0], [w - 1, h - 1]], n=K_SAMPLES)).max())
    return f"K = {worst:.4f} (largest over the input image)"


def cmd_demo(args):
    """Warp the bundled sample picture and say where it went and its K."""
    check_output_path(None, args.output, args.overwrite)
    with resources.as_file(resources.files("fpiwarp.data").joinpath("sample.png")) as sample:
        image, info = read_image(sample, with_info=True)
    h, w = image.shape[:2]
    src = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    dst = [[fx * (w - 1), fy * (h - 1)] for fx, fy in DEMO_DST]
    fpi = FPI(src, dst)
    warped = warp_image(image, fpi, order=3, backend=args.backend)
    write_image(args.output, warped, info, overwrite=args.overwrite)
    print(f"wrote {args.output}")
    print(f"K = {fpi.K:.4f}")
    return 0


def cmd_warp(args):
    """Warp one image file."""
    transform = transform_from_args(args)
    output_shape = parse_output_shape(args.output_shape)
    cval = parse_cval(args.cval)
    if not Path(args.input).exists():
        raise FileNotFoundError(f"no such file: {args.input}")
    check_output_path(args.input, args.output, args.overwrite)
    image, info = read_image(args.input, orientation=args.orientation, with_info=True, damaged=_damaged(args))
    check_writable(args.output, image.dtype, 1 if image.ndim == 2 else image.shape[2], info)
    out_h, out_w = output_shape or image.shape[:2]  # a local deformation: continuous over this picture and the output
    transform = on_picture(transform, max(image.shape[1], out_w), max(image.shape[0], out_h))
    warped = warp_image(
        image, transform, output_shape, order=args.order, mode=args.mode, cval=cval, backend=args.backend,
        antialias=_antialias(args),
    )
    write_image(args.output, warped, info, overwrite=args.overwrite)
    print(f"wrote {args.output}")
    print(_distortion_line(transform, image))
    return 0


def cmd_batch(args):
    """Warp a folder; summary at the end, status 1 if any file failed."""
    transform = load_spec(args.spec)
    output_shape = parse_output_shape(args.output_shape)
    cval = parse_cval(args.cval)
    if args.jobs < 1:
        raise UsageError(f"--jobs must be at least 1, got {args.jobs}")
    total = len(list_inputs(args.input_dir, args.pattern, exclude=args.output_dir, extensions=args.ext))
    progress = Progress(total, enabled=False if args.no_progress else None)
    summary = BatchSummary()
    try:
        run_batch(
            transform,
            args.input_dir,
            args.output_dir,
            pattern=args.pattern,
            jobs=args.jobs,
            overwrite=args.overwrite,
            backend=args.backend,
            order=args.order,
            mode=args.mode,
            cval=cval,
            antialias=_antialias(args),
            output_shape=output_shape,
            progress=progress,
            scheduler=args.scheduler,
            summary=summary,
            orientation=args.orientation,
            extensions=args.ext,
            damaged=_damaged(args),
        )
    except KeyboardInterrupt:
        progress.close()
        _print_summary(summary)
        return 130
    progress.close()
    _print_summary(summary)
    if summary.total == 0:
        what = args.pattern or (f"*.{{{args.ext}}}" if args.ext else "the image extensions")
        print(f"fpiwarp: warning: no files in {args.input_dir} match {what}", file=sys.stderr)
    return 0 if summary.ok else 1


def _print_summary(summary):
    lines = summary.report()
    print(lines[0])
    for line in lines[1:]:
        print(line, file=sys.stderr)


def cmd_backends(args):
    """One line per backend: available, or why not and what to install; then the default."""
    from ..backends.default import default_backend  # noqa: PLC0415 - measures on its first use

    for name, reason in backend_status().items():
        if reason is None:
            print(f"{name:8} available")
            continue
        entry = REGISTRY[name]
        hint = f" (pip install 'fpiwarp[{entry.extra}]'" if entry.extra else ""
        if entry.system:
            hint += f"{'; ' if hint else ' ('}needs {entry.system}"
        print(f"{name:8} unavailable: {reason}{hint + ')' if hint else ''}")
    print(f"default: {default_backend()} (the fastest that works here, for numpy images; --backend numpy for "
          "the float64 reference)")
    return 0


def _preview_transform(args, image):
    """The map to show; the source corners default to the image's, and
    with no map at all the viewer starts from the identity."""
    if args.spec is None and args.src is None:
        h, w = image.shape[:2]
        corners = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
        if args.dst is None and args.edges is None:
            return FPI(corners, corners)
        args.src = ",".join(str(v) for p in corners for v in p)
    return transform_from_args(args)


#: The packages of each preview extra (top-level import names): a missing
#: one is a missing extra, named with its pip command; any other ImportError
#: stays a bug.
PREVIEW_EXTRAS = {
    "preview": ("moderngl", "moderngl_window", "glcontext", "pyglet"),
    "widget": ("anywidget", "moderngl", "glcontext"),
}


def _import_for_preview(module, extra, what):
    """``fpiwarp.<module>`` imported, or a MissingDependencyError naming the
    missing package and ``pip install 'fpiwarp[<extra>]'``."""
    import importlib

    try:
        return importlib.import_module(f"fpiwarp.{module}")
    except ImportError as exc:
        missing = (exc.name or "").split(".")[0]
        if missing not in PREVIEW_EXTRAS[extra]:
            raise
        raise MissingDependencyError(
            f"{what} needs {missing.replace('_', '-')}, which is not installed: pip install 'fpiwarp[{extra}]'"
        ) from None


def cmd_preview(args):
    """Show the warp in a window, or render one frame with --screenshot."""
    if not Path(args.input).exists():
        raise FileNotFoundError(f"no such file: {args.input}")
    if args.screenshot is not None:
        check_output_path(args.input, args.screenshot, args.overwrite)
    image, info = read_image(args.input, orientation=args.orientation, with_info=True, damaged=_damaged(args))
    transform = _preview_transform(args, image)
    overlays = () if args.no_overlay else ("handles", "outline")
    if args.web:
        _import_for_preview("widget.session", "widget", "fpiwarp preview --web")
        return _preview_web(args, image, info, transform, overlays)
    viewer = _import_for_preview("viewer", "preview", "fpiwarp preview")
    if args.screenshot is not None:
        try:
            frame = viewer.render_image(image, transform, overlays=overlays, order=args.order)
        except RuntimeError as exc:  # no GL driver: create_context's reason
            raise BackendUnavailableError(f"cannot render offscreen: {exc}") from None
        keep = info if frame.shape[2:] == image.shape[2:] else None
        check_writable(args.screenshot, frame.dtype, 1 if frame.ndim == 2 else frame.shape[2], keep)
        write_image(args.screenshot, frame, keep, overwrite=args.overwrite)
        print(f"wrote {args.screenshot}")
        return 0
    name = Path(args.input).stem
    editor = viewer.run(image, transform, info=info, name=name, export_path=f"{name}-warped{Path(args.input).suffix}",
                 overlays=overlays, order=args.order)
    for path in editor.saved:
        print(f"wrote {path}")
    return 0


def _preview_web(args, image, info, transform, overlays):
    """--web: the editor page from a local server, in the system browser;
    with --screenshot one frame from headless Chromium."""
    from ..widget.session import Session

    name = Path(args.input).stem
    session = Session(image, transform, order=args.order, overlays=overlays, info=info, name=name,
                      export_path=f"{name}-warped{Path(args.input).suffix}",
                      background=None if args.screenshot else (0.18, 0.18, 0.2, 1.0))
    if args.screenshot is not None:
        from ..widget.browser import screenshot

        frame = screenshot(session, overlays=bool(overlays))
        keep = info if frame.shape[2:] == image.shape[2:] else None
        check_writable(args.screenshot, frame.dtype, frame.shape[2], keep)
        write_image(args.screenshot, frame, keep, overwrite=args.overwrite)
        print(f"wrote {args.screenshot}")
        return 0
    import webbrowser

    from ..widget.server import PageServer

    server = PageServer(session, port=args.port)
    print(f"fpiwarp preview: {server.url}  (Ctrl-C stops)", flush=True)
    if not args.no_browser:
        webbrowser.open(server.url)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
    for path in session.editor.saved:
        print(f"wrote {path}")
    return 0


# --------------------------------------------------------------------------
# Parser and entry point


def antialiasing_backends():
    """The registered backends that antialias (their capabilities say so)."""
    return [name for name in REGISTRY if backend_capabilities(name).antialias]


def _antialias(args):
    """``--antialias`` / ``--no-antialias``, else the command line's default:
    on at orders 1 and 3 (a photo tool filters where the map shrinks; where
    it does not, the result is the plain warp's bit for bit), off at order
    0 (nearest: label maps and masks are never averaged) and on a named
    backend that does not antialias."""
    if args.antialias is not None:
        return args.antialias
    return args.order != 0 and (args.backend is None or backend_capabilities(args.backend).antialias)


def _add_warp_options(p):
    p.add_argument("--backend", default=None, help="backend name (see 'fpiwarp backends'); default: the fastest that "
                   "works here ('fpiwarp backends' names it); numpy for the float64 reference")
    p.add_argument("--order", type=int, choices=ORDERS, default=1, help="0 nearest, 1 bilinear (default), 3 cubic")
    p.add_argument("--mode", choices=MODES, default="constant", help="border mode (default constant)")
    p.add_argument("--antialias", action=argparse.BooleanOptionalAction, default=None,
                   help="filter each output pixel over its footprint in the source: no moire where the warp "
                   "shrinks, unchanged where it does not. Default: on at --order 1 and 3, off at --order 0 "
                   "(label maps are never averaged). Backends that antialias: "
                   + ", ".join(antialiasing_backends()))
    p.add_argument("--cval", help="value outside the image in constant mode: V or V1,V2,... per channel")
    p.add_argument(
        "--output-shape",
        metavar="WxH",
        help="output WIDTHxHEIGHT in pixels, e.g. 1920x1080 (default the input's size); note the "
        "Python API's output_shape is (rows, cols), i.e. (HEIGHT, WIDTH)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace outputs that exist")
    _add_orientation_option(p)


def _damaged(args):
    return "accept" if args.accept_damaged else "refuse"


def _add_orientation_option(p):
    p.add_argument(
        "--orientation",
        choices=ORIENTATIONS,
        default="apply",
        help="EXIF orientation: 'apply' (default) warps photos as viewers show them and writes them upright; "
        "'stored' keeps the stored pixels and their tag",
    )
    p.add_argument(
        "--accept-damaged",
        action="store_true",
        help="decode damaged image files as far as they go (truncated data, a JPEG smaller than its header's "
        "size needs), the rest filled by the decoder; by default they are refused",
    )


def build_parser():
    parser = Parser(
        prog="fpiwarp",
        description="Quasiconformal 4-point image warps (Lipman, Kim, Funkhouser 2012). "
        "Coordinates are pixels: x = column, y = row, pixel centers at integers.",
    )
    parser.add_argument("--version", action="version", version=f"fpiwarp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)

    p = sub.add_parser("demo", help="warp the bundled sample picture", description=cmd_demo.__doc__)
    p.add_argument("output", nargs="?", default=DEMO_OUTPUT, help=f"output file (default {DEMO_OUTPUT})")
    p.add_argument("--backend", default=None, help="backend name (see 'fpiwarp backends'); default: the fastest that "
                   "works here ('fpiwarp backends' names it); numpy for the float64 reference")
    p.add_argument("--overwrite", action="store_true", help="replace the output if it exists")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser(
        "warp",
        help="warp one image",
        description="Warp one image by a 4-point map sending --src corners to --dst corners "
        "(or by a JSON spec). The output's format follows its extension.",
    )
    p.add_argument("input", help="image file to read (never modified)")
    p.add_argument("output", help="image file to write")
    p.add_argument("--src", metavar="X1,Y1,...,X4,Y4", help="four source corners")
    p.add_argument("--dst", metavar="X1,Y1,...,X4,Y4", help="where the four corners go")
    p.add_argument("--edges", metavar="I,J", help="constrain edges I and J (edge k joins corner k and k+1)")
    p.add_argument("--spec", metavar="SPEC.json", help="a JSON spec instead of --src/--dst")
    _add_warp_options(p)
    p.set_defaults(func=cmd_warp)

    p = sub.add_parser(
        "batch",
        help="warp every image of a folder",
        description="Warp every image of INPUT_DIR into OUTPUT_DIR with one map, keeping names, "
        "formats and metadata. Existing outputs are skipped (a rerun resumes) unless --overwrite; "
        "files that fail are listed at the end and make the exit status 1. Files that are not images by their "
        "extension (notes.txt) are listed as ignored; images of another size than the first are warped with "
        "the same pixel coordinates and listed.",
    )
    p.add_argument("spec", metavar="SPEC.json", help="the JSON spec of the warp")
    p.add_argument("input_dir", metavar="INPUT_DIR")
    p.add_argument("output_dir", metavar="OUTPUT_DIR", help="created if missing; must differ from INPUT_DIR")
    p.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1), help="parallel workers")
    p.add_argument("--pattern", metavar="GLOB",
                   help="files to take, e.g. '*.jpg' or '**/*.png' (default: every image file at the top level; "
                   "other files such as notes.txt are listed as ignored)")
    p.add_argument("--ext", metavar="EXT,...", help="only files with these extensions, e.g. jpg,png")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster (tcp://host:8786)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_warp_options(p)
    p.set_defaults(func=cmd_batch)

    p = sub.add_parser(
        "preview",
        help="interactive viewer: drag the target points",
        description="Show IMAGE warped by a 4-point map and drag the target points live (needs a display "
        "and OpenGL 3.3; pip install moderngl-window). Keys: H handles, O outline, C checkerboard, "
        "D distortion heat map, N overlays off/on, M mesh/per-pixel drawing, click an edge to constrain it "
        "(X clears), F fit, R reset, S save the spec, E export the warped image, Q quit. With --screenshot, render one "
        "frame offscreen at the image's size (no display needed), write it and exit. With --web, the same editor in "
        "the browser (WebGL2) from a local server; --web --screenshot renders its frame in headless Chromium.",
    )
    p.add_argument("input", help="image file to show (never modified)")
    p.add_argument("--src", metavar="X1,Y1,...,X4,Y4", help="four source corners (default the image's)")
    p.add_argument("--dst", metavar="X1,Y1,...,X4,Y4", help="where the four corners go")
    p.add_argument("--edges", metavar="I,J", help="constrain edges I and J (edge k joins corner k and k+1)")
    p.add_argument("--spec", metavar="SPEC.json", help="a JSON spec instead of --src/--dst")
    p.add_argument("--screenshot", metavar="OUT.png", help="render one frame offscreen, write it and exit")
    p.add_argument("--no-overlay", action="store_true",
                   help="no handles or outline: the screenshot is exactly the warped image")
    p.add_argument("--order", type=int, choices=ORDERS, default=1, help="0 nearest, 1 bilinear (default), 3 cubic")
    p.add_argument("--web", action="store_true",
                   help="the editor in the browser (WebGL2): served on 127.0.0.1 with a token in the URL and "
                   "opened in the system browser; with --screenshot rendered in headless Chromium")
    p.add_argument("--port", type=int, default=0, help="--web: the port (default a free one)")
    p.add_argument("--no-browser", action="store_true", help="--web: print the URL, open no browser")
    p.add_argument("--overwrite", action="store_true", help="replace the screenshot if it exists")
    _add_orientation_option(p)
    p.set_defaults(func=cmd_preview)

    p = sub.add_parser("backends", help="list backends and why any cannot run")
    p.set_defaults(func=cmd_backends)
    return parser


def _message(exc):
    if isinstance(exc, OutputExistsError):
        return f"{exc.filename} already exists; pass --overwrite to replace it"
    if isinstance(exc, OSError) and exc.strerror and exc.filename:
        return f"{exc.strerror}: {exc.filename}"
    return str(exc) or type(exc).__name__


#: Exceptions that mean the user asked for something impossible: one line.
USER_ERRORS = (FpiwarpError, OSError)


def main(argv=None):
    """Run the command line; return the exit status."""
    argv = join_numeric_options(list(sys.argv[1:] if argv is None else argv))
    try:
        args = build_parser().parse_args(argv)
        if args.command is None:
            build_parser().print_help()
            return 2
        return args.func(args)
    except KeyboardInterrupt:
        print("fpiwarp: interrupted", file=sys.stderr)
        return 130
    except UsageError as exc:
        text = str(exc)
        print(text if text.startswith("fpiwarp") else f"fpiwarp: {text}", file=sys.stderr)
        return 2
    except USER_ERRORS as exc:
        print(f"fpiwarp: error: {' '.join(_message(exc).split())}", file=sys.stderr)
        return 1
    except Exception as exc:  # not the user's mistake: show where it happened
        traceback.print_exc()
        print(f"fpiwarp: internal error ({type(exc).__name__}): this is a bug in fpiwarp, "
              "please report it with the traceback above", file=sys.stderr)
        return BUG_STATUS
