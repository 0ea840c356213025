"""All plotting lives here; matplotlib is imported lazily so computing never needs it."""

from __future__ import annotations

import numpy as np


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


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
        fig.savefig(path, dpi=120)
        plt.close(fig)
    return fig
