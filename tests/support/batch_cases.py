"""Maps of every block kind, varied by an index, for the batch tests."""

import fpiwarp


def make_map(kind, k, w, h):
    """A map of ``kind`` (each kind a different block kind), varied by k."""
    src = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    d = 0.37 * k
    fpi = fpiwarp.FPI(src, [[1 + d, 1.2], [w - 2 - 0.5 * d, -1 - d], [w + 1, h - 1 + 0.7 * d], [-1 - 0.3 * d, h - 2]])
    tps = fpiwarp.ThinPlateSpline([w / 4 + 1j * h / 3, w / 2 + 1j * h / 2 + k, 3 * w / 4 + 1j * h / 4],
                                  [0.01, -0.02 * (1 + k), 0.01j], (1, 0.05, 1 + 0.5j * k))
    return {
        "fpi": fpi,
        "fpi_inverse": fpi.inverse,
        "shift": fpiwarp.RLinear(1, 0.1 * k, 0.5 + 1j * k),
        "compound": fpi @ fpiwarp.RLinear(1, 0, k),
        "tps": tps,
        "tps_inverse": tps.inverse,
    }[kind]


KINDS = ["fpi", "fpi_inverse", "shift", "compound", "tps", "tps_inverse"]
