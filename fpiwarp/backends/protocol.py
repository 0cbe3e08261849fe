"""The interface a backend implements; what it accepts is in :mod:`.capabilities`.

Backends receive arguments already checked by :mod:`fpiwarp.validation`
against their declared :class:`~fpiwarp.backends.capabilities.Capabilities`:
a contiguous (H, W, C) image of a declared dtype, ``output_shape`` as two
Python ints, ``order`` and ``mode`` among the declared ones, ``cval`` as
float64 (C,), float64 (..., 2) points, and only declared options.
"""

from typing import Protocol, runtime_checkable


@runtime_checkable
class Backend(Protocol):
    """What :func:`fpiwarp.backends.get_backend` returns."""

    name: str

    def map_points(self, transform, points):
        """float64 (..., 2) points mapped by ``transform``; float64 (..., 2) out."""

    def warp_image(self, image, transform, output_shape, *, order, mode, cval, **options):
        """(rows, cols, C) of the image's dtype: each output pixel sampled at
        ``transform.inverse`` of its position."""


@runtime_checkable
class BatchingBackend(Backend, Protocol):
    """A backend whose capabilities say ``batches``: a stack in one call."""

    def warp_batch(self, stack, transforms, output_shape, *, order, mode, cval):
        """(N, rows, cols, C) from an (N, H, W, C) stack and a list of one
        map for all images or one map per image."""


@runtime_checkable
class BindingBackend(Backend, Protocol):
    """A backend that prepares one map for many images (``bind``)."""

    def bind(self, transform):
        """An object with ``warp_image(image, output_shape, *, order, mode, cval)``."""


class GenericBoundMap:
    """``bind`` for a backend without one: each image warped by ``warp_image``."""

    def __init__(self, backend, transform):
        self.backend, self.transform = backend, transform

    def warp_image(self, image, output_shape, *, order, mode, cval, **options):
        return self.backend.warp_image(image, self.transform, output_shape, order=order, mode=mode, cval=cval,
                                       **options)


def bind(backend, transform):
    """``backend.bind(transform)`` where the backend prepares maps, else a
    :class:`GenericBoundMap`."""
    if isinstance(backend, BindingBackend):
        return backend.bind(transform)
    return GenericBoundMap(backend, transform)
