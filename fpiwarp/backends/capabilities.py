"""What each backend accepts, declared as data so it is checked in one place.

A :class:`Capabilities` record says which dtypes, orders and border modes
a backend samples, how large a call may be, how many map stages its
kernels evaluate, which extra options it takes (:class:`BackendOption`),
whether it warps a stack in one call (``batches``), whether it may be
called from several threads at once (``thread_safe``) and whether it
antialiases (``antialias``: ``warp_image(..., antialias=True)``, see
:mod:`fpiwarp.sampling.antialias`). The registry in
:mod:`fpiwarp.backends` holds one record per backend, and
:mod:`fpiwarp.validation` checks every call against it before the
backend runs, so a call a backend cannot do fails with one line instead
of a driver error or an exhausted machine.
"""

from dataclasses import dataclass, field

from ..block import MAX_STAGES
from ..sampling.sampler import DTYPES, MODES, ORDERS

#: Values (rows × cols × channels) one call may read or write: the int32
#: index range of the device kernels. Every backend shares it, so a call
#: that works on one backend works on all.
MAX_ELEMENTS = 2**31 - 1
#: Pixels per side on the device backends: their kernels compute pixel
#: positions in float32, exact for integers up to 2**24.
MAX_DEVICE_SIDE = 2**24
#: Points per map_points call on the opencl backend (its int32 work sizes).
MAX_OPENCL_POINTS = 2**30


@dataclass(frozen=True)
class BackendOption:
    """An option a backend takes beyond those of :func:`fpiwarp.warp_image`.

    ``kind`` is the Python type the value must have; ``orders`` and
    ``modes`` restrict where a true value applies (None: everywhere).
    """

    name: str
    kind: type
    default: object
    doc: str
    orders: tuple | None = None
    modes: tuple | None = None


@dataclass(frozen=True)
class Capabilities:
    """What one backend accepts (see the module docstring)."""

    dtypes: tuple = DTYPES
    orders: tuple = ORDERS
    modes: tuple = MODES
    max_elements: int = MAX_ELEMENTS
    max_side: int | None = None
    max_points: int | None = None
    max_stages: int | None = None
    options: tuple = field(default_factory=tuple)
    batches: bool = False
    thread_safe: bool = False
    antialias: bool = False

    def option(self, name):
        """The :class:`BackendOption` called ``name``, or None."""
        return next((opt for opt in self.options if opt.name == name), None)


NUMPY = Capabilities(batches=True, thread_safe=True, antialias=True)
OPENCL = Capabilities(
    max_side=MAX_DEVICE_SIDE, max_points=MAX_OPENCL_POINTS, max_stages=MAX_STAGES, antialias=True, batches=True
)
WARP = Capabilities(max_side=MAX_DEVICE_SIDE, max_stages=MAX_STAGES, antialias=True, batches=True)
GL = Capabilities(
    max_side=MAX_DEVICE_SIDE,
    max_stages=MAX_STAGES,
    antialias=True,
    batches=True,
    options=(
        BackendOption(
            "hardware_filter",
            bool,
            False,
            "let the texture unit interpolate: faster, bilinear weights quantized by the hardware "
            "(results may differ from the reference by a level or so); with antialias=True the texture unit "
            "also filters the footprint: trilinear over the source's mipmaps by textureGrad (anisotropic "
            "where the driver's filter passes a check; not on llvmpipe), exactly the plain option where "
            "the map does not shrink, elsewhere an approximation blurrier than the reference (measured "
            "against the 8x8 box reference: 1/3 FPI 24-34 dB, 1/8 FPI 28-32 dB, anisotropic 18-31 dB, "
            "where the reference scores 29-57 and plain sampling 13-31; benchmarks/results/antialias.md)",
            orders=(0, 1),
            modes=("constant", "edge", "wrap"),
        ),
    ),
)
