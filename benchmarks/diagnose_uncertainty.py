"""How honest diagnose's ``+-`` are: ``z = (fitted - hidden) / std`` on the bundled FE truths, for the reported
standard deviation (:func:`bscomp.validate.uncertainty.parameter_std`, the sandwich with batch means) and for the
classical ``sigma^2 (J^T J)^-1`` it replaced (docs/validation.md, "Parameter uncertainty").

Per case of ``systems/data/truths/<model>/``: each accepted effect's main parameters (as
``benchmarks/diagnose_table.py``) and the re-calibrated table mass and coupling stiffness against the truth's
hidden values (the table mass without the hidden part where ``table_subassembly`` was accepted); then the
median |z| and the counts within 1 / 2 / 3 std over all cases run.

    python benchmarks/diagnose_uncertainty.py [--model axial_torsional|full ...] [--case NAME ...] [--json F]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from diagnose_table import CASES, MODELS, hidden_pairs, load_case  # noqa: E402

import bscomp.validate.evaluation as evaluation  # noqa: E402
from bscomp.validate.diagnostics import diagnose  # noqa: E402
from bscomp.validate.uncertainty import parameter_std  # noqa: E402

_CALLS = []      # (reported std, classical std) per uncertainty() call, by parameter label


def _uncertainty(self, theta, sol):
    """Problem.uncertainty, also keeping the classical value of the same fit."""
    if sol is None or sol.jac is None:
        return {}
    rob, cla = parameter_std(np.asarray(sol.jac), np.asarray(sol.fun), getattr(self, "block_sizes", []))
    out = {f.label: float(math.exp(t) * s) for f, t, s in zip(self.free, theta, rob, strict=True)}
    _CALLS.append((out, {f.label: float(math.exp(t) * c) for f, t, c in zip(self.free, theta, cla, strict=True)}))
    return out


def _classical(label, std):
    """The classical std of the fit that reported ``std`` for ``label``."""
    for rob, cla in reversed(_CALLS):
        if rob.get(label) == std:
            return cla[label]
    return float("nan")


def run(model: str, case: str) -> list:
    truth, data = load_case(model, case)
    _CALLS.clear()
    t0 = time.perf_counter()
    d = diagnose(MODELS[model], data, max_effects=2)
    wall = time.perf_counter() - t0
    items = []
    for a, n, t in hidden_pairs(d, truth):
        s = a.std.get(n, float("nan"))
        items.append((f"{a.name}.{n}", a.values[n], s, _classical(f"{a.name}.{n}", s), t))
    joint = "joint" in truth["hidden"] and any(a.name == "table_subassembly" for a in d.accepted)
    for k, (v, s) in d.recalibrated.items():
        if k == "table.m" and joint:
            t = truth["hidden"]["joint"]["table_m"]
        elif k in truth.get("misset", {}):
            t = truth["misset"][k]["truth"]
        else:
            continue
        items.append((k, v, s, _classical(k, s), t))
    rows = []
    for name, v, s, c, t in items:
        rows.append(dict(model=model, case=case, param=name, fit=v, truth=t, rel=v / t - 1, std=s, classical=c,
                         z=(v - t) / s, z_classical=(v - t) / c))
        print(f"| {model} | {case} | {name} | {v / t - 1:+.2%} | {s:.3g} ({s / c:.1f}x classical) | "
              f"{(v - t) / s:+.1f} | {(v - t) / c:+.1f} |", flush=True)
    print(f"<!-- {case}: {wall:.0f} s -->", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", nargs="*", choices=list(MODELS), default=list(MODELS))
    ap.add_argument("--case", nargs="*", choices=CASES, default=CASES)
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    evaluation.Problem.uncertainty = _uncertainty
    print("| model | case | parameter | fitted vs hidden | std | z | z classical |\n|---|---|---|---:|---:|---:|---:|")
    rows = [r for m in args.model for c in args.case for r in run(m, c)]
    z, zc = np.abs([r["z"] for r in rows]), np.abs([r["z_classical"] for r in rows])
    print(f"\n{len(rows)} parameters: median |z| {np.median(z):.2f} (classical {np.median(zc):.2f}); within 1 / 2 / 3 "
          f"std: {', '.join(f'{np.sum(z <= k)}' for k in (1, 2, 3))} (classical "
          f"{', '.join(f'{np.sum(zc <= k)}' for k in (1, 2, 3))})")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
