"""One loader for the kernel and shader source files.

``kernels/`` and ``glsl/`` sit at the top of the source tree and are
installed as the packages ``fpiwarp.kernels`` and ``fpiwarp.glsl`` (see
pyproject.toml). They must come from the same tree as the ``fpiwarp``
that is running: in a wheel they lie inside the package; in a checkout
they lie beside it. An editable install maps both names to the checkout
that was *installed*, so a second checkout (a git worktree, a copy on
``PYTHONPATH``) would run its own Python against another tree's kernels.
:func:`bind_source_packages` (run when ``fpiwarp`` is imported) binds the
two names to the running tree first, and :func:`source` reads through
them, so Python, kernels and shaders always come from one tree.
"""

import functools
import hashlib
import importlib.util
import sys
from importlib import resources
from pathlib import Path

PACKAGES = {"kernels": "fpiwarp.kernels", "glsl": "fpiwarp.glsl"}
_PACKAGE_DIR = Path(__file__).resolve().parent


def source_dir(kind):
    """The folder that holds the ``kind`` sources of the running fpiwarp."""
    if kind not in PACKAGES:
        raise ValueError(f"kind must be one of {sorted(PACKAGES)}, got {kind!r}")
    for folder in (_PACKAGE_DIR / kind, _PACKAGE_DIR.parent / kind):  # wheel, then checkout
        if (folder / "__init__.py").is_file():
            return folder
    return None


def bind_source_packages():
    """Import ``fpiwarp.kernels`` / ``fpiwarp.glsl`` from the running tree.

    A no-op where they are already imported or lie inside the package (a
    wheel, where ordinary import finds them).
    """
    for kind, name in PACKAGES.items():
        folder = source_dir(kind)
        if name in sys.modules or folder is None or folder.parent == _PACKAGE_DIR:
            continue
        spec = importlib.util.spec_from_file_location(
            name, folder / "__init__.py", submodule_search_locations=[str(folder)]
        )
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        setattr(sys.modules["fpiwarp"], kind, module)


@functools.cache
def source(kind, name):
    """The text of ``name`` in ``kernels`` or ``glsl``; cached after one read."""
    if kind not in PACKAGES:
        raise ValueError(f"kind must be one of {sorted(PACKAGES)}, got {kind!r}")
    bind_source_packages()
    try:
        return resources.files(PACKAGES[kind]).joinpath(name).read_text(encoding="utf-8")
    except ModuleNotFoundError:
        raise FileNotFoundError(
            f"{PACKAGES[kind]} is not installed: install fpiwarp (pip install -e .) "
            "rather than running from a bare source tree"
        ) from None


def digest(*texts):
    """A short stable hash of sources and options, for compile caches."""
    h = hashlib.sha256()
    for t in texts:
        h.update(t.encode() if isinstance(t, str) else bytes(t))
        h.update(b"\0")
    return h.hexdigest()[:16]
