"""Design-sweep maps: a result over two swept parameters (e.g. the first-mode frequency over bearing and
coupling stiffness), from the numbers of a :class:`bscomp.design_sweep.SweepTable`."""

from __future__ import annotations

import numpy as np

from bscomp.plotting.base import pyplot, save_figure

__all__ = ["sweep_map"]


def sweep_map(xs, ys, Z, xlabel: str, ylabel: str, label: str, title: str = "", path=None, levels: int = 14):
    """Filled contours of ``Z[j, i]`` at ``(xs[i], ys[j])`` with labelled iso-lines; saved to ``path`` if given.

    Returns the matplotlib Figure.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    X, Y = np.meshgrid(np.asarray(xs, float), np.asarray(ys, float))
    cf = ax.contourf(X, Y, Z, levels=levels, cmap="viridis")
    cs = ax.contour(X, Y, Z, levels=cf.levels[::2], colors="white", linewidths=0.6)
    ax.clabel(cs, fmt="%.0f", fontsize=7)
    fig.colorbar(cf, ax=ax, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path, dpi=120)
    return fig
