"""The README is a landing page: every file it links to exists (in the
checkout and in the unpacked sdist), and it links the guides that took over
its old sections."""

import re

from support import ROOT


def _links():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return [t for t in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text) if "://" not in t]


def test_readme_links_point_at_files_of_the_tree():
    links = _links()
    assert links
    missing = [t for t in links if not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"


def test_readme_links_every_guide_this_branch_wrote():
    linked = {t for t in _links() if t.startswith("docs/")}
    for name in ("installation", "command_line", "local_deformations", "antialiasing", "device_arrays",
                 "limits_and_errors", "threads_and_gl", "performance"):
        assert f"docs/guides/{name}.rst" in linked, name
    assert "docs/changelog.rst" in linked
