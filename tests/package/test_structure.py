"""The shape of the package and of the benchmarks beside it: no import
cycles, no private names used across modules, kernel constants from one
place. Modules are grouped by topic, not capped by length.

These read the source as text (``ast``), so they hold for every module,
also those whose backend cannot run here.
"""

import ast

from support import ROOT

#: Where each top-level source folder is installed (see pyproject.toml), and
#: the benchmarks (a package run from the checkout: ``python3 -m benchmarks``).
TREES = {"fpiwarp": ROOT / "fpiwarp", "fpiwarp.kernels": ROOT / "kernels", "fpiwarp.glsl": ROOT / "glsl",
         "benchmarks": ROOT / "benchmarks"}


def _modules():
    """{dotted name: path} of every Python module of the package and the benchmarks."""
    found = {}
    for package, folder in TREES.items():
        for path in folder.rglob("*.py"):
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join([package, *parts])] = path
    return found


MODULES = _modules()


def _is_package(name):
    return MODULES[name].name == "__init__.py"


def _resolve(module, level, target):
    """The absolute name of a (possibly relative) import in ``module``."""
    if level == 0:
        return target
    base = module.split(".")
    base = base if _is_package(module) else base[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def _imports(name):
    """[(imported module, [names taken from it])] of every import statement."""
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            source = _resolve(name, node.level, node.module)
            out.append((source, [alias.name for alias in node.names]))
    return out


def _edges(name):
    """The package's own modules that ``name`` imports (at any level)."""
    edges = set()
    for source, names in _imports(name):
        for taken in names:
            if f"{source}.{taken}" in MODULES:  # "from pkg import submodule"
                edges.add(f"{source}.{taken}")
            elif source in MODULES:
                edges.add(source)
        if not names and source in MODULES:
            edges.add(source)
    edges.discard(name)
    return edges


def test_no_import_cycles():
    graph = {name: _edges(name) for name in MODULES}
    cycles, state = [], {}

    def visit(node, path):
        state[node] = "open"
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                cycles.append(path[path.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def _private(name):
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def test_no_private_name_used_across_modules():
    """``from .x import _y`` and ``x._y`` on another module of the package
    are refused: what other modules need is public in its module."""
    found = []
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                source = _resolve(name, node.level, node.module)
                for alias in node.names:
                    if f"{source}.{alias.name}" in MODULES:
                        aliases[alias.asname or alias.name] = f"{source}.{alias.name}"
                    elif source in MODULES and _private(alias.name) and source != name:
                        found.append(f"{name}: from {source} import {alias.name}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name in MODULES and alias.asname:
                        aliases[alias.asname] = alias.name
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and _private(node.attr)
                and isinstance(node.value, ast.Name)
                and node.value.id in aliases
                and aliases[node.value.id] != name
            ):
                found.append(f"{name}: {aliases[node.value.id]}.{node.attr}")
    assert not found, "private names used across modules: " + ", ".join(sorted(set(found)))


def _public_callables():
    """(name, callable) of every function and method users call: the names
    of ``fpiwarp.__all__`` (classes: their constructor and public methods)
    and of the public modules users import from."""
    import inspect

    import fpiwarp
    from fpiwarp import curves, metrics
    from fpiwarp.sampling import positions

    found = []
    metric_names = ["conformal_distortion", "conformal_dilation", "jacobian_determinant", "area_distortion",
                    "summarize", "grid"]
    for module, names in [(fpiwarp, fpiwarp.__all__), (metrics, metric_names), (curves, ["curve_map", "fpi_curve"]),
                          (positions, ["source_positions"])]:
        for name in names:
            obj = getattr(module, name)
            if inspect.isclass(obj):
                if issubclass(obj, BaseException):
                    continue
                members = {"__init__": obj.__init__} if "__init__" in vars(obj) else {}
                members.update({k: v for k, v in vars(obj).items() if inspect.isfunction(v) and not k.startswith("_")
                                and k not in ("map_complex", "wirtinger")})
                if obj is fpiwarp.Transform:
                    members.update({"map_complex": obj.map_complex, "wirtinger": obj.wirtinger})
                found += [(f"{name}.{k}", v) for k, v in members.items()]
            elif callable(obj):
                found.append((name, obj))
    return found


def test_the_public_api_has_type_hints():
    """py.typed promises hints: every parameter and return of what users call."""
    import inspect

    missing = []
    for name, func in _public_callables():
        sig = inspect.signature(func)
        params = [p for p in sig.parameters.values() if p.name not in ("self", "cls")
                  and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
        if any(p.annotation is inspect.Parameter.empty for p in params) or (
                sig.return_annotation is inspect.Signature.empty and not name.endswith("__init__")):
            missing.append(name)
    assert not missing, "no type hints: " + ", ".join(sorted(missing))


def test_maps_are_called_through_their_public_protocol():
    """``_map``/``_wirtinger`` are a map's own hooks behind ``map_complex`` and
    ``wirtinger``: only ``self`` calls them."""
    found = []
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Attribute) and node.attr in ("_map", "_wirtinger")
                    and not (isinstance(node.value, ast.Name) and node.value.id == "self")):
                found.append(f"{name}:{node.lineno}")
    assert not found, "private map hooks called from outside the map: " + ", ".join(found)


def test_the_structure_checks_see_the_benchmarks():
    """The checks above read benchmarks/ too: its modules are in the graph,
    with the edges of their relative imports."""
    assert {"benchmarks.common", "benchmarks.speed", "benchmarks.__main__"} <= set(MODULES)
    assert "benchmarks.common" in _edges("benchmarks.speed")


def test_benchmark_modules_are_named_by_topic():
    """One naming scheme: a module per topic (speed.py, gl_backend.py, ...),
    no ``bench_`` prefix, and the shared helpers in benchmarks/common.py."""
    names = sorted(p.name for p in (ROOT / "benchmarks").glob("*.py"))
    assert not [n for n in names if n.startswith("bench")], names
    assert "common.py" in names
