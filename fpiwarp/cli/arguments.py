"""The command line's words turned into the library's arguments.

Corner lists, edge pairs, cval and WIDTHxHEIGHT sizes parsed with one-line
errors naming the option; the map a ``warp``/``preview`` command asks for
(``--src``/``--dst``/``--edges`` or ``--spec``); the checks an output path
must pass before any work; and an argparse parser whose errors are one line.
"""

import argparse
import os
import re
from pathlib import Path

import numpy as np

from ..errors import ArgumentError, FpiwarpError
from ..io.atomic import check_output
from ..maps.fpi import FPI
from ..maps.local import LocalDeformation
from ..spec import load_spec

#: Options whose value may start with "-" (negative coordinates, a mistyped size).
NUMERIC_OPTIONS = ("--src", "--dst", "--edges", "--cval", "--output-shape")


class UsageError(Exception):
    """A wrong command line; argparse's usage text is not repeated."""


class Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, not usage + message
        raise UsageError(f"{self.prog}: {message} (see {self.prog} --help)")


def parse_numbers(text, count, what):
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise UsageError(f"{what} must be {count} numbers separated by commas, got {text!r}") from None
    if len(values) != count:
        raise UsageError(f"{what} must be {count} numbers separated by commas, got {len(values)}")
    return values


def parse_quad(text, what):
    return np.array(parse_numbers(text, 8, what)).reshape(4, 2)


def parse_edges(text):
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    if len(parts) != 2 or not all(p.isdigit() and int(p) <= 3 for p in parts) or parts[0] == parts[1]:
        raise UsageError(f"--edges must be two different edge numbers 0..3 like 0,2, got {text!r}")
    return [int(p) for p in parts]


def parse_cval(text):
    if text is None:
        return 0.0
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise UsageError(f"--cval must be a number or one number per channel, got {text!r}") from None
    if not values or not all(np.isfinite(values)):
        raise UsageError(f"--cval must be finite numbers, got {text!r}")
    return values[0] if len(values) == 1 else values


def parse_output_shape(text):
    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", text)
    if not m or int(m.group(1)) == 0 or int(m.group(2)) == 0:
        raise UsageError(f"--output-shape must be WIDTHxHEIGHT in pixels like 1920x1080, got {text!r}")
    return int(m.group(2)), int(m.group(1))  # (rows, cols), the API's order


def transform_from_args(args):
    if args.spec is not None:
        if args.src is not None or args.dst is not None or args.edges is not None:
            raise UsageError("give either --spec or --src/--dst/--edges, not both")
        return load_spec(args.spec)
    if args.src is None or args.dst is None:
        raise UsageError("give --src and --dst (eight numbers each), or --spec SPEC.json")
    src, dst = parse_quad(args.src, "--src"), parse_quad(args.dst, "--dst")
    if args.edges is None:
        return FPI(src, dst)
    edges = tuple(parse_edges(args.edges))
    try:
        return LocalDeformation(src, dst, edges=edges)
    except FpiwarpError:
        raise
    except ValueError as exc:  # the local deformation's own checks of the quads
        raise ArgumentError(f"--src/--dst/--edges: {exc}") from None


def same_file(a, b):
    try:
        return Path(a).resolve() == Path(b).resolve() or (Path(b).exists() and os.path.samefile(a, b))
    except OSError:
        return False


def check_output_path(input_path, output, overwrite):
    if input_path is not None and same_file(input_path, output):
        raise UsageError(f"the output {output} is the input file; inputs are never modified, choose another name")
    check_output(output, overwrite=overwrite)  # a folder, a special file, an existing file without --overwrite


# --------------------------------------------------------------------------
# Commands


def join_numeric_options(argv):
    """'--src -3,4,...' -> '--src=-3,4,...': argparse would take a value
    starting with '-' for an option."""
    out, i = [], 0
    while i < len(argv):
        if argv[i] in NUMERIC_OPTIONS and i + 1 < len(argv):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out
