"""Closed-loop figures (thesis Ch 4). Each function receives numbers, the :class:`LoopCurves` of
:meth:`bscomp.control.loop_analysis.LoopAnalysis.curves` (frequency grid [Hz], complex ``L``, ``S``, ``T``,
``D``, step responses, metrics), and computes nothing but decibels and phases; matplotlib is imported when
a figure is drawn.

* :func:`loop_plot` -- one loop: Bode of ``L``, ``|S|``, ``|T|``, step and disturbance-step responses (the
  panels of Figs 4.4-4.11, 4.16-4.18, 4.22-4.25);
* :func:`bode_comparison_plot`, :func:`step_comparison_plot`, :func:`sensitivity_comparison_plot`,
  :func:`disturbance_comparison_plot` -- several loops on one figure.

Any object with the attributes of ``LoopCurves`` will do (``name``, ``metrics``, ``f_hz``, ``L``, ``S``,
``T``, ``D``, ``t``, ``y``, ``t_d``, ``y_d``).
"""

from __future__ import annotations

import sys

import numpy as np

from bscomp.plotting.base import save_figure

__all__ = ["loop_plot", "bode_comparison_plot", "step_comparison_plot", "sensitivity_comparison_plot",
           "disturbance_comparison_plot"]


def _plt():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg") and not _interactive():
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _interactive():
    return hasattr(sys, "ps1")


def _finish(fig, path):
    if path is not None:
        fig.tight_layout()
        save_figure(fig, path, dpi=120)
        _plt().close(fig)
    return fig


def _db(H):
    return 20 * np.log10(np.abs(H))


def _phase_deg(H):
    return np.degrees(np.unwrap(np.angle(H)))


def bode_comparison_plot(curves, path=None, title="Open loop L"):
    """Bode diagram of the open loops ``L`` with the margins in the legend (Fig 4.6, 4.9, 4.16, 4.22)."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for c in curves:
        lab = f"{c.name}: GM {c.metrics['gm_db']:.2f} dB, PM {c.metrics['pm_deg']:.1f} deg"
        a1.semilogx(c.f_hz, _db(c.L), label=lab)
        a2.semilogx(c.f_hz, _phase_deg(c.L))
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


def step_comparison_plot(curves, path=None, title="Unit step response"):
    """Reference step responses (Fig 4.4, 4.7, 4.10, 4.17, 4.23)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    for c in curves:
        ax.plot(1e3 * c.t, c.y, label=f"{c.name}: ts {1e3 * c.metrics['settling_time_s']:.1f} ms, "
                                      f"OS {c.metrics['overshoot_pct']:.1f} %")
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("output / reference")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _finish(fig, path)


def sensitivity_comparison_plot(curves, path=None, title="Sensitivity functions"):
    """``|D|`` (the thesis's "sensitivity": disturbance to output), ``|S|``, ``|T|`` (Fig 4.5, 4.8, 4.18)."""
    plt = _plt()
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 8))
    for c in curves:
        for ax, H in zip(axes, (c.D, c.S, c.T)):
            if H is not None:
                ax.semilogx(c.f_hz, _db(H), label=c.name)
    for ax, lab in zip(axes, ("|D| = |x/F_d| [dB]", "|S| [dB]", "|T| [dB]")):
        ax.set_ylabel(lab)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title(title)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("frequency [Hz]")
    return _finish(fig, path)


def disturbance_comparison_plot(curves, path=None, title="Unit step disturbance force"):
    """Responses to a unit step of ``F_d`` [N] (Fig 4.25); curves without ``F_d`` are skipped."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    for c in curves:
        if c.y_d is None:
            continue
        ax.plot(1e3 * c.t_d, 1e9 * c.y_d, label=f"{c.name}: ts {1e3 * c.metrics['dist_settling_time_s']:.1f} ms")
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("output per N [1e-9 units]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _finish(fig, path)


def loop_plot(c, path=None):
    """Four panels for the curves ``c`` of one loop: Bode of ``L`` with the margins, ``|S|`` and ``|T|``,
    the unit step and (with ``F_d``) the unit disturbance step."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    axes[0, 0].semilogx(c.f_hz, _db(c.L), label="|L|")
    ax_p = axes[0, 0].twinx()
    ax_p.semilogx(c.f_hz, _phase_deg(c.L), "C3", lw=0.8)
    ax_p.set_ylabel("phase L [deg]")
    axes[0, 0].set_title(f"GM {c.metrics['gm_db']:.2f} dB, PM {c.metrics['pm_deg']:.1f} deg")
    axes[0, 0].set_ylabel("|L| [dB]")
    for H, lab in ((c.S, "|S|"), (c.T, "|T|")):
        axes[0, 1].semilogx(c.f_hz, _db(H), label=lab)
    axes[0, 1].legend()
    axes[0, 1].set_ylabel("[dB]")
    axes[1, 0].plot(1e3 * c.t, c.y)
    axes[1, 0].set_title("unit step")
    axes[1, 0].set_xlabel("time [ms]")
    if c.y_d is not None:
        axes[1, 1].plot(1e3 * c.t_d, c.y_d)
        axes[1, 1].set_title("unit step of F_d [N]")
        axes[1, 1].set_xlabel("time [ms]")
    for a in axes.flat:
        a.grid(True, which="both", alpha=0.3)
    for a in axes[0]:
        a.set_xlabel("frequency [Hz]")
    fig.suptitle(c.name, fontsize=9)
    return _finish(fig, path)
