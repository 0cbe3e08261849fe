"""The browser side carries no copy of the map or the sampler: the page's
files hold no shader text, and its programs are the glsl/ files assembled
by the one loader (the browser half of this check: test_page_parity.py)."""

import re
from importlib import resources

import pytest

from fpiwarp import FPI, LocalDeformation, glsl
from fpiwarp.widget import shaders

STATIC = resources.files("fpiwarp.widget").joinpath("static")
#: Signs of GLSL or of the block's math written in the page's own files.
FORBIDDEN = [r"#version", r"void\s+main", r"\bprecision\s+highp", r"\bfpw_\w+\s*\(", r"texelFetch", r"\bvec[234]\(",
             r"uniform\s+\w+", r"\bcmul\b", r"\bcdiv\b", r"mobius", r"newton", r"\btps\b", r"cubic", r"(?-i:FPW_)"]


def _page_files():
    pages = [p for p in STATIC.iterdir() if p.name.endswith((".js", ".html", ".css"))]
    return {p.name: p.read_text(encoding="utf-8") for p in pages}


def test_page_files_hold_no_shader_or_map_code():
    files = _page_files()
    assert {"editor.js", "page.js", "page.html", "editor.css"} <= set(files)
    for name, text in files.items():
        for pattern in FORBIDDEN:
            found = re.search(pattern, text, re.IGNORECASE)
            assert not found, f"static/{name} has {found.group(0)!r}: the page must take its shaders from glsl/"


def test_widget_front_end_is_the_page_script():
    from fpiwarp.widget import WarpWidget

    assert WarpWidget._esm.startswith(_page_files()["editor.js"])
    for pattern in FORBIDDEN:
        assert not re.search(pattern, WarpWidget._esm, re.IGNORECASE), pattern


@pytest.mark.parametrize("f", [FPI([[0, 0], [9, 0], [9, 9], [0, 9]], [[1, 0], [9, 1], [8, 9], [0, 8]]),
                               LocalDeformation([[0, 0], [9, 0], [9, 9], [0, 9]], [[1, 0], [9, 1], [8, 9], [0, 8]],
                                                edges=(0, 2))])
def test_page_programs_are_the_desktop_preview_in_the_es_dialect(f):
    block = f.inverse.params()
    key = shaders.preview_key(block, order=3, mode="constant", alpha=True)
    assert (key.vertex, key.fragment) == (glsl.FULLSCREEN_VERT, glsl.PREVIEW_FRAG)
    vertex, fragment = shaders.program_sources(key)
    desktop = glsl.assemble(key.fragment, ("FPW_WITH_SAMPLER",) + key.defines())
    # the same text after the first line (the dialect's #version and precision preamble)
    assert fragment.split("#define", 1)[1] == desktop.split("#define", 1)[1]
    assert fragment.startswith("#version 300 es\nprecision highp float;")
    assert "FPW_STAGES FPW_STAGE(1, " in fragment and "#define PV_ALPHA" in fragment
    with pytest.raises(ValueError, match="dialect"):
        glsl.assemble(key.fragment, dialect="webgpu")
