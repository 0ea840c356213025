"""``bscomp demo``: the thesis test bed's modes and FRF, then the validation story on the bundled measurements
(compare, diagnose, the lines to add, the HTML report). Called by :mod:`bscomp.cli` inside its error boundary."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bscomp import cli_checks as ck


def demo(args) -> int:
    """Modes and FRFs of the thesis test bed (FE, axial + torsional), then the validation story."""
    from bscomp.linear.modal import modes
    from bscomp.model import as_system

    out = ck.output_folder(args.out, "--out")         # before computing: not a file, writable
    out.mkdir(parents=True, exist_ok=True)
    system = as_system("testbed_axial_torsional")
    print(f"bscomp demo: {system.description}")
    md = modes(system, inputs=["amp.u"], outputs=["rotor.w", "table.a"], n=6, warn=False)  # small-signal demo
    print("  modes (undamped K phi = w^2 M phi; damping from the damped poles):")
    print("    " + md.table("rotor.phi").replace("\n", "\n    "))
    from bscomp.linear.response import frf

    f = np.logspace(0, np.log10(2000), 600)
    res = frf(system, input="amp.u", output=["rotor.w", "table.a"], freqs=f, warn=False)
    from bscomp.plotting.base import bode_plot

    png = out / "demo_bode.png"
    bode_plot(f, res.H[:, :, 0], labels=["amp.u -> rotor.w [rad/s/V]", "amp.u -> table.a [m/s^2/V]"],
              title="thesis test bed (FE, axial + torsional): open-loop FRF", path=png)
    print(f"  Bode plot written to {png}")
    if args.no_validation:
        return 0
    return demo_validation(out)


DEMO_CASE = ("axial_torsional", "joint_friction")
"""The bundled measurements of the demo: an FE test-bed truth with two hidden effects
(``systems/data/truths/axial_torsional/joint_friction``, made by :mod:`bscomp.systems.truths`)."""


def demo_validation(out: Path) -> int:
    """The headline story on bundled measurements of the FE test bed: compare, diagnose, add, explain, compare
    again (the model with the effects found: the report's third section)."""
    import json
    from importlib import resources

    from bscomp.validate.comparison import compare
    from bscomp.validate.diagnostics import diagnose
    from bscomp.validate.measurements import load_all
    from bscomp.validate.report import write_report

    root = resources.files("bscomp.systems") / "data" / "truths" / DEMO_CASE[0] / DEMO_CASE[1]
    datasets = load_all([str(root / "frf.csv"), str(root / "time.csv")])
    print("\nbscomp demo, part 2: the FE model meets measurements it did not make (synthetic, from an "
          "independent truth with another mesh, the moving nut, noise and hidden effects: "
          f"systems/data/truths/{'/'.join(DEMO_CASE)})")
    comp = compare("testbed_axial_torsional", datasets)
    print("  " + comp.summary().replace("\n", "\n  "))
    print("  diagnosing: re-calibrate the uncertain parameters, then fit and confirm the candidate effects...",
          flush=True)
    diag = diagnose("testbed_axial_torsional", datasets, max_effects=2)
    print("  " + diag.table().replace("\n", "\n  "))
    if diag.accepted:
        print("  lines to add to the system file:\n    " + diag.code().replace("\n", "\n    "))
    truth = json.loads((root / "truth.json").read_text())
    print(f"  (the truth, which diagnose did not see: {json.dumps(truth['hidden'])})")
    items = [comp, diag]
    if diag.accepted:                     # the lines added: compare again, the error fallen in the user's own terms
        after = compare(diag.updated("testbed_axial_torsional"), datasets)
        print("  the model with the effects found, compared again:\n  " + after.summary().replace("\n", "\n  "))
        items.append(after)
    from bscomp.files import atomic_dir

    rep = out / "validation"
    with atomic_dir(rep) as tmp:
        write_report(items, tmp, title="bscomp demo: the FE test bed meets the measurements")
        diag.to_json(tmp / "diagnosis.json")
    path = rep / "index.html"
    print(f"  report written to {path}")
    return 0
