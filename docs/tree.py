"""Print the source tree, one line per file, each Python module with the first
line of its docstring: ``python3 docs/tree.py [FOLDER ...]``.

By default the top-level files and the folders a newcomer reads: fpiwarp/,
kernels/, glsl/, tests/, benchmarks/ (without benchmarks/results/), docs/ and
.ci/. Files git ignores are left out
when git is there; caches always are.
"""

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("fpiwarp", "kernels", "glsl", "tests", "benchmarks", "docs", ".ci")
SKIP = ("benchmarks/results/",)


def tracked(root):
    """The files git tracks or would track under ``root`` (None without git)."""
    try:
        out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"], cwd=root,
                             capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    return {root / line for line in out.splitlines()}


def summary(path):
    """The first line of a module's docstring, or of a shader's leading comment."""
    text = path.read_text(encoding="utf-8", errors="replace")
    if path.suffix == ".py":
        try:
            doc = ast.get_docstring(ast.parse(text))
        except SyntaxError:
            doc = None
        return doc.strip().splitlines()[0] if doc else ""
    for line in text.splitlines():
        line = line.strip()
        if line.startswith(("//", "/*", "#")) and not line.startswith(("#version", "#include", "#define", "#if")):
            return line.lstrip("/*# ").rstrip("*/ ").strip()
        if line:
            break
    return ""


def main(argv=None):
    folders = argv or sys.argv[1:] or FOLDERS
    known = tracked(ROOT)
    if folders == FOLDERS:  # the top-level files first
        for path in sorted(p for p in ROOT.iterdir() if p.is_file() and (known is None or p in known)):
            print(path.name)
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*")):
            rel = path.relative_to(ROOT).as_posix()
            if (not path.is_file() or "__pycache__" in path.parts or rel.startswith(SKIP)
                    or (known is not None and path not in known)):
                continue
            text = summary(path) if path.suffix in {".py", ".cl", ".h", ".glsl", ".vert", ".frag"} else ""
            print(f"{rel:48s} {text}".rstrip())


if __name__ == "__main__":
    main()
