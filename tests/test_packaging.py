"""Kernel and shader sources ship in the wheel and load through one loader."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from fpiwarp import resources

ROOT = Path(__file__).resolve().parents[1]


def test_loader_reads_sources_from_the_checkout():
    for kind, folder in [("kernels", "kernels"), ("glsl", "glsl")]:
        files = [p for p in (ROOT / folder).iterdir() if p.suffix in {".cl", ".h", ".glsl", ".vert", ".frag"}]
        for path in files:
            assert resources.source(kind, path.name) == path.read_text(encoding="utf-8")
    with pytest.raises(ValueError, match="kind"):
        resources.source("shaders", "x.glsl")
    with pytest.raises(FileNotFoundError):
        resources.source("glsl", "does-not-exist.glsl")


def test_digest_is_stable_and_sensitive():
    assert resources.digest("a", "b") == resources.digest("a", "b")
    assert resources.digest("a", "b") != resources.digest("ab")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(out), str(ROOT)],
        check=True,
        capture_output=True,
    )
    (path,) = out.glob("fpiwarp-*.whl")
    return path


def test_wheel_ships_kernels_shaders_and_data(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for folder, package in [("kernels", "fpiwarp/kernels"), ("glsl", "fpiwarp/glsl")]:
        for path in (ROOT / folder).iterdir():
            if path.suffix in {".cl", ".h", ".glsl", ".vert", ".frag", ".py"}:
                assert f"{package}/{path.name}" in names
    for path in (ROOT / "fpiwarp" / "data").iterdir():
        if path.suffix in {".png", ".json"}:
            assert f"fpiwarp/data/{path.name}" in names


def test_loader_reads_sources_from_an_installed_wheel(wheel, tmp_path):
    zipfile.ZipFile(wheel).extractall(tmp_path)
    code = (
        "import fpiwarp, fpiwarp.resources as r, pathlib, sys;"
        "assert pathlib.Path(fpiwarp.__file__).is_relative_to(sys.argv[1]), fpiwarp.__file__;"
        "import importlib.resources as ir;"
        "names = [p.name for k in ('kernels', 'glsl') for p in ir.files('fpiwarp.' + k).iterdir()];"
        "print(len([n for n in names if not n.endswith(('.py', '__pycache__'))]))"
    )
    result = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)],
        cwd=tmp_path,
        env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    expected = sum(1 for f in ("kernels", "glsl") for p in (ROOT / f).iterdir() if p.suffix in {".cl", ".h", ".glsl", ".vert", ".frag"})
    assert int(result.stdout) == expected
