"""All plotting lives here; matplotlib is imported lazily so computing never needs it.

Functions: :func:`bode_plot` (FRFs), :func:`mode_shape_plot` (:class:`~bscomp.linear.modal.Modes`),
:func:`frequency_position_plot` and :func:`frf_overlay_plot` (:class:`~bscomp.linear.sweeps.PositionSweep`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bscomp.errors import OutputFileError
from bscomp.files import atomic_path, check_path_type, writable_dir


def pyplot():
    """``matplotlib.pyplot`` with a non-interactive backend unless one is chosen (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


_plt = pyplot


def save_figure(fig, path, dpi=120):
    """``fig.savefig(path)`` through a temporary file with the same suffix (format chosen by extension), renamed
    into place when complete: a failing write leaves an existing figure intact.

    Raises :class:`bscomp.errors.OutputFileError` for an extension matplotlib cannot write (before writing).
    """
    check_path_type(path, "figure file (path)")
    suffix = Path(path).suffix.lower().lstrip(".")
    known = fig.canvas.get_supported_filetypes()
    if suffix not in known:
        raise OutputFileError(f"figure file {str(path)!r} has the extension {('.' + suffix) if suffix else '(none)'!r}"
                              f"; use one of {', '.join('.' + k for k in sorted(known))}")
    drop_placeholder_layout(fig)
    with atomic_path(path, "figure file") as tmp:
        fig.savefig(tmp, dpi=dpi)
    return path


def drop_placeholder_layout(fig):
    """Forget the placeholder layout engine ``fig.tight_layout()`` leaves behind (matplotlib >= 3.6): with any
    engine set, ``savefig`` draws the figure twice (once to lay it out); the subplot positions it fixed stay.
    The same bytes are written, in ~60 % of the time (the demo's 13 figures: 26 draws -> 13)."""
    try:
        from matplotlib.layout_engine import PlaceHolderLayoutEngine
    except ImportError:                         # matplotlib 3.5: no layout engines, one draw already
        return
    if isinstance(fig.get_layout_engine(), PlaceHolderLayoutEngine):
        fig.set_layout_engine(None)


def bode_plot(freqs_hz, H, labels=None, title="", path=None):
    """Magnitude (dB) and phase (deg) of one or more FRFs ``H[:, k]`` against frequency [Hz]."""
    plt = _plt()
    H = np.asarray(H)
    if H.ndim == 1:
        H = H[:, None]
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for k in range(H.shape[1]):
        lab = labels[k] if labels else None
        ax1.semilogx(freqs_hz, 20 * np.log10(np.abs(H[:, k]) + 1e-300), label=lab)
        ax2.semilogx(freqs_hz, np.degrees(np.unwrap(np.angle(H[:, k]))), label=lab)
    ax1.set_ylabel("magnitude [dB]")
    ax2.set_ylabel("phase [deg]")
    ax2.set_xlabel("frequency [Hz]")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
    if labels:
        ax1.legend(fontsize=8)
    if title:
        ax1.set_title(title)
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path, dpi=120)
        plt.close(fig)
    return fig


def _finish(fig, plt, path):
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path, dpi=120)
        plt.close(fig)
    return fig


def mode_shape_plot(result, path=None, modes=None, title=None):
    """Mode shapes of a :class:`bscomp.linear.modal.Modes` result, one panel per mode (``modes``: indices,
    default the first 8).

    Each shape is scaled per unit group (rotations [rad] and translations [m] separately) to a largest
    component of 1, so both are visible; bars for up to 30 coordinates, lines along the coordinate list
    otherwise (e.g. the nodes of an FE screw).
    """
    plt = _plt()
    idx = list(range(min(len(result), 8))) if modes is None else [int(k) for k in np.atleast_1d(modes)]
    if not idx:
        raise ValueError("no modes to plot")
    fig, axes = plt.subplots(len(idx), 1, sharex=True, figsize=(8, 1.8 + 1.6 * len(idx)), squeeze=False)
    units = np.asarray(result.units)
    x = np.arange(len(result.coordinates))
    groups = list(dict.fromkeys(units))
    for ax, k in zip(axes[:, 0], idx, strict=True):
        phi = result.shapes[:, k]
        for g in groups:
            sel_g = units == g
            mx = np.max(np.abs(phi[sel_g])) if sel_g.any() else 0.0
            y = phi[sel_g] / mx if mx > 0 else phi[sel_g]
            if len(x) <= 30:
                ax.bar(x[sel_g], y, label=f"[{g}]")
            else:
                ax.plot(x[sel_g], y, ".-", label=f"[{g}]")
        f = result.frequencies[k]
        txt = "rigid body" if result.rigid_body[k] else f"{f:.2f} Hz, zeta = {result.damping[k]:.3f}"
        ax.set_ylabel(f"mode {k + 1}")
        ax.set_title(txt, fontsize=9, loc="left")
        ax.axhline(0, color="k", lw=0.5)
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    if len(x) <= 30:
        axes[-1, 0].set_xticks(x)
        axes[-1, 0].set_xticklabels(result.coordinates, rotation=45, ha="right", fontsize=8)
    else:
        axes[-1, 0].set_xlabel("coordinate index")
    fig.suptitle(title or f"{result.name}: mode shapes (scaled per unit)")
    return _finish(fig, plt, path)


def frequency_position_plot(positions, frequencies, parameter="position", title="", path=None):
    """Natural frequencies ``frequencies[position, mode]`` [Hz] against the swept position."""
    plt = _plt()
    F = np.asarray(frequencies, float)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k in range(F.shape[1]):
        ax.plot(positions, F[:, k], "o-", ms=3, label=f"mode {k + 1}")
    ax.set_xlabel(parameter)
    ax.set_ylabel("natural frequency [Hz]")
    ax.grid(True, alpha=0.3)
    if F.shape[1] <= 10:
        ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    return _finish(fig, plt, path)


def frf_overlay_plot(freqs_hz, H, labels=None, title="", path=None):
    """Magnitude [dB] of several FRFs ``H[curve, freq]`` on one axis (e.g. one per nut position)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for k, h in enumerate(np.asarray(H)):
        ax.semilogx(freqs_hz, 20 * np.log10(np.abs(h) + 1e-300), label=labels[k] if labels else None)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("magnitude [dB]")
    ax.grid(True, which="both", alpha=0.3)
    if labels and len(labels) <= 12:
        ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    return _finish(fig, plt, path)


def time_plot(t, signals, names, title="", path=None, units=None):
    """Signals against time, one axis each; ``units`` ``{name: unit}`` label the axes (``table.a [m/s^2]``)."""
    plt = _plt()
    n = len(signals)
    fig, axes = plt.subplots(n, 1, sharex=True, figsize=(8, 1.8 + 1.6 * n), squeeze=False)
    for ax, y, name in zip(axes[:, 0], signals, names, strict=False):
        ax.plot(t, y)
        unit = (units or {}).get(name)
        ax.set_ylabel(f"{name} [{unit}]" if unit and unit != "1" else name, fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        axes[0, 0].set_title(title)
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path, dpi=120)
        plt.close(fig)
    return fig


#: extensions that name a figure file, not the folder the validation plots write several figures into
_FIGURE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff")


def figure_folder(path, what: str) -> Path:
    """The folder several figures go to, created if needed: ``path`` must be a str or path, not an existing file
    and not a name like ``fig.png`` (these functions write several figures into a folder). ``what`` names the
    argument in errors (``"Comparison.plot: out_dir"``); nothing is created when it is refused."""
    p = writable_dir(path, what)
    if not p.is_dir() and p.suffix.lower() in _FIGURE_SUFFIXES:
        raise OutputFileError(f"{what} {str(p)!r} looks like a figure file, but several figures are written into "
                              f"this folder: give a folder name, e.g. {str(p.with_suffix(''))!r}")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputFileError(f"{what} {str(p)!r} cannot be created: {exc.strerror or exc}",
                              hint="choose a writable location") from exc
    return p
