"""Rigid-ballscrew (Eq 3.35) vs shape-function (Eq 3.36-3.39) screw-nut interface: first screw-nut
frequencies vs nut length, for a stiff and a slender screw (issue: component library, item 6).

Run: python examples/screw_nut_methods.py OUT_DIR
"""

from __future__ import annotations

import sys
from pathlib import Path


def main(out_dir="out/screw_nut_methods"):
    from bscomp.plotting import pyplot as _plt

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "components"))
    from test_screw_nut_shape_function import nut_frequencies

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    turns = [1, 2, 4, 6, 8, 10]
    for ax, (label, d, E) in zip(axes, [("stiff screw (40 mm, E x 1000)", 0.04, 210e12),
                                        ("slender screw (12 mm, steel)", 0.012, 210e9)]):
        fr = [nut_frequencies("rigid", d=d, E=E, turns=t)[0] for t in turns]
        fs = [nut_frequencies("shape", d=d, E=E, turns=t)[0] for t in turns]
        L = [2 * t * 10.0 for t in turns]  # nut length [mm] = turns x 2 x lead
        ax.plot(L, fr, "o-", label="rigid ballscrew (Eq 3.35)")
        ax.plot(L, fs, "s--", label="shape functions (Eq 3.36-3.39)")
        ax.set_xlabel("nut length [mm]")
        ax.set_ylabel("first screw-nut mode [Hz]")
        ax.set_title(label, fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        print(f"{label}: " + ", ".join(f"{l:.0f} mm: {a:.1f} vs {b:.1f} Hz" for l, a, b in zip(L, fr, fs)))
    fig.tight_layout()
    path = out / "screw_nut_methods.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


if __name__ == "__main__":
    main(*(sys.argv[1:2] or ["out/screw_nut_methods"]))
