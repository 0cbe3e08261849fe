"""fpiwarp: quasiconformal 4-point warps (Lipman, Kim, Funkhouser 2012)."""

from .resources import bind_source_packages

bind_source_packages()  # kernels/ and glsl/ from this tree, never another checkout's

from .backends import available_backends, backend_capabilities, backend_status
from .backends.default import default_backend, set_default_backend
from .batch.images import warp_batch, warp_images
from .batch.points import map_points_batch
from .errors import (
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
    OutputIsSpecialFileError,
    SizeLimitError,
    SpecError,
    ThreadOwnershipError,
)
from .io.images import read_image, write_image
from .maps.constrained import ConstrainedFPI
from .maps.fpi import FPI
from .maps.local import LocalDeformation
from .maps.mobius import Mobius
from .maps.rlinear import RLinear
from .maps.thin_plate_spline import ThinPlateSpline
from .maps.transform import Compound, Transform
from .sampling.positions import source_positions
from .spec import load_spec
from .warping import Warper, map_points, warp_image

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
    "OutputIsSpecialFileError",
    "RLinear",
    "SizeLimitError",
    "SpecError",
    "ThreadOwnershipError",
    "ThinPlateSpline",
    "Transform",
    "Warper",
    "available_backends",
    "backend_capabilities",
    "backend_status",
    "default_backend",
    "load_spec",
    "map_points",
    "map_points_batch",
    "read_image",
    "set_default_backend",
    "source_positions",
    "warp_batch",
    "warp_image",
    "warp_images",
    "write_image",
]
