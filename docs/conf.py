"""Sphinx configuration of the fpiwarp documentation.

Build with ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
No intersphinx: the build runs with no network, so cross-references point
only inside this site.
"""

import importlib.util
import os
import sys
from pathlib import Path

# The gallery runs every example in this process: load Triton (PyPI's torch
# brings it; torchvision and fpiwarp.augment.torchvision import it) before any
# example loads Mesa's LLVM through the gl backend, or torch's lazy import of
# Triton crashes the process (see docs/guides/autodiff.rst).
if importlib.util.find_spec("triton") is not None:
    import triton  # noqa: F401

import fpiwarp  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # benchmarks/ for the gallery's comparison methods
sys.path.insert(0, str(ROOT / "docs"))  # gallery_order

# Gallery examples render offscreen and pick their backends here.
os.environ.setdefault("MPLBACKEND", "Agg")

project = "fpiwarp"
author = "the fpiwarp authors"
copyright = "the fpiwarp authors"
version = release = fpiwarp.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "myst_parser",  # includes the benchmark results (Markdown) as they are written
]
# The guides include Markdown notes whose headings start below H1 (they sit
# inside an rst section): that is intended.
suppress_warnings = ["myst.header"]
source_suffix = {".rst": "restructuredtext"}  # Markdown only through include
autosummary_generate = False

exclude_patterns = ["_build", "_generated", "examples/README.rst", "examples/*.py"]
templates_path = []
default_role = "code"

# numpydoc: render the sections; members are listed by the API pages themselves.
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
autodoc_member_order = "bysource"
# Every cross-reference must resolve (a broken one fails the -W build), but
# for these: internal modules and classes that docstrings name for readers
# of the source, which the site does not document.
nitpicky = True
nitpick_ignore = [
    ("py:mod", "fpiwarp.maps.quad"),
    ("py:mod", "fpiwarp.block"),
    ("py:mod", "fpiwarp.block.codegen"),
    ("py:func", "read_image"),  # ImageInfo's docstring, in its private module
    ("py:func", "fpiwarp.block.reference.evaluate"),
    ("py:func", "describe"),
    ("py:class", "Stage"),
    ("py:class", "BlockKind"),
    ("py:class", "InverseThinPlateSpline"),
    ("py:class", "fpiwarp.backends.protocol.Backend"),
    ("py:attr", "mesh_step"),
]
autodoc_typehints = "none"

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "gallery_order.ExampleOrder",
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "show_memory": False,
    "plot_gallery": "True",
    # Code in the examples links to the API reference, and the API pages list
    # the examples that use each name (minigallery directives).
    "doc_module": ("fpiwarp",),
    "reference_url": {"fpiwarp": None},
    "backreferences_dir": "_generated/backreferences",
}

html_theme = "pydata_sphinx_theme"
html_title = f"fpiwarp {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_static_path = []
html_show_sourcelink = False


def _backend_options_table():
    """docs/_generated/backend_options.rst: every backend's declared options,
    from the registry (the single source), as an RST table."""
    from fpiwarp.backends import REGISTRY

    rows = []
    for name, entry in REGISTRY.items():
        for opt in entry.capabilities.options:
            where = []
            if opt.orders is not None:
                where.append("orders " + ", ".join(map(str, opt.orders)))
            if opt.modes is not None:
                where.append("modes " + ", ".join(opt.modes))
            doc = " ".join(opt.doc.split())
            if where:
                doc += f" (applies to {'; '.join(where)})"
            rows.append((f"``{name}``", f"``{opt.name}``", opt.kind.__name__, f"``{opt.default!r}``", doc))
    out = Path(__file__).parent / "_generated"
    out.mkdir(exist_ok=True)
    if not rows:
        text = "No backend declares options beyond those of :func:`fpiwarp.warp_image`.\n"
    else:
        lines = [".. list-table::", "   :header-rows: 1", "", "   * - backend", "     - option", "     - type",
                 "     - default", "     - what it does"]
        for row in rows:
            lines.append(f"   * - {row[0]}")
            lines.extend(f"     - {cell}" for cell in row[1:])
        text = "\n".join(lines) + "\n"
    target = out / "backend_options.rst"
    if not target.exists() or target.read_text() != text:
        target.write_text(text)



def _cli_help():
    """docs/_generated/cli.rst: ``fpiwarp --help`` and each command's help,
    from the parser itself (fpiwarp.cli.build_parser)."""
    import argparse

    from fpiwarp.cli.commands import build_parser

    parser = build_parser()
    parser.prog = "fpiwarp"
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "88"  # argparse wraps to the terminal: fix it for a stable page
    parts = [("fpiwarp", parser)] + [(f"fpiwarp {name}", p) for name, p in sub.choices.items()]
    lines = []
    for title, p in parts:
        p.prog = title
        lines += [f"``{title}``", "^" * (len(title) + 4), "", ".. code-block:: text", ""]
        lines += ["   " + line if line else "" for line in p.format_help().rstrip().splitlines()]
        lines.append("")
    if columns is None:
        del os.environ["COLUMNS"]
    else:
        os.environ["COLUMNS"] = columns
    target = Path(__file__).parent / "_generated" / "cli.rst"
    text = "\n".join(lines) + "\n"
    if not target.exists() or target.read_text() != text:
        target.write_text(text)


_backend_options_table()
_cli_help()
