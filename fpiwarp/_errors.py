"""Exceptions raised by fpiwarp, one type per kind of user mistake."""


class DegenerateQuadError(ValueError):
    """Four points that cannot define an orientation-preserving 4-point map.

    Raised for wrong shapes, NaN or inf, coincident points, three collinear
    points, zero area, self-intersecting (bow-tie) quads, and for a source
    and target of opposite orientation. The message names the problem.
    """


class BackendUnavailableError(RuntimeError):
    """A backend was asked for that cannot run here; the message says why
    and which extra to install."""


class InverseNotConvergedError(ArithmeticError):
    """A numerical inverse did not reach its tolerance; no silent wrong answer."""
