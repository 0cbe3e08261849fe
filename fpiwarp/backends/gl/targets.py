"""Textures and framebuffers a warper reuses between calls.

Each role (the source texture, the output target, ...) keeps one object
and the key it was made for (size, format); a call with another key
releases the old object and makes a new one. Framebuffers are released
with their textures, after binding a 1×1 framebuffer of our own: moderngl
rebinds the current framebuffer when it creates the next one, and a
deleted one would be GL_INVALID_OPERATION.
"""

import moderngl


def release_object(obj, dummy):
    """Release a cached object; a framebuffer with its textures, after
    binding ``dummy``."""
    if isinstance(obj, moderngl.Framebuffer):
        dummy.use()
        attachments = obj.color_attachments
        obj.release()
        for tex in attachments:
            tex.release()
    else:
        obj.release()


class TargetCache:
    """One texture, framebuffer or sampler per role, remade when its key changes."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._cache = {}  # role -> (key, object)
        #: a 1×1 framebuffer of ours, bound where none of the caller's may be
        self.dummy = ctx.framebuffer(color_attachments=[ctx.renderbuffer((1, 1))])

    def cached(self, role, key, make):
        """The object of ``role`` made for ``key`` (by ``make()`` if new)."""
        old = self._cache.get(role)
        if old is not None and old[0] == key:
            return old[1]
        if old is not None:
            release_object(old[1], self.dummy)
        obj = make()
        self._cache[role] = (key, obj)
        return obj

    def get(self, role):
        """The object of ``role`` made last, or None."""
        entry = self._cache.get(role)
        return None if entry is None else entry[1]

    def texture(self, role, size, components, dtype):
        """A texture of ``size`` (w, h), ``components`` of ``dtype``."""
        return self.cached(role, (size, components, dtype),
                           lambda: self.ctx.texture(size, components, dtype=dtype))

    def target(self, role, size, components, dtype, cover=False):
        """A framebuffer with one color texture (and a coverage one)."""
        def make():
            tex = [self.ctx.texture(size, components, dtype=dtype)]
            if cover:
                tex.append(self.ctx.texture(size, 1, dtype="f4"))
            return self.ctx.framebuffer(color_attachments=tex)
        return self.cached(role, (size, components, dtype, cover), make)

    def owns(self, fbo):
        """Whether ``fbo`` is one of these framebuffers."""
        return fbo is self.dummy or any(fbo is obj for _, obj in self._cache.values())

    def release(self, rebind):
        """Free every object; bind the framebuffer ``rebind`` (one that is
        not ours) before the last of ours goes."""
        for _, obj in self._cache.values():
            release_object(obj, self.dummy)
        self._cache.clear()
        rebind.use()
        self.dummy.release()
