"""The registry's "gl" backend on the shared headless context, and the
mesh path as a function of the public API (:func:`warp_image_mesh`)."""

import numpy as np

from ...block import describe
from ...block.many import BlockStack, inverses
from ...validation import check_cval, check_image, check_map_size, check_output_shape, check_sizes, check_warp_options
from .context import check_thread, shared_context
from .warper import GLWarper


class Backend:
    """The registry's "gl" backend on the shared headless context.

    Its warper follows the shared context: after
    :func:`~fpiwarp.backends.gl.context.release_shared_context` the next
    call makes a new warper in the new context (in the thread that makes it).
    """

    name = "gl"

    def __init__(self, max_texture_size=None):
        self.max_texture_size = max_texture_size
        self._warper = None
        shared_context()  # fail here, not at the first warp, without a driver

    @property
    def warper(self):
        """The :class:`GLWarper` of the current shared context (made on
        first use, in the thread that owns the context)."""
        ctx = shared_context()
        if self._warper is None or self._warper.ctx is not ctx:
            check_thread()
            self._warper = GLWarper(ctx, max_texture_size=self.max_texture_size)
        return self._warper

    @property
    def host_pyramids(self):
        """Antialiasing's atlases of recent host sources (the current
        warper's: :class:`~fpiwarp.sampling.pyramid.SourcePyramids`)."""
        return self.warper.pyramids.atlases

    @property
    def ctx(self):
        return self.warper.ctx

    @property
    def device_label(self):
        """The GL renderer and version of the shared context (e.g. "llvmpipe (LLVM 15.0.6, 256 bits), 4.5 (Core
        Profile) Mesa 22.3.6")."""
        info = shared_context().info
        return f"{info.get('GL_RENDERER', '?')}, {info.get('GL_VERSION', '?')}"

    def map_points(self, transform, points):
        check_thread()
        return self.warper.map_points(transform, points)

    def warp_image(self, image, transform, output_shape, *, order, mode, cval, hardware_filter=False,
                   antialias=False):
        check_thread()
        return self.warper.warp_image(image, transform, output_shape, order=order, mode=mode, cval=cval,
                                      hardware_filter=hardware_filter, antialias=antialias)

    def warp_batch(self, stack, transforms, output_shape, *, order, mode, cval, antialias=False):
        """A validated (N, H, W, C) stack warped by one map or one map per
        image, one instanced draw per kind of map (see :mod:`.batch`)."""
        from .batch import warp_batch  # noqa: PLC0415 - loaded with the first batch

        check_thread()
        blocks = BlockStack.of(inverses(transforms))
        return warp_batch(self.warper, stack, blocks, output_shape, order=order, mode=mode, cval=cval,
                          antialias=antialias)

    def map_points_batch(self, transforms, points):
        """float64 (N, P, 2) point sets mapped by one map or one map each,
        one transform-feedback pass per kind of map (see :mod:`.batch_points`)."""
        from .batch_points import map_points_batch  # noqa: PLC0415 - loaded with the first batch

        check_thread()
        return map_points_batch(self.warper, BlockStack.of(transforms), points)

    def bind(self, transform):
        """``transform`` prepared for many images: its inverse's block packed
        and checked once (:class:`BoundMap`)."""
        return BoundMap(self, transform)


class BoundMap:
    """One map bound to the gl backend: the block of its inverse packed
    and checked once; programs, textures and targets are the warper's,
    kept across calls."""

    def __init__(self, backend, transform):
        self.backend = backend
        self.block = np.ascontiguousarray(transform.inverse.params(), dtype=np.float32)
        describe(self.block)  # refuse a block no kernel knows now

    def warp_image(self, image, output_shape, *, order, mode, cval, hardware_filter=False, antialias=False):
        check_thread()
        return self.backend.warper.warp_block(image, self.block, output_shape, order=order, mode=mode, cval=cval,
                                              hardware_filter=hardware_filter, antialias=antialias)


def warp_image_mesh(image, transform, output_shape=None, *, order=1, mode="constant", cval=0,
                    grid_step=4.0, vertices=None, triangles=None):
    """Warp ``image`` by ``transform`` (source -> output) on the GL backend
    by the mesh path: see :meth:`GLWarper.warp_image_mesh`.

    Accepts what :func:`fpiwarp.warp_image` accepts; returns the same
    dtype and channel layout.
    """
    from .. import backend_capabilities, get_backend

    capabilities = backend_capabilities("gl")
    order, mode = check_warp_options(transform, order, mode)
    img, squeeze = check_image(image)
    cval = check_cval(cval, img.shape[2], img.dtype)
    shape = check_output_shape(output_shape, img)
    check_sizes(img.shape, shape, img.dtype, capabilities, "gl")
    check_map_size(transform, capabilities, "gl")  # the mesh path evaluates the forward map
    backend = get_backend("gl")
    check_thread()
    out = backend.warper.warp_image_mesh(
        np.ascontiguousarray(img), transform, shape, order=order, mode=mode, cval=cval,
        grid_step=grid_step, vertices=vertices, triangles=triangles)
    return out[:, :, 0] if squeeze else out


