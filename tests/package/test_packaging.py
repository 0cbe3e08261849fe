"""Packaging: the sdist carries the tests and runs them, the wheel carries the
package with its kernels, shaders, data and py.typed and no tests, and the
kernel and shader sources load through one loader."""

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


#: Source files by suffix: what the sdist must carry and the wheel must not lose.
PACKAGED_SUFFIXES = {".py", ".cl", ".h", ".glsl", ".vert", ".frag", ".json", ".png", ".md", ".typed", ".rst"}
#: What a docs build writes (never in the sdist).
DOCS_BUILD = ["docs/_build", "docs/_generated", "docs/auto_examples", "docs/sg_execution_times.rst"]


def _files(folder, skip=()):
    """Relative posix paths of the source files under ``folder`` (no caches)."""
    return {p.relative_to(ROOT).as_posix() for p in (ROOT / folder).rglob("*")
            if p.is_file() and p.suffix in PACKAGED_SUFFIXES and "__pycache__" not in p.parts
            and not any(p.is_relative_to(ROOT / s) for s in skip)}


@pytest.fixture(scope="module")
def sdist(tmp_path_factory):
    """The source distribution, built by setuptools' PEP 517 backend in this tree."""
    out = tmp_path_factory.mktemp("sdist")
    code = "import sys; from setuptools import build_meta; print(build_meta.build_sdist(sys.argv[1]))"
    done = subprocess.run([sys.executable, "-c", code, str(out)], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    (path,) = out.glob("fpiwarp-*.tar.gz")
    return path


@pytest.fixture(scope="module")
def unpacked_sdist(sdist, tmp_path_factory):
    import tarfile

    out = tmp_path_factory.mktemp("unpacked")
    with tarfile.open(sdist) as tar:
        tar.extractall(out, filter="data")
    (root,) = out.iterdir()
    return root


@pytest.fixture(scope="module")
def wheel(unpacked_sdist, tmp_path_factory):
    """The wheel, built from the unpacked sdist as ``python -m build`` does
    (so the sdist must carry all the wheel needs, and no stale build/ of the
    checkout can slip into it)."""
    out = tmp_path_factory.mktemp("wheel")
    done = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(out),
         str(unpacked_sdist)],
        capture_output=True, text=True,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    (path,) = out.glob("fpiwarp-*.whl")
    return path


def test_sdist_carries_the_tests_and_what_they_need(sdist, unpacked_sdist):
    names = {p.relative_to(unpacked_sdist).as_posix() for p in unpacked_sdist.rglob("*") if p.is_file()}
    expected = (_files("fpiwarp") | _files("kernels") | _files("glsl") | _files("tests") | _files("benchmarks")
                | _files("docs", skip=DOCS_BUILD))
    assert {"tests/conftest.py", "tests/support/__init__.py", "benchmarks/common.py", "docs/conf.py"} <= expected
    assert expected <= names, sorted(expected - names)[:20]
    assert {"LICENSE", "README.md", "pyproject.toml", ".ci/run", "PKG-INFO"} <= names
    assert not [n for n in names if "__pycache__" in n or n.startswith(tuple(DOCS_BUILD))]


def test_the_tests_run_from_the_unpacked_sdist(unpacked_sdist):
    """A sample of the suite that leans on conftest.py, tests/support, the
    benchmarks and the package's own files, run inside the unpacked sdist
    against the package there (not this checkout)."""
    env = {**__import__("os").environ, "PYTHONPATH": str(unpacked_sdist)}
    probe = subprocess.run([sys.executable, "-c", "import fpiwarp; print(fpiwarp.__file__)"], cwd=unpacked_sdist,
                           env=env, capture_output=True, text=True, check=True)
    assert Path(probe.stdout.strip()).resolve().is_relative_to(unpacked_sdist.resolve()), probe.stdout
    sample = ["tests/package/test_structure.py", "tests/package/test_readme_links.py",
              "tests/bench/test_benchmark_common.py", "tests/maps/test_quad_fuzz.py", "tests/test_errors.py",
              "tests/block/test_block.py"]
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *sample],
                          cwd=unpacked_sdist, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert " passed" in done.stdout and " error" not in done.stdout


def test_wheel_has_the_package_and_its_files_and_no_tests(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    package = {n for n in _files("fpiwarp") if not n.endswith(".md")}
    assert package <= names, sorted(package - names)[:20]  # every subpackage listed in pyproject.toml
    assert "fpiwarp/py.typed" in names
    assert not [n for n in names if n.startswith(("tests/", "benchmarks/", "docs/")) or "/tests/" in n]
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    top = {n.split("/")[0] for n in names}
    assert {t for t in top if not t.endswith(".dist-info")} == {"fpiwarp"}


def test_wheel_metadata_has_the_spdx_license_and_its_file(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    (metadata,) = [n for n in names if n.endswith(".dist-info/METADATA")]
    text = zipfile.ZipFile(wheel).read(metadata).decode()
    assert "License-Expression: MIT" in text
    assert "License-File: LICENSE" in text
    assert "Classifier: License" not in text and "\nLicense: " not in text
    (license_file,) = [n for n in names if n.endswith(".dist-info/licenses/LICENSE")]
    assert zipfile.ZipFile(wheel).read(license_file).decode() == (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert "The fpiwarp authors" in (ROOT / "LICENSE").read_text(encoding="utf-8")


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
