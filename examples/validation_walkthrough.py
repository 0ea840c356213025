"""Validation walkthrough: a model meets measurements, the missing physics is found and the error falls.

The story of thesis Sec 3.5.2.4, automated:

1. model   -- the nominal lumped test-bed drive (``validation_drive``) and "measurements" (synthetic:
              the bundled files in systems/data/validation, or freshly generated with a hidden
              nut-table joint compliance and guideway friction);
2. compare -- where the nominal model fails (FRF overlay, time residual);
3. diagnose-- re-calibrate the uncertain parameters, rank the candidate effects, accept them one by one;
4. result  -- the updated system, the lines to add to a system file, the error staircase figure.

Run:  python examples/validation_walkthrough.py out/validation
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from bscomp.systems.validation_drive import validation_drive
from bscomp.validate.diagnostics import diagnose
from bscomp.validate.synthetic import generate


def _overlay(data, systems, linear_systems, labels, path):
    """FRF magnitude and table-acceleration time response of several models against the data."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bscomp.simulation.compiled import CompiledModel

    frf, tim = data.frf, data.time
    fig, ax = plt.subplots(2, 1, figsize=(8, 7))
    pair = ("amp.u", "table.a")
    ax[0].loglog(frf.freqs, np.abs(frf.H[pair]), "k.", ms=3, label="measured")
    ax[1].plot(tim.t, tim.outputs["table.a"], "k", lw=0.8, label="measured")
    for s, s_lin, lbl in zip(systems, linear_systems, labels):
        H = CompiledModel(s_lin, ["amp.u"], ["table.a"]).frf({}, frf.freqs, [pair])[pair]
        ax[0].loglog(frf.freqs, np.abs(H), label=lbl)
        y = CompiledModel(s, ["amp.u"], ["table.a"]).simulate({}, tim.t, {"amp.u": tim.inputs["amp.u"]})["table.a"]
        ax[1].plot(tim.t, y, lw=0.8, label=lbl)
    ax[0].set_xlabel("f [Hz]")
    ax[0].set_ylabel("|table.a / amp.u| [m/s^2/V]")
    ax[1].set_xlabel("t [s]")
    ax[1].set_ylabel("table.a [m/s^2]")
    for a in ax:
        a.legend(fontsize=8)
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(out_dir="out/validation") -> int:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    # ---- model and measurements -----------------------------------------------------------------
    nominal = validation_drive()
    data = generate(hidden={"nut_table_joint": {}, "guideway_friction": {}}, seed=2024)
    print(f"nominal: {nominal.description}; uncertain: {nominal.uncertain}")
    print(f"data: {data.frf.source}; {data.time.source} (hidden: {list(data.hidden)})")

    # ---- diagnose ---------------------------------------------------------------------------------
    diag = diagnose(nominal, data.datasets, max_effects=3, verbose=True)
    print(diag.table())
    print("\nlines for the system file:\n" + diag.code())

    # ---- post-process -----------------------------------------------------------------------------
    updated = diag.apply(nominal)
    paths = diag.plot(out)
    paths.append(_overlay(data, [nominal, updated], [nominal, diag.apply(nominal, linear=True)],
                          ["nominal", "after diagnose"], out / "overlay.png"))
    diag.to_json(out / "diagnosis.json")
    for p in paths:
        print(f"written {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "out/validation"))
