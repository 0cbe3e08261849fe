"""The gl backend's OpenGL context, and the one thread that may use it.

An OpenGL context is current in one thread at a time, and drawing from a
thread where it is not current gives wrong pictures or crashes, never a
clear error. So the backend's shared (headless) context belongs to the
thread that first used the backend (the one that created the context,
often through :func:`probe`); calls from any other thread are refused
with a ThreadOwnershipError (an FpiwarpError and a RuntimeError) by
:func:`check_thread`; no context at all is a BackendUnavailableError.

To move the backend to another thread, :func:`release_shared_context`
in the owning thread frees the context (and everything drawn with it);
the next thread that uses the backend creates a new one and owns it.
:func:`claim_shared_context` makes the calling thread the owner up front
(a worker thread that will do all GL work, say), or says which thread
must release it first.
"""

import threading

import moderngl

from ...errors import BackendUnavailableError, ThreadOwnershipError

#: GLSL version of the shader files; the context must provide at least this.
GL_REQUIRE = 330

# The process-wide context: "ctx" (None after a failed creation, with
# "error"), "thread" (the owner's ident). Empty: none made yet, or released.
_shared = {}
_lock = threading.Lock()


def create_context():
    """A new standalone (offscreen) moderngl context: EGL first (headless,
    Mesa's llvmpipe without a GPU), then the platform's default."""
    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            return moderngl.create_standalone_context(require=GL_REQUIRE, **kwargs)
        except Exception as exc:  # noqa: BLE001 - each platform fails in its own way
            errors.append(f"{kwargs.get('backend', 'default')}: {exc}".strip())
    version = f"{GL_REQUIRE // 100}.{GL_REQUIRE % 100 // 10}"
    raise BackendUnavailableError(f"no OpenGL {version} context: " + "; ".join(errors))


def shared_context():
    """The process-wide context of the backend, created once (an error too)
    and owned by the thread that created it."""
    with _lock:
        if "ctx" not in _shared:
            _shared["thread"] = threading.get_ident()
            try:
                _shared["ctx"] = create_context()
            except RuntimeError as exc:
                _shared["ctx"] = None
                _shared["error"] = str(exc)
        if _shared["ctx"] is None:
            raise BackendUnavailableError(_shared["error"])
        return _shared["ctx"]


def owner_thread():
    """The ident (``threading.get_ident()``) of the thread that owns the
    shared context, or None while there is none."""
    return _shared.get("thread") if _shared.get("ctx") is not None else None


def check_thread():
    """Raise unless called from the thread that owns the shared context:
    a GL context is current in one thread only, and drawing from another
    would silently give wrong pictures."""
    owner = _shared.get("thread")
    if owner is not None and owner != threading.get_ident():
        raise ThreadOwnershipError(
            "the gl backend's OpenGL context belongs to the thread that first used it; "
            "call the gl backend from that thread (e.g. the main thread), or call "
            "fpiwarp.backends.gl.release_shared_context() there to hand it over"
        )


def usable_here():
    """None where the calling thread may use the backend without taking the
    context from another thread (it owns the context, or none exists and
    this is the main thread), else why not. The fast default
    (:mod:`fpiwarp.backends.default`) asks this, so that it never makes a
    worker thread the owner behind the caller's back."""
    owner = _shared.get("thread") if _shared.get("ctx") is not None else None
    here = threading.get_ident()
    if owner == here or owner is None and threading.current_thread() is threading.main_thread():
        return None
    return "its OpenGL context belongs to another thread" if owner is not None else \
        "the fast default creates its OpenGL context in the main thread only"


def claim_shared_context():
    """Make the calling thread the owner of the gl backend: create the
    shared context here unless this thread has it already. Raises
    ThreadOwnershipError when another thread owns it (release it there first) or
    when no context can be created. Returns the context."""
    check_thread()
    return shared_context()


def release_shared_context():
    """Free the shared context and every GL object made in it (call from
    the owning thread). The backend stays usable: the next thread that uses
    it creates a new context and owns it. Warpers, renderers and textures
    made in the old context must not be used again. Does nothing when no
    context exists; a failed creation is forgotten, so it is tried again."""
    check_thread()
    with _lock:
        ctx = _shared.get("ctx")
        _shared.clear()
    if ctx is not None:
        ctx.release()


def probe():
    """None when a GL context can be created here, else the reason."""
    try:
        ctx = shared_context()
    except RuntimeError as exc:
        return " ".join(str(exc).split())[:300]
    if ctx.version_code < GL_REQUIRE:  # pragma: no cover - require= already checks
        return f"OpenGL {ctx.version_code} is older than {GL_REQUIRE}"
    return None


#: Renderer names of software rasterizers (GL_RENDERER, lower case).
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swiftshader", "software")


def software_rasterizer(ctx):
    """Whether ``ctx`` renders on the CPU (Mesa llvmpipe, softpipe, SwiftShader)."""
    return any(name in str(ctx.info.get("GL_RENDERER", "")).lower() for name in SOFTWARE_RENDERERS)


def bound_framebuffer(ctx):
    """The framebuffer bound in ``ctx`` (moderngl's record), or framebuffer 0
    when none is recorded or the recorded one has been released."""
    fbo = ctx.fbo
    alive = isinstance(fbo, moderngl.Framebuffer) and not isinstance(fbo.mglo, moderngl.InvalidObject)
    return fbo if alive else ctx.detect_framebuffer(0)
