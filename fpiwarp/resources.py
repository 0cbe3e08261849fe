"""One loader for the kernel and shader source files.

``kernels/`` and ``glsl/`` sit at the top of the source tree and are
installed as the packages ``fpiwarp.kernels`` and ``fpiwarp.glsl`` (see
pyproject.toml), so ``importlib.resources`` finds them in a wheel and in an
editable install alike.
"""

import functools
import hashlib
from importlib import resources

PACKAGES = {"kernels": "fpiwarp.kernels", "glsl": "fpiwarp.glsl"}


@functools.lru_cache(maxsize=None)
def source(kind, name):
    """The text of ``name`` in ``kernels`` or ``glsl``; cached after one read."""
    if kind not in PACKAGES:
        raise ValueError(f"kind must be one of {sorted(PACKAGES)}, got {kind!r}")
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
