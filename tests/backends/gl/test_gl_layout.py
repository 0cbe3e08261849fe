"""The GL stack's layout: the packages it adds are installed, and no module
of the GL stack imports a private name from another module."""

import ast

import pytest
import tomllib
from support import ROOT

GL_MODULES = sorted((ROOT / "fpiwarp" / "backends" / "gl").glob("*.py")) + sorted(
    (ROOT / "fpiwarp" / "viewer").glob("*.py"))


def test_every_package_of_fpiwarp_is_listed_in_pyproject():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "fpiwarp").rglob("__init__.py")
             if "__pycache__" not in p.parts}
    found -= {"fpiwarp.kernels", "fpiwarp.glsl"}  # top-level kernels/ and glsl/, mapped by package-dir
    assert found <= listed, f"not in [tool.setuptools] packages: {sorted(found - listed)}"


@pytest.mark.parametrize("path", GL_MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_private_name_is_imported_across_modules(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    private = [f"{node.module}.{alias.name}" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
               for alias in node.names if alias.name.startswith("_") and alias.name != "__all__"]
    assert private == []
