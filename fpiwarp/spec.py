"""Warp specifications: a deformation written down as JSON.

Three kinds of spec, told apart by their fields (or by an optional
``"type"``):

* an FPI, ``{"src": [[x, y] ×4], "dst": [[x, y] ×4]}``: the 4-point
  interpolant sending each ``src`` corner to the ``dst`` corner of the same
  index (:class:`fpiwarp.FPI`);
* a local deformation, ``{"src": ..., "dst": ..., "edges": [i, j]}``: the
  operator of the paper's §4.1 with edges i and j constrained, edge k
  joining corner k to corner k+1 (:class:`fpiwarp.LocalDeformation`);
* a compound, ``{"steps": [spec, spec, ...]}``: the steps applied in order,
  the first to the source image (:class:`fpiwarp.Compound`).

Every object may also carry ``"description"`` (text) and ``"$schema"``.
Coordinates are pixels: x = column, y = row, pixel centers at integers,
at most ±1e100 (``MAX_COORDINATE``). Compounds nest at most
``MAX_NESTING`` (32) levels of ``"steps"``, and JSON text at most
``MAX_JSON_DEPTH`` (68) brackets deep, enough for that; deeper specs are
refused with one line, before anything recurses. A UTF-8 byte-order mark
at the start of the text is ignored.
The JSON schema of this format ships as ``fpiwarp/data/spec.schema.json``
(see :func:`schema`); :func:`validate_spec` checks the same rules and says
which field is wrong, and :func:`build_transform` also checks the geometry
(degenerate quads), which a schema cannot express.

>>> t = build_transform({"src": [[0, 0], [9, 0], [9, 9], [0, 9]],
...                      "dst": [[1, 0], [9, 1], [8, 9], [0, 8]]})
>>> type(t).__name__
'FPI'
>>> validate_spec({"steps": [{"src": [[0, 0], [1, 0], [1, 1]], "dst": []}]})
Traceback (most recent call last):
...
fpiwarp.SpecError: steps[0].src: must be a list of 4 [x, y] points, got a list of 3 items
"""

import json
import numbers
import os
import re
from importlib import resources

from .errors import DegenerateQuadError, SpecError
from .maps.fpi import FPI
from .maps.quad import MAX_COORDINATE, check_quad
from .maps.transform import Compound, Transform

__all__ = ["SpecError", "build_transform", "load_spec", "parse_spec", "save_spec", "schema", "to_spec", "validate_spec"]

KINDS = ("fpi", "local", "compound")
COMMON_FIELDS = ("type", "description", "$schema")
FIELDS = {
    "fpi": ("src", "dst"),
    "local": ("src", "dst", "edges"),
    "compound": ("steps",),
}


#: Most levels of "steps" inside "steps".
MAX_NESTING = 32
#: Most brackets ([ or {) open at once in spec text: a compound level takes
#: two (the object and its "steps" list), the innermost map four (object,
#: quad, point, and one to spare).
MAX_JSON_DEPTH = 2 * MAX_NESTING + 4
_JSON_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def _where(path, name):
    if isinstance(name, int):
        return f"{path}[{name}]"
    return f"{path}.{name}" if path else name


def _fail(path, problem):
    raise SpecError(f"{path or 'spec'}: {problem}")


def _describe(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return f"a list of {len(value)} items"
    if isinstance(value, str):
        return f"the text {value!r}"
    return repr(value)


def _short(number):
    """A number in a few characters, even an integer too large for a float."""
    try:
        return format(number, ".6g")
    except OverflowError:
        return f"an integer of {len(str(abs(number)))} digits"


def _is_number(value):
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _is_integer(value):
    return _is_number(value) and (isinstance(value, int) or float(value).is_integer())


def spec_kind(spec, path=""):
    """'fpi', 'local' or 'compound': ``type`` if given, else by fields."""
    if not isinstance(spec, dict):
        _fail(path, f"must be a JSON object, got {_describe(spec)}")
    if "type" in spec:
        kind = spec["type"]
        if kind not in KINDS:
            _fail(_where(path, "type"), f"must be one of {', '.join(map(repr, KINDS))}, got {_describe(kind)}")
        return kind
    if "steps" in spec:
        return "compound"
    if "edges" in spec:
        return "local"
    return "fpi"


def validate_spec(spec, path=""):
    """Check the structure of a spec (a dict from JSON); raise SpecError
    naming the first wrong field. Agrees with the published JSON schema
    (which cannot express the nesting limit MAX_NESTING)."""
    _validate(spec, path, 0)


def _validate(spec, path, depth):
    if depth > MAX_NESTING:
        _fail(path, f"compounds nest more than {MAX_NESTING} levels of 'steps' (the limit)")
    kind = spec_kind(spec, path)
    allowed = FIELDS[kind] + COMMON_FIELDS
    for key in spec:
        if key not in allowed:
            _fail(path, f"unknown field {key!r} in a {kind} spec (allowed: {', '.join(allowed)})")
    for key in FIELDS[kind]:
        if key not in spec:
            _fail(path, f"missing required field {key!r} of a {kind} spec")
    for key in ("description", "$schema"):
        if key in spec and not isinstance(spec[key], str):
            _fail(_where(path, key), f"must be text, got {_describe(spec[key])}")
    if kind == "compound":
        steps = spec["steps"]
        if not isinstance(steps, list) or not steps:
            _fail(_where(path, "steps"), f"must be a non-empty list of specs, got {_describe(steps)}")
        for i, step in enumerate(steps):
            _validate(step, _where(_where(path, "steps"), i), depth + 1)
        return
    for key in ("src", "dst"):
        _check_quad(spec[key], _where(path, key))
    if kind == "local":
        _check_edges(spec["edges"], _where(path, "edges"))


def _check_quad(value, path):
    if not isinstance(value, list) or len(value) != 4:
        _fail(path, f"must be a list of 4 [x, y] points, got {_describe(value)}")
    for i, point in enumerate(value):
        if not isinstance(point, list) or len(point) != 2:
            _fail(_where(path, i), f"must be [x, y] (two numbers), got {_describe(point)}")
        for name, v in zip("xy", point):
            if not _is_number(v):
                _fail(_where(path, i), f"must be [x, y] (two numbers), but {name} is {_describe(v)}")
            if abs(v) > MAX_COORDINATE:
                limit = f"±{MAX_COORDINATE:g}"
                _fail(_where(path, i), f"{name} = {_short(v)} lies beyond {limit}, the largest coordinate supported")


def _check_edges(value, path):
    if (
        not isinstance(value, list)
        or len(value) != 2
        or not all(_is_integer(v) and 0 <= v <= 3 for v in value)
        or value[0] == value[1]
    ):
        _fail(
            path,
            f"must be two different edge numbers from 0 to 3 (edge k joins corner k and k+1), got {_describe(value)}",
        )


def build_transform(spec, path=""):
    """The transform a spec describes; SpecError for a bad spec, naming the
    field, including degenerate quads and inconsistent constraints."""
    validate_spec(spec, path)
    return _build(spec, path)


def _build(spec, path):
    kind = spec_kind(spec, path)
    if kind == "compound":
        steps_path = _where(path, "steps")
        return Compound([_build(step, _where(steps_path, i)) for i, step in enumerate(spec["steps"])])
    for key in ("src", "dst"):
        try:
            check_quad(spec[key], "quad")
        except DegenerateQuadError as exc:
            _fail(_where(path, key), str(exc))
    try:
        if kind == "fpi":
            return FPI(spec["src"], spec["dst"])
        edges = tuple(int(e) for e in spec["edges"])
        return _local_deformation()(spec["src"], spec["dst"], edges=edges)
    except SpecError:
        raise
    except (DegenerateQuadError, ValueError, ArithmeticError) as exc:
        _fail(path, str(exc))


def _local_deformation():
    try:
        from .maps.local import LocalDeformation
    except ImportError as exc:
        raise SpecError(f"local deformations (specs with 'edges') are not available in this fpiwarp: {exc}") from None
    return LocalDeformation


def _reject_constant(name):
    raise ValueError(f"{name} is not valid JSON (numbers must be finite)")


def _check_json_depth(text, name):
    """Refuse text whose brackets nest deeper than MAX_JSON_DEPTH, before
    the JSON parser recurses into them."""
    depth = 0
    for token in _JSON_TOKENS.finditer(text):
        t = token.group()
        if t in "[{":
            depth += 1
            if depth > MAX_JSON_DEPTH:
                raise SpecError(
                    f"{name}: brackets nest more than {MAX_JSON_DEPTH} deep (the limit; "
                    f"compounds may nest {MAX_NESTING} levels of 'steps')"
                )
        elif t in "]}":
            depth -= 1


def parse_spec(text: str, name: str = "spec") -> Transform:
    """The transform of a spec given as JSON text; ``name`` prefixes errors.
    A leading UTF-8 byte-order mark is ignored."""
    if text.startswith("\ufeff"):
        text = text[1:]
    _check_json_depth(text, name)
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise SpecError(f"{name}: not valid JSON: {exc}") from None
    except ValueError as exc:
        raise SpecError(f"{name}: {exc}") from None
    try:
        return build_transform(data)
    except SpecError as exc:
        raise SpecError(f"{name}: {exc}") from None


def load_spec(path: str | os.PathLike) -> Transform:
    """The map that the JSON spec file at ``path`` describes.

    A spec is ``{"src": quad, "dst": quad}`` (an FPI), the same with
    ``"edges": [i, j]`` (a local deformation) or ``{"steps": [spec, ...]}``
    (a compound, applied in order); quads are four ``[x, y]`` points in
    pixels, x = column, y = row. The schema is ``fpiwarp/data/spec.schema.json``
    (:func:`schema`); the command line's ``--spec`` reads the same files.

    Parameters
    ----------
    path : str or path-like
        A UTF-8 JSON file.

    Returns
    -------
    Transform
        An :class:`~fpiwarp.FPI`, :class:`~fpiwarp.LocalDeformation` or
        :class:`~fpiwarp.Compound`.

    Raises
    ------
    SpecError
        Not JSON, or not a valid spec; the message names the file and the
        place in it.
    FileNotFoundError
        A missing file.

    See Also
    --------
    save_spec, parse_spec, to_spec

    Examples
    --------
    >>> import json, tempfile, pathlib
    >>> import fpiwarp
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "warp.json"
    >>> _ = path.write_text(json.dumps({"src": [[0, 0], [9, 0], [9, 9], [0, 9]],
    ...                                 "dst": [[1, 0], [9, 1], [8, 9], [0, 8]]}))
    >>> f = fpiwarp.load_spec(path)
    >>> type(f).__name__, f([[9, 9]]).round(9).tolist()
    ('FPI', [[8.0, 9.0]])
    """
    with open(path, encoding="utf-8") as f:
        try:
            text = f.read()
        except UnicodeDecodeError:
            raise SpecError(f"{path}: not a JSON text file") from None
    return parse_spec(text, str(path))


def to_spec(transform: Transform) -> dict:
    """A spec (dict) describing ``transform``: an FPI, a local deformation
    or a compound of those. TypeError for maps a spec cannot describe."""
    if isinstance(transform, FPI):
        return {"src": transform.src.tolist(), "dst": transform.dst.tolist()}
    if isinstance(transform, Compound):
        return {"steps": [to_spec(step) for step in transform.steps]}
    if type(transform).__name__ == "LocalDeformation" and hasattr(transform, "edges"):
        return {
            "src": [[float(x), float(y)] for x, y in transform.src],
            "dst": [[float(x), float(y)] for x, y in transform.dst],
            "edges": [int(e) for e in transform.edges],
        }
    raise TypeError(f"a spec cannot describe a {type(transform).__name__}; use FPI, LocalDeformation or Compound")


def save_spec(transform: Transform, path: str | os.PathLike, *, overwrite: bool = False) -> None:
    """Write ``transform`` as a JSON spec file, atomically.

    Parameters
    ----------
    transform : FPI, LocalDeformation or Compound
        A map a spec can describe (see :func:`to_spec`).
    path : str or path-like
        The file to write.
    overwrite : bool, optional
        Replace an existing file; default False.

    Raises
    ------
    TypeError
        A map a spec cannot describe.
    OutputExistsError
        ``path`` exists and not ``overwrite``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import fpiwarp
    >>> from fpiwarp.spec import save_spec
    >>> f = fpiwarp.FPI([[0, 0], [9, 0], [9, 9], [0, 9]], [[1, 0], [9, 1], [8, 9], [0, 8]])
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "warp.json"
    >>> save_spec(f, path)
    >>> fpiwarp.load_spec(path).dst.tolist() == f.dst.tolist()
    True
    """
    from .io.images import atomic_write

    text = json.dumps(to_spec(transform), indent=2) + "\n"
    atomic_write(path, lambda f: f.write(text.encode("utf-8")), overwrite=overwrite)


def schema() -> dict:
    """The JSON schema (draft 2020-12) of specs, as a dict."""
    text = resources.files("fpiwarp.data").joinpath("spec.schema.json").read_text(encoding="utf-8")
    return json.loads(text)
