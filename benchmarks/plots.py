"""Pictures of the benchmarks (matplotlib, Agg: no display needed).

- :func:`speed_scaling`: time against size, log-log, one line per
  backend and peer; one panel per workload (points, uint8 and float32
  images).
- :func:`fig8`: like the paper's Fig. 8, a checkerboard deformed by each
  method beside its conformal dilation (blue 0, red >= 0.8, the paper's
  scale), one column pair per configuration, the constraints on top.
- :func:`fig11`: the same for the constrained FPI against a TPS with the
  same edge constraints.

The deformed pictures are drawn forward, as the paper's textured meshes:
a grid over the square is mapped by the method and each cell is filled
with its checker color or its dilation at the cell center.
"""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np

from fpiwarp import metrics

DILATION_MAX = 0.8  # the paper's color scale: dark red is 0.8


def speed_scaling(results, path, dpi=90):
    """Log-log time against size for every implementation, saved to ``path``."""
    panels = [("map_points", "float64", "map_points (points)")]
    if any(r.workload == "map_points constrained" for r in results):
        panels.append(("map_points constrained", "float64", "map_points, constrained FPI (points)"))
    panels += [
        ("warp_image", d, f"warp_image, {d} RGB (pixels)")
        for d in sorted({r.dtype for r in results if r.workload == "warp_image"}, reverse=True)
    ]
    fig, axes = plt.subplots(1, len(panels), figsize=(6.0 * len(panels), 4.8), squeeze=False)
    for ax, (workload, dtype, title) in zip(axes[0], panels):
        rows = [r for r in results if r.workload == workload and r.dtype == dtype]
        for impl in dict.fromkeys(r.impl for r in rows):
            pts = [(r.n, r.seconds) for r in rows if r.impl == impl and r.seconds is not None]
            if not pts:
                continue
            n, s = zip(*pts)
            backend = impl.startswith("fpiwarp")
            ax.plot(
                n,
                s,
                marker="o" if backend else "s",
                linestyle="-" if backend else "--",
                linewidth=2 if backend else 1.2,
                label=impl,
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(title.split("(")[-1].rstrip(")"))
        ax.set_ylabel("seconds per call")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.subplots_adjust(left=0.06, right=0.99, bottom=0.11, top=0.92, wspace=0.22)
    fig.savefig(path, dpi=dpi, format="png")
    plt.close(fig)


def _mesh(f, n):
    """Mapped (n+1) × (n+1) vertices of the unit square, and the dilation
    at the n × n cell centers."""
    t = np.linspace(0.0, 1.0, n + 1)
    verts = np.stack(np.meshgrid(t, t), axis=-1)
    c = (np.arange(n) + 0.5) / n
    centers = np.stack(np.meshgrid(c, c), axis=-1)
    with np.errstate(all="ignore"):
        mapped = np.asarray(f(verts.reshape(-1, 2)), dtype=np.float64).reshape(verts.shape)
        dil = metrics.conformal_dilation(f, centers.reshape(-1, 2)).reshape(n, n)
    return mapped, dil


def _limits(dst):
    lo, hi = dst.min(axis=0), dst.max(axis=0)
    pad = 0.15 * max(hi - lo)
    return (lo[0] - pad, hi[0] + pad), (lo[1] - pad, hi[1] + pad)


def _draw(ax_board, ax_dil, f, dst, n, checkers=8):
    xlim, ylim = _limits(np.asarray(dst))
    for ax in (ax_board, ax_dil):
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    if f is None:
        for ax in (ax_board, ax_dil):
            ax.text(0.5, 0.5, "failed", ha="center", va="center", transform=ax.transAxes)
        return None
    mapped, dil = _mesh(f, n)
    finite = np.isfinite(mapped).all(axis=-1)
    mapped = np.where(finite[..., None], np.clip(mapped, -1e3, 1e3), 0.0)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    board = ((i * checkers // n + j * checkers // n) % 2).astype(float)
    ax_board.pcolormesh(mapped[..., 0], mapped[..., 1], board, cmap="gray", vmin=-0.3, vmax=1.2, shading="flat")
    return ax_dil.pcolormesh(
        mapped[..., 0],
        mapped[..., 1],
        np.nan_to_num(dil, nan=DILATION_MAX),
        cmap="jet",
        vmin=0,
        vmax=DILATION_MAX,
        shading="flat",
    )


def _constraints(ax, src, dst):
    src, dst = np.asarray(src), np.asarray(dst)
    ax.fill(*np.r_[src, src[:1]].T, facecolor="0.9", edgecolor="0.5", linestyle="--")
    ax.plot(*np.r_[dst, dst[:1]].T, color="C3", linewidth=1)
    for a, b in zip(src, dst):
        ax.annotate("", xy=b, xytext=a, arrowprops={"arrowstyle": "->", "color": "C0"})
    ax.plot(*dst.T, "o", color="C3", markersize=3)
    xlim, ylim = _limits(np.r_[src, dst])
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def _grid_figure(columns, rows, maps, path, n, title, dpi):
    """columns: [(name, src, dst)]; rows: method names; maps[(col, row)]."""
    ncols, nrows = 2 * len(columns), len(rows) + 1
    fig, axes = plt.subplots(nrows, ncols, figsize=(1.55 * ncols + 0.8, 1.55 * nrows + 0.6), squeeze=False)
    mappable = None
    for c, (name, src, dst) in enumerate(columns):
        _constraints(axes[0, 2 * c], src, dst)
        axes[0, 2 * c].set_title(name, fontsize=8)
        axes[0, 2 * c + 1].axis("off")
        for r, method in enumerate(rows, start=1):
            m = _draw(axes[r, 2 * c], axes[r, 2 * c + 1], maps.get((name, method)), dst, n)
            mappable = m or mappable
    for r, method in enumerate(rows, start=1):
        axes[r, 0].set_ylabel(method, fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0.04, right=0.89, bottom=0.02, top=0.93, wspace=0.06, hspace=0.12)
    if mappable is not None:
        cax = fig.add_axes((0.91, 0.1, 0.012, 0.75))
        fig.colorbar(mappable, cax=cax, label="conformal dilation")
    fig.savefig(path, dpi=dpi, format="png")
    plt.close(fig)


def fig8(quality_result, path, n=64, dpi=80):
    """Checkerboard and dilation per method and configuration (Fig. 8)."""
    from .quality import METHODS

    columns = [(c["name"], c["src"], c["dst"]) for c in quality_result["configs"]]
    _grid_figure(
        columns,
        METHODS,
        quality_result["_maps"],
        path,
        n,
        "Square with moved corners: checkerboard | conformal dilation",
        dpi,
    )


def fig11(quality_result, path, n=64, dpi=80):
    """Constrained FPI against TPS with the same constraints (Fig. 11)."""
    cfgs = quality_result.get("constrained") or []
    if not cfgs:
        return False
    columns = [(c["name"], c["src"], c["dst"]) for c in cfgs]
    rows = list(cfgs[0]["rows"])
    _grid_figure(
        columns, rows, quality_result["_maps"], path, n, "Constrained FPI vs TPS with the same edge constraints", dpi
    )
    return True
