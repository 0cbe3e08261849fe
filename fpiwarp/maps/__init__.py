"""The maps: Möbius, R-linear, the FPI, thin-plate splines, the constrained
FPI, the local deformation operator, and the protocol they share.

One module per topic:

* :mod:`.transform`: the :class:`Transform` protocol and :class:`Compound`
  (composition in mathematical order);
* :mod:`.points`: the API's ``(..., 2)`` arrays to complex numbers and back;
* :mod:`.mobius`, :mod:`.rlinear`: the two building blocks;
* :mod:`.quad`: quad checks, the parallelogram Möbius map, and the
  refusal of pairs float64 cannot build exactly;
* :mod:`.fpi`: the 4-point interpolant (paper §2-3);
* :mod:`.thin_plate_spline`: the spline, its pairing for the block's
  paired cores, its Newton inverse and the device seed table;
* :mod:`.constrained`: the constrained FPI (paper §4.2), where its spline
  is pinned and fitted, and its fold-over check;
* :mod:`.local`: the whole-plane local deformation operator (paper §4.1).
"""

from .constrained import ConstrainedFPI
from .fpi import FPI
from .local import LocalDeformation
from .mobius import Mobius
from .rlinear import RLinear
from .thin_plate_spline import ThinPlateSpline
from .transform import Compound, Transform

__all__ = ["FPI", "Compound", "ConstrainedFPI", "LocalDeformation", "Mobius", "RLinear", "ThinPlateSpline", "Transform"]
