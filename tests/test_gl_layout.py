"""The GL stack's layout: the packages it adds are installed, the
historical module names still offer their public names, and no module
of the GL stack imports a private name from another module."""

import ast
import importlib
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[1]
GL_MODULES = sorted((ROOT / "fpiwarp" / "backends" / "gl").glob("*.py")) + sorted(
    (ROOT / "fpiwarp" / "viewer").glob("*.py"))


def test_every_package_of_fpiwarp_is_listed_in_pyproject():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "fpiwarp").rglob("__init__.py")
             if "__pycache__" not in p.parts}
    found -= {"fpiwarp.kernels", "fpiwarp.glsl"}  # top-level kernels/ and glsl/, mapped by package-dir
    assert found <= listed, f"not in [tool.setuptools] packages: {sorted(found - listed)}"


@pytest.mark.parametrize("module, names", [
    ("fpiwarp.backends.gl_backend", ["Backend", "GLWarper", "probe", "warp_image_mesh", "set_uniform", "grid_mesh",
                                     "shared_context", "check_thread", "release_shared_context",
                                     "claim_shared_context", "shader_source", "map_kind", "bound_framebuffer"]),
    ("fpiwarp.gl", ["Renderer", "render_image", "constant_dilation", "HANDLE_COLOR"]),
    ("fpiwarp.preview", ["Editor", "run", "max_distortion"]),
])
def test_historical_names_keep_their_public_names(module, names):
    pytest.importorskip("moderngl")
    mod = importlib.import_module(module)
    assert [n for n in names if not hasattr(mod, n)] == []


@pytest.mark.parametrize("path", GL_MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_private_name_is_imported_across_modules(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    private = [f"{node.module}.{alias.name}" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
               for alias in node.names if alias.name.startswith("_") and alias.name != "__all__"]
    assert private == []


@pytest.mark.parametrize("path", GL_MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_modules_stay_small(path):
    assert len(path.read_text(encoding="utf-8").splitlines()) <= 450
