"""fpiwarp: quasiconformal 4-point warps (Lipman, Kim, Funkhouser 2012)."""

from ._errors import BackendUnavailableError, DegenerateQuadError, InverseNotConvergedError
from ._fpi import FPI
from ._linear import RLinear
from ._mobius import Mobius
from ._transform import Compound, Transform

__version__ = "0.1.0"
from ._warp import map_points, warp_image
from .backends import available_backends, backend_status

__all__ = [
    "FPI",
    "BackendUnavailableError",
    "Compound",
    "DegenerateQuadError",
    "InverseNotConvergedError",
    "Mobius",
    "RLinear",
    "Transform",
    "available_backends",
    "backend_status",
    "map_points",
    "warp_image",
]
