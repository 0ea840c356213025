"""Figures for :mod:`bscomp.control.closed_loop` (matplotlib imported here only, lazily by the result objects).

* :func:`plot_loop` -- one loop: Bode of ``L``, ``|S|``, ``|T|``, ``|D|``, step and disturbance-step
  responses (the panels of Figs 4.4-4.11, 4.16-4.18, 4.22-4.25);
* :func:`plot_bode_comparison`, :func:`plot_step_comparison`, :func:`plot_sensitivity_comparison`,
  :func:`plot_disturbance_comparison` -- several loops on one figure.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_loop", "plot_bode_comparison", "plot_step_comparison", "plot_sensitivity_comparison",
           "plot_disturbance_comparison"]


def _plt():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg") and not _interactive():
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _interactive():
    import sys

    return hasattr(sys, "ps1")


def _finish(fig, path):
    if path is not None:
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        _plt().close(fig)
    return fig


def _bode_data(loop, sys):
    from bscomp.control.closed_loop import freqresp

    w = loop.frequencies(1500)
    H = freqresp(sys, w)
    return w / (2 * np.pi), 20 * np.log10(np.abs(H)), np.degrees(np.unwrap(np.angle(H)))


def plot_bode_comparison(loops, path=None, title="Open loop L"):
    """Bode diagram of the open loops ``L`` with the margins in the legend (Fig 4.6, 4.9, 4.16, 4.22)."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for lp in loops:
        f, m, p = _bode_data(lp, lp.L)
        lab = f"{lp.name}: GM {lp.metrics['gm_db']:.2f} dB, PM {lp.metrics['pm_deg']:.1f} deg"
        a1.semilogx(f, m, label=lab)
        a2.semilogx(f, p)
    a1.axhline(0, color="k", lw=0.5)
    a2.axhline(-180, color="k", lw=0.5)
    a1.set_ylabel("|L| [dB]")
    a2.set_ylabel("phase [deg]")
    a2.set_xlabel("frequency [Hz]")
    a1.set_title(title)
    a1.legend(fontsize=7)
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3)
    return _finish(fig, path)


def plot_step_comparison(loops, path=None, title="Unit step response"):
    """Reference step responses (Fig 4.4, 4.7, 4.10, 4.17, 4.23)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    for lp in loops:
        t, y = lp.step()
        ax.plot(1e3 * t, y, label=f"{lp.name}: ts {1e3 * lp.metrics['settling_time_s']:.1f} ms, "
                                  f"OS {lp.metrics['overshoot_pct']:.1f} %")
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("output / reference")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _finish(fig, path)


def plot_sensitivity_comparison(loops, path=None, title="Sensitivity functions"):
    """``|D|`` (the thesis's "sensitivity": disturbance to output), ``|S|``, ``|T|`` (Fig 4.5, 4.8, 4.18)."""
    plt = _plt()
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 8))
    for lp in loops:
        for ax, sys in zip(axes, (lp.D, lp.S, lp.T)):
            if sys is None:
                continue
            f, m, _ = _bode_data(lp, sys)
            ax.semilogx(f, m, label=lp.name)
    for ax, lab in zip(axes, ("|D| = |x/F_d| [dB]", "|S| [dB]", "|T| [dB]")):
        ax.set_ylabel(lab)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title(title)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("frequency [Hz]")
    return _finish(fig, path)


def plot_disturbance_comparison(loops, path=None, title="Unit step disturbance force"):
    """Responses to a unit step of ``F_d`` [N] (Fig 4.25)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    for lp in loops:
        if lp.D is None:
            continue
        t, y = lp.disturbance_step()
        ax.plot(1e3 * t, 1e9 * y, label=f"{lp.name}: ts {1e3 * lp.metrics['dist_settling_time_s']:.1f} ms")
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("output per N [1e-9 units]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _finish(fig, path)


def plot_loop(loop, path=None):
    """Four panels for one :class:`~bscomp.control.closed_loop.LoopAnalysis`."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    f, m, p = _bode_data(loop, loop.L)
    axes[0, 0].semilogx(f, m, label="|L|")
    ax_p = axes[0, 0].twinx()
    ax_p.semilogx(f, p, "C3", lw=0.8)
    ax_p.set_ylabel("phase L [deg]")
    axes[0, 0].set_title(f"GM {loop.metrics['gm_db']:.2f} dB, PM {loop.metrics['pm_deg']:.1f} deg")
    axes[0, 0].set_ylabel("|L| [dB]")
    for sys, lab in ((loop.S, "|S|"), (loop.T, "|T|")):
        f, m, _ = _bode_data(loop, sys)
        axes[0, 1].semilogx(f, m, label=lab)
    axes[0, 1].legend()
    axes[0, 1].set_ylabel("[dB]")
    t, y = loop.step()
    axes[1, 0].plot(1e3 * t, y)
    axes[1, 0].set_title("unit step")
    axes[1, 0].set_xlabel("time [ms]")
    if loop.D is not None:
        t, y = loop.disturbance_step()
        axes[1, 1].plot(1e3 * t, y)
        axes[1, 1].set_title("unit step of F_d [N]")
        axes[1, 1].set_xlabel("time [ms]")
    for a in axes.flat:
        a.grid(True, which="both", alpha=0.3)
    for a in axes[0]:
        a.set_xlabel("frequency [Hz]")
    fig.suptitle(loop.name, fontsize=9)
    return _finish(fig, path)
