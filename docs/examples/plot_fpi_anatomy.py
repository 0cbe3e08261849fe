"""
Inside the FPI: two Möbius maps and one affine map
==================================================

The FPI is ``f = m_W⁻¹ ∘ A ∘ m_Z``, with its parts in ``f.m_src``,
``f.linear`` and ``f.m_dst`` (see :class:`fpiwarp.FPI`). The Möbius map
``m_Z`` sends the source quad's corners to a parallelogram; the affine map
``A`` sends that parallelogram to the one ``m_W`` makes of the target
quad; ``m_W⁻¹`` brings it home. Möbius maps are conformal (small circles
stay circles), so only ``A`` distorts, and by the same amount everywhere:
the FPI's *K*. The small circles drawn on the source become ellipses of
one shape, whatever their place.
"""

import matplotlib.pyplot as plt
import numpy as np

import fpiwarp
import fpiwarp.metrics

src = np.array([[0, 0], [4, 0], [3.2, 3], [0.6, 2.4]])
dst = np.array([[0.5, 0.2], [4.6, -0.4], [3.9, 3.4], [-0.3, 2.6]])
f = fpiwarp.FPI(src, dst)
steps = [
    ("source quad", lambda p: p),
    ("m_Z: a parallelogram", f.m_src),
    ("A: the target's parallelogram", lambda p: f.linear(f.m_src(p))),
    ("m_W⁻¹: the target quad", f),
]
print(f"K = {f.K:.3f}; the pole, far outside: {np.round(f.pole, 1).tolist()}")

# %%
# Grid lines of the source quad (:func:`fpiwarp.metrics.grid`) and small
# circles inside it, pushed through each step.
mesh = fpiwarp.metrics.grid(src, n=200)
lines = [mesh[:, i] for i in range(0, 200, 22)] + [mesh[i] for i in range(0, 200, 22)]
lines += [mesh[:, -1], mesh[-1]]
t = np.linspace(0, 1, 100)
ring = 0.15 * np.stack([np.cos(2 * np.pi * t), np.sin(2 * np.pi * t)], -1)
circles = [ring + mesh[i, j] for i, j in [(40, 40), (100, 100), (160, 160), (40, 160), (160, 40)]]

fig, axes = plt.subplots(1, 4, figsize=(12, 3.2))
for ax, (title, g) in zip(axes, steps):
    for line in lines:
        ax.plot(*g(line).T, color="0.6", lw=0.6)
    for circle in circles:
        ax.fill(*g(circle).T, color="tab:blue", alpha=0.8)
    ax.plot(*g(src).T, "o", color="tab:orange")
    ax.set_title(title, fontsize=10)
    ax.set_aspect("equal")
    ax.invert_yaxis()  # image coordinates: y down
    ax.set_axis_off()
fig.tight_layout()
plt.show()
