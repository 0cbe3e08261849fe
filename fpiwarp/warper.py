"""One map and its warp options, ready to warp many images (:class:`Warper`).

Shared by the array batches of :mod:`fpiwarp.batch` and the folder runs of
:mod:`fpiwarp.batch_folders`: options are checked once, the map is bound
to the backend once (see :func:`fpiwarp.backends.protocol.bind`).
"""

import dataclasses

import numpy as np

from ._errors import ArgumentError
from ._warp import warp_image
from .arrays import array_info
from .backends import backend_capabilities, get_backend
from .backends.protocol import bind
from .validation import (
    check_antialias,
    check_backend_options,
    check_output_shape,
    check_sizes,
    check_warp_arguments,
    check_warp_options,
)

__all__ = ["Warper"]


class Warper:
    """One map and its warp options, ready to warp many images.

    Options are checked once here, with the errors of
    :func:`fpiwarp.warp_image`. Calling the warper on an image returns what
    ``warp_image(image, transform, output_shape, ...)`` returns; the map is
    bound to the backend once (see :mod:`fpiwarp.batch`). Picklable (for
    Dask workers): the bound map is rebuilt where the warper is unpickled.
    Device arrays (:mod:`fpiwarp.arrays`) of the warper's backend are
    warped in place by :func:`fpiwarp.warp_image` (the map is not bound).

    The fast path for many images: the checked arguments are kept per
    image shape and dtype (numpy arrays), so a further image of a known
    shape and dtype goes straight to the bound map, which keeps a prepared
    job (kernel, buffers, launch shape) per kind of call on the device
    backends. The map's parameter block is taken when it is bound (the
    first call): change a map by making a new warper (assigning any of its
    attributes, ``transform`` included, drops what was prepared).
    """

    #: Shapes and dtypes whose checked arguments are kept.
    MAX_PREPARED = 8

    def __init__(self, transform, output_shape=None, *, order=1, mode="constant", cval=0, backend="numpy",
                 backend_options=None, antialias=False):
        caps = backend_capabilities(backend)
        order, mode = check_warp_options(transform, order, mode)
        if np.ndim(cval) > 1:
            raise ArgumentError(f"cval must be a number or one per channel, got {cval!r}")
        self.options = check_backend_options(backend_options, caps, backend, order, mode)
        self.antialias = check_antialias(antialias, caps, backend)
        if output_shape is not None:  # refuse a huge output before the first image is read
            check_sizes((1, 1, 1), check_output_shape(output_shape, None), np.uint8, caps, backend)
        get_backend(backend)  # fail now if unavailable
        self.transform, self.output_shape = transform, output_shape
        self.order, self.mode, self.cval, self.backend = order, mode, cval, backend
        self.capabilities = caps

    def __setattr__(self, name, value):  # a changed option or map drops what was prepared for the old one
        super().__setattr__(name, value)
        if not name.startswith("_"):
            super().__setattr__("_bound", None)
            super().__setattr__("_prepared", {})

    def __getstate__(self):  # no bound map: it may hold device state
        state = self.__dict__.copy()
        state["_bound"] = None
        state["_prepared"] = {}
        return state

    @property
    def bound(self):
        """The map bound to the backend (built on first use)."""
        if self._bound is None:
            self._bound = bind(get_backend(self.backend), self.transform)
        return self._bound

    def __call__(self, image):
        if not isinstance(image, np.ndarray) and array_info(image).kind != "host":
            # a device array (fpiwarp.arrays): warped in place on this warper's backend
            return warp_image(image, self.transform, self.output_shape, order=self.order, mode=self.mode,
                              cval=self.cval, backend=self.backend, backend_options=self.options,
                              antialias=self.antialias)
        key = None
        if type(image) is np.ndarray and image.flags.c_contiguous:
            key = (image.shape, image.dtype)
            args = self._prepared.get(key)
            if args is not None:  # checked before: a known shape and dtype
                out = self.bound.warp_image(image[:, :, None] if args.squeeze else image, args.output_shape,
                                            order=args.order, mode=args.mode, cval=args.cval, **args.options)
                return out[:, :, 0] if args.squeeze else out
        args = check_warp_arguments(image, self.transform, self.output_shape, self.order, self.mode, self.cval,
                                    self.capabilities, self.backend, self.options, self.antialias)
        out = self.bound.warp_image(args.image, args.output_shape, order=args.order, mode=args.mode, cval=args.cval,
                                    **args.options)
        if key is not None and len(self._prepared) < self.MAX_PREPARED:
            self._prepared[key] = dataclasses.replace(args, image=None)
        return out[:, :, 0] if args.squeeze else out
