"""Write the bundled truth data sets (issue 13, point 6): FE test-bed truths with hidden effects.

For every case of :data:`bscomp.systems.truths.CASES` (control, joint, friction, backlash, delay,
joint + friction, and ripple: a motor torque ripple outside the candidates' library) and both models
(axial_torsional, full) this writes ``frf.csv``, ``time.csv`` and ``truth.json`` into
``OUT_DIR/<model>/<case>/`` with the seed :func:`~bscomp.systems.truths.default_seed` (the files in
``systems/data/truths`` are this script's output; see the README there).

Run: python examples/make_truth_data.py [OUT_DIR] [--models axial_torsional,full] [--cases joint,delay]
     [--no-time] [--full-nut-joint moving|point] [--summary]

The FRFs take seconds. The time series (IDAS, rtol 1e-7, moving nut) took 40-130 s per case on the
axial + torsional model and 3.4-6.8 min per case on the full 6-DOF model (the full ripple: 17 min, its
rotor turning through the ripple's periods; 2-core machine shared with
other jobs; ~1 min with ``--full-nut-joint point``, the nut frozen at the file's position). Times are
printed and stored in each truth.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from bscomp.systems import truths

DEFAULT_OUT = Path(__file__).resolve().parent.parent / "systems" / "data" / "truths"


def main(out_dir=DEFAULT_OUT, models=truths.MODELS, cases=truths.CASES, time_series: bool = True,
         full_nut_joint: str = "moving") -> list:
    """Generate the cases (section: model), write them (section: solve), print a summary (post-process)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for model in models:
        for case in cases:
            t0 = time.perf_counter()
            kw = {"nut_joint": full_nut_joint} if model == "full" else {}
            res = truths.generate_case(case, model, out, truths.default_seed(case, model), time=time_series, **kw)
            info = res["info"]
            wall = time.perf_counter() - t0
            t_time = info.get("time", {}).get("wall_s", float("nan"))
            rows.append((model, case, info["seed"], info["nut_position"], info["hidden"], info["frf"]["wall_s"],
                         t_time, wall))
            print(f"{model:<16} {case:<15} seed {info['seed']}  x = {info['nut_position']:.4f} m  "
                  f"FRF {info['frf']['wall_s']:5.1f} s  time series {t_time:7.1f} s  total {wall:7.1f} s  "
                  f"{json.dumps(_short(info['hidden']))}", flush=True)
    return rows


def summary(out_dir=DEFAULT_OUT) -> str:
    """A markdown table of the written truths (from their truth.json): what the README lists."""
    lines = ["| model | case | seed | nut position [m] | mesh C | table mass [kg] | k_T factor | hidden values | "
             "FRF [s] | time series [s] |", "|---|---|---|---|---|---|---|---|---|---|"]
    for model in truths.MODELS:
        for case in truths.CASES:
            path = Path(out_dir) / model / case / "truth.json"
            if not path.is_file():
                continue
            i = json.loads(path.read_text())
            hid = "; ".join(f"{k}: " + ", ".join(f"{p} {_fmt(v)}" for p, v in d.items() if p in _MAIN.get(k, ()))
                            for k, d in i["hidden"].items()) or "none"
            tm = i.get("time", {})
            lines.append(f"| {model} | {case} | {i['seed']} | {i['nut_position']:.4f} | "
                         f"{i['mesh']['section_C_elements']} | {i['misset']['table.m']['truth']:.1f} | "
                         f"{i['misset']['coupling.k_T']['factor']:.3f} | {hid} | {i['frf']['wall_s']:.1f} | "
                         f"{tm.get('wall_s', float('nan')):.0f} ({tm.get('nut_joint', '-')} nut) |")
    return "\n".join(lines)


_MAIN = {"joint": ("k", "m", "zeta", "f_target"), "friction": ("F_c", "v_s", "d"), "backlash": ("b", "c"),
         "delay": ("T",), "ripple": ("A", "p", "phi_0"), "housing": ("m", "k", "zeta", "f_target"),
         "damping": ("c_axial", "d_torsion", "zeta_truth")}


def _fmt(v) -> str:
    if isinstance(v, list):
        return "/".join(_fmt(x) for x in v)
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _short(hidden: dict) -> dict:
    return {k: {p: float(f"{v:.4g}") for p, v in d.items() if isinstance(v, float)} for k, d in hidden.items()}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir", nargs="?", default=str(DEFAULT_OUT))
    ap.add_argument("--models", default=",".join(truths.MODELS))
    ap.add_argument("--cases", default=",".join(truths.CASES))
    ap.add_argument("--no-time", action="store_true", help="FRFs and truth.json only")
    ap.add_argument("--summary", action="store_true", help="print the table of the truths in OUT_DIR and stop")
    ap.add_argument("--full-nut-joint", default="moving", choices=("moving", "point"),
                    help="nut joint of the full 6-DOF truth in the time series (point: ~5x faster)")
    a = ap.parse_args()
    if a.summary:
        print(summary(a.out_dir))
        raise SystemExit(0)
    main(a.out_dir, a.models.split(","), a.cases.split(","), not a.no_time, a.full_nut_joint)
