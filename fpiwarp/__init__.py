"""fpiwarp: quasiconformal 4-point warps (Lipman, Kim, Funkhouser 2012)."""

from .resources import bind_source_packages

bind_source_packages()  # kernels/ and glsl/ from this tree, never another checkout's

from ._constrained import ConstrainedFPI
from ._errors import (
    ArgumentError,
    ArgumentTypeError,
    BackendUnavailableError,
    ConstraintError,
    DegenerateQuadError,
    DeviceMismatchError,
    FoldOverError,
    FpiwarpError,
    IllConditionedPairError,
    ImageError,
    InverseNotConvergedError,
    MissingDependencyError,
    OutputExistsError,
    OutputIsFolderError,
    SizeLimitError,
    SpecError,
)
from ._fpi import FPI
from ._linear import RLinear
from ._local import LocalDeformation
from ._mobius import Mobius
from ._tps import ThinPlateSpline
from ._transform import Compound, Transform
from ._warp import map_points, warp_image
from .backends import available_backends, backend_capabilities, backend_status
from .batch import warp_batch, warp_images
from .batch_points import map_points_batch
from .io import read_image, write_image
from .positions import source_positions
from .spec import load_spec

__version__ = "0.1.0"

__all__ = [
    "FPI",
    "ArgumentError",
    "ArgumentTypeError",
    "BackendUnavailableError",
    "Compound",
    "ConstrainedFPI",
    "ConstraintError",
    "DegenerateQuadError",
    "DeviceMismatchError",
    "FoldOverError",
    "FpiwarpError",
    "IllConditionedPairError",
    "ImageError",
    "InverseNotConvergedError",
    "LocalDeformation",
    "MissingDependencyError",
    "Mobius",
    "OutputExistsError",
    "OutputIsFolderError",
    "RLinear",
    "SizeLimitError",
    "SpecError",
    "ThinPlateSpline",
    "Transform",
    "available_backends",
    "backend_capabilities",
    "backend_status",
    "load_spec",
    "map_points",
    "map_points_batch",
    "read_image",
    "source_positions",
    "warp_batch",
    "warp_image",
    "warp_images",
    "write_image",
]
