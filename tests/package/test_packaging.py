"""Kernel and shader sources ship in the wheel and load through one loader."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from support import ROOT

from fpiwarp import resources

#: Kernel and shader files (any depth below kernels/ and glsl/).
SOURCE_SUFFIXES = {".cl", ".h", ".glsl", ".vert", ".frag"}


def test_loader_reads_sources_from_the_checkout():
    for kind, folder in [("kernels", "kernels"), ("glsl", "glsl")]:
        files = [p for p in (ROOT / folder).rglob("*") if p.suffix in SOURCE_SUFFIXES]
        assert files
        for path in files:
            name = path.relative_to(ROOT / folder).as_posix()
            assert resources.source(kind, name) == path.read_text(encoding="utf-8")
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
        for path in (ROOT / folder).rglob("*"):
            if path.suffix in SOURCE_SUFFIXES | {".py"} and "__pycache__" not in path.parts:
                assert f"{package}/{path.relative_to(ROOT / folder).as_posix()}" in names
    for path in (ROOT / "fpiwarp" / "data").iterdir():
        if path.suffix in {".png", ".json"}:
            assert f"fpiwarp/data/{path.name}" in names


def test_loader_reads_sources_from_an_installed_wheel(wheel, tmp_path):
    zipfile.ZipFile(wheel).extractall(tmp_path)
    code = (
        "import fpiwarp, fpiwarp.resources as r, pathlib, sys;"
        "assert pathlib.Path(fpiwarp.__file__).is_relative_to(sys.argv[1]), fpiwarp.__file__;"
        "import importlib.resources as ir;"
        "import os;"
        "roots = [str(ir.files('fpiwarp.' + k)) for k in ('kernels', 'glsl')];"
        "names = [n for r in roots for _, _, fs in os.walk(r) for n in fs];"
        "print(len([n for n in names if n.endswith(('.cl', '.h', '.glsl', '.vert', '.frag'))]))"
    )
    result = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)],
        cwd=tmp_path,
        env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    expected = sum(
        1
        for f in ("kernels", "glsl")
        for p in (ROOT / f).rglob("*")
        if p.suffix in SOURCE_SUFFIXES
    )
    assert int(result.stdout) == expected


def readme_command(marker):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text.split(f"<!-- {marker} -->")[1].split(f"<!-- /{marker} -->")[0]
    (line,) = [ln for ln in block.splitlines() if ln.strip() and not ln.startswith("```")]
    return line


def test_readme_main_command_runs_the_demo(tmp_path):
    """The main command installs, then runs the demo: run its second half."""
    install, run = readme_command("main-command").split(" && ")
    assert install.startswith("python3 -m pip install")
    args = run.split()
    assert args[:4] == ["python3", "-m", "fpiwarp", "demo"]
    result = subprocess.run([sys.executable, *args[1:]], cwd=tmp_path, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "K = " in result.stdout
    assert (tmp_path / args[4]).stat().st_size > 10_000


def test_ci_runs_the_readme_test_command():
    """.ci/run extracts its test command from the README with sed: run that
    extraction and compare."""
    import re

    command = readme_command("test-command")
    assert "pytest" in command
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    (extraction,) = re.findall(r"test_command=\$\((sed .*README\.md)\)", ci)
    result = subprocess.run(["bash", "-c", extraction], cwd=ROOT, capture_output=True, text=True, check=True)
    assert result.stdout.strip() == command
    assert 'bash -euo pipefail -c "$test_command"' in ci


def test_a_second_tree_runs_its_own_kernels(tmp_path):
    """A copy of the checkout on PYTHONPATH loads the copy's kernels and
    shaders, not those of the checkout an editable install points to."""
    import shutil

    copy = tmp_path / "tree"
    for folder in ("fpiwarp", "kernels", "glsl"):
        shutil.copytree(ROOT / folder, copy / folder, ignore=shutil.ignore_patterns("__pycache__"))
    marker = "// a change only the copy has\n"
    cl = copy / "kernels" / "opencl" / "fpiwarp.cl"
    cl.write_text(marker + cl.read_text(encoding="utf-8"), encoding="utf-8")
    probe = (
        "import fpiwarp, fpiwarp.kernels, fpiwarp.glsl\n"
        "from fpiwarp import resources\n"
        "print(fpiwarp.__file__); print(fpiwarp.kernels.__file__); print(fpiwarp.glsl.__file__)\n"
        "print(resources.source('kernels', 'opencl/fpiwarp.cl').splitlines()[0])\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe],
        capture_output=True,
        text=True,
        check=True,
        env={**__import__("os").environ, "PYTHONPATH": str(copy)},
        cwd=tmp_path,
    ).stdout.splitlines()
    for line in out[:3]:
        assert Path(line).resolve().is_relative_to(copy.resolve()), out
    assert out[3] + "\n" == marker
