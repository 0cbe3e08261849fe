"""
The FPI curve through four points (Fig. 6)
==========================================

:func:`fpiwarp.curves.fpi_curve` draws a closed curve through four
anchors: the image of the unit circle under the FPI that sends four
equally spaced points of the circle to the anchors. Since the FPI is a
bijection, the curve never crosses itself; as the anchors move from a
square towards a long kite, the curve goes from a circle to an
egg-shaped oval.
"""

import matplotlib.pyplot as plt
import numpy as np

from fpiwarp.curves import fpi_curve

quads = {
    "square": [[1, 0], [0, 1], [-1, 0], [0, -1]],
    "rectangle": [[2, 0], [0, 1], [-2, 0], [0, -1]],
    "kite": [[1.6, 0], [0, 0.8], [-0.6, 0], [0, -0.8]],
    "skewed": [[1.4, 0.3], [0.1, 1.1], [-1, -0.2], [0.3, -0.9]],
}

fig, axes = plt.subplots(1, len(quads), figsize=(11, 3))
for ax, (name, anchors) in zip(axes, quads.items()):
    curve = fpi_curve(anchors, n=256)
    closed = np.vstack([curve, curve[:1]])
    a = np.asarray(anchors, float)
    ax.plot(*closed.T, color="tab:blue")
    ax.plot(*np.vstack([a, a[:1]]).T, ":", color="gray")
    ax.plot(*a.T, "o", color="tab:orange")
    ax.set_title(name)
    ax.set_aspect("equal")
    ax.set_axis_off()
    print(f"{name:9s} passes through its anchors: {np.allclose(curve[::64], a)}")
fig.tight_layout()
plt.show()
