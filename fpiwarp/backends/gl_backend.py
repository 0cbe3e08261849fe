"""The "gl" backend under its historical name: everything lives in the
package :mod:`fpiwarp.backends.gl` (one module per job); this module
re-exports its public names so that ``fpiwarp.backends.gl_backend`` keeps
working. See that package for the backend and its thread rules."""

import moderngl  # noqa: F401 - missing: the registry reports "cannot import moderngl"

from .gl import *  # noqa: F403 - the public names of the package
from .gl import __all__  # noqa: F401
