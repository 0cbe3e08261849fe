"""What one stage of the parameter block holds, with named fields.

A map's ``stages()`` returns a list of :class:`Stage`; :func:`fpiwarp.block.pack`
writes them into the block (layout in :mod:`fpiwarp.block.layout`). Every
part has named fields, so the pre- and post-Möbius maps cannot be mixed up
by position.
"""

from dataclasses import dataclass, field

import numpy as np

from .layout import CORE_AFFINE


@dataclass(frozen=True)
class MobiusPart:
    """m(z) = offset + scale * u / (1 - inverse_pole * u), u = z - center.

    ``inverse_pole`` is 1 / (pole - center), 0 for a map without a pole (a
    similarity): the centered form keeps float32 well conditioned when the
    center lies near the data. A stage's ``pre`` part has no ``offset``
    (the block has no room for it) and its ``post`` part is centered at 0;
    :func:`fpiwarp.block.pack` checks both. Defaults give the identity.
    """

    center: complex = 0j
    inverse_pole: complex = 0j
    scale: complex = 1 + 0j
    offset: complex = 0j


@dataclass(frozen=True)
class LinearPart:
    """The R-linear map p -> l1 p + l2 conj(p) + l3 (the identity by default)."""

    l1: complex = 1 + 0j
    l2: complex = 0j
    l3: complex = 0j


@dataclass(frozen=True)
class Region:
    """A half-plane beyond a line, mapped by the similarity z -> a z + b."""

    origin: complex
    normal: complex
    a: complex
    b: complex


@dataclass(frozen=True)
class SeedTable:
    """The Newton cores' seed table (rows in :mod:`fpiwarp.block.layout`):
    node (i, j) at ``lo + i * step.real + 1j * j * step.imag`` holds the
    correction from the R-linear seed to the exact inverse there;
    ``corrections`` has shape (SEED_N, SEED_N), indexed [j, i]."""

    lo: complex
    step: complex
    corrections: np.ndarray


@dataclass(frozen=True)
class Stage:
    """One evaluation stage: regions, pre-Möbius, core, post-Möbius.

    ``core`` is one of :data:`fpiwarp.block.layout.CORES`; ``linear`` is the
    R-linear part of the core (all of it for ``CORE_AFFINE``), ``centers``
    and ``weights`` the TPS terms, ``newton_iters`` and ``newton_tol`` the
    device Newton of ``CORE_TPS_INVERSE``, ``seed`` its optional
    :class:`SeedTable` (None: the R-linear seed alone). For the paired cores
    (:data:`fpiwarp.block.layout.PAIRED_CORES`) ``centers`` and ``weights``
    are each pair's first center c and summed weight W, ``offsets`` and
    ``offset_weights`` its second center's offset d and weight b2 (zero
    for a center without a partner). Defaults give the identity.
    """

    pre: MobiusPart = MobiusPart()
    linear: LinearPart = LinearPart()
    post: MobiusPart = MobiusPart()
    core: int = CORE_AFFINE
    centers: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    weights: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    regions: tuple = ()
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    offset_weights: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    newton_iters: int = 0
    newton_tol: float = 0.0
    seed: SeedTable | None = None

    def __post_init__(self):
        for name, kind in (("pre", MobiusPart), ("linear", LinearPart), ("post", MobiusPart)):
            if not isinstance(getattr(self, name), kind):
                raise TypeError(f"Stage.{name} must be a {kind.__name__}, got {getattr(self, name)!r}")
