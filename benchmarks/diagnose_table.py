"""The results table of ``docs/validation.md``: ``diagnose`` on every bundled truth case of both FE test beds.

For each model (``axial_torsional`` -> ``testbed_axial_torsional``, ``full`` -> ``testbed``) and case of
``systems/data/truths/<model>/`` (made by :mod:`bscomp.systems.truths`: another FE mesh, the moving nut,
mis-set uncertain parameters, hidden effects of their own structure, noise), one ``diagnose(..., max_effects=2)``
of the case's FRF file and 0.6 s time series; printed: the candidate named first (with those the data cannot
tell apart from it, :mod:`bscomp.validate.equivalence`), the best other refined one with Vuong's z against it
and the share of their improvements in common, the accepted ones, their main parameters against the truth's
hidden values (relative error), the error after re-calibration and at the end (mean chi^2, 1 = noise floor)
with the drop, and the wall clock.

    python benchmarks/diagnose_table.py [--model axial_torsional|full] [--case joint ...] [--json out.json] [--stepped]
                                        [--seed N ...] [--channels rotor.phi,table.s] [--drive other]
                                        [--case bearing_friction] [--candidate rotor_friction]

``--drive other`` (with ``--seed``): truths of another drive than the thesis's, built from the same components
(:data:`bscomp.systems.truths.DRIVES`), diagnosed with that drive's model (``overrides`` =
:func:`bscomp.systems.truths.drive_overrides`). ``--case bearing_friction`` (with ``--seed``): a truth with friction
at the screw's bearing instead of the guideways (:data:`bscomp.systems.truths.EXTRA_CASES`); ``--candidate NAME``
adds a library candidate to the defaults (:func:`bscomp.validate.candidates.library`; one already among them is tried
once -- ``rotor_friction``, optional until 2026-12-07, is a default now).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from importlib import resources  # noqa: E402
from pathlib import Path  # noqa: E402

from bscomp.systems.truths import CASES as TRUTH_CASES  # noqa: E402
from bscomp.systems.truths import EXTRA_CASES as TRUTH_EXTRA  # noqa: E402
from bscomp.validate.arguments import resolve_candidates  # noqa: E402
from bscomp.validate.candidates import default_candidates  # noqa: E402
from bscomp.validate.conclusion import UNEXPLAINED  # noqa: E402
from bscomp.validate.diagnostics import diagnose  # noqa: E402
from bscomp.validate.measurements import load_all  # noqa: E402

MODELS = {"axial_torsional": "testbed_axial_torsional", "full": "testbed"}
CASES = list(TRUTH_CASES)
EXTRA = list(TRUTH_EXTRA)          # drawn by seed only (no bundled data): --case bearing_friction --seed N
#: accepted effect -> (hidden effect, its main parameters as (candidate name, truth name))
MAIN = {"table_subassembly": ("joint", (("m", "m"), ("k", "k"))), "guideway_friction": ("friction", (("F_c", "F_c"),)),
        "guideway_stribeck": ("friction", (("F_c", "F_c"),)), "screw_nut_backlash": ("backlash", (("b", "b"),)),
        "compliant_backlash": ("backlash", (("b", "b"), ("k", "c"))), "amplifier_delay": ("delay", (("T", "T"),)),
        "bearing_housing": ("housing", (("m", "m"), ("k", "k"))), "support_damping": ("damping", (("c", "c_axial"),)),
        "coupling_damping": ("damping", (("d", "d_torsion"),)),
        "rotor_friction": ("bearing_friction", (("T_c", "T_c"),))}


def stepped_frfs(model: str, case: str, conditions: dict) -> list:
    """Stepped-sine FRFs of the truth at 0.2 V and 2 V (14 frequencies 10-200 Hz, rotor.w and table.a per amp.u,
    1 % complex noise; the truth's hidden delay is not in its System, so not the ``delay`` case), each stating its
    amplitude -- the FRFs a test engineer measures on a drive with friction,
    instead of the bundled small-signal one (cached in benchmarks/.cache/stepped_truths)."""
    import zlib

    import numpy as np

    import bscomp
    from bscomp.systems.truths import truth_system
    from bscomp.validate import load

    cache = Path(__file__).resolve().parent / ".cache" / "stepped_truths"
    cache.mkdir(parents=True, exist_ok=True)
    truth, _ = truth_system(case, model, nut_joint="point")
    out, rng = [], np.random.default_rng(zlib.crc32(f"{model}/{case}".encode()))
    for v in (0.2, 2.0):
        path = cache / f"{model}_{case}_{v:g}V.csv"
        if not path.exists():
            ss = bscomp.stepped_sine(truth, "amp.u", ["rotor.w", "table.a"], np.geomspace(10.0, 200.0, 14), v,
                                     jit=True)
            ss.to_csv(path, units={"amp.u": "V"})
        d = load(path)
        d.conditions.update(conditions)
        for k in d.H:
            n = d.freqs.size
            d.H[k] = d.H[k] * (1 + 0.01 * (rng.standard_normal(n) + 1j * rng.standard_normal(n)) / np.sqrt(2))
        out.append(d)
    return out


def load_case(model: str, case: str, seed: int | None = None, drive: str = "thesis") -> tuple:
    """``(truth, [FRF data, time data])`` of a bundled truth case, or with ``seed`` of a truth drawn anew
    (:func:`bscomp.systems.truths.generate_case`, written once to ``benchmarks/.cache/truths/<seed>``, another
    drive's to ``benchmarks/.cache/truths/<drive>/<seed>``)."""
    root = resources.files("bscomp.systems") / "data" / "truths" / model / case
    if drive != "thesis" and seed is None:
        raise SystemExit(f"--drive {drive}: its truths are drawn anew, give --seed")
    if seed is not None:
        from bscomp.systems.truths import generate_case

        base = Path(__file__).resolve().parent / ".cache" / "truths"
        base = (base if drive == "thesis" else base / drive) / str(seed)
        root = base / model / case
        if not (root / "truth.json").exists():
            generate_case(case, model, base, seed, drive=drive)
    truth = json.loads((root / "truth.json").read_text())
    return truth, load_all([str(root / "frf.csv"), str(root / "time.csv")])


def hidden_pairs(d, truth) -> list:
    """``(accepted fit, parameter name, hidden value)`` for each accepted effect's main parameters (:data:`MAIN`)."""
    out = []
    for a in d.accepted:
        hidden, names = MAIN.get(a.name, (None, ()))
        for n, tn in names:
            t = truth["hidden"].get(hidden, {}).get(tn)
            if t is not None and n in a.values:
                out.append((a, n, t))
    return out


def keep_channels(data, channels) -> list:
    """The datasets with only ``channels`` of each time series (a drive's own sensors: e.g. ``rotor.phi``,
    ``table.s``, an encoder and a linear scale, without the motor speed and the accelerometer)."""
    import dataclasses

    out = []
    for d in data:
        if hasattr(d, "t"):
            missing = sorted(set(channels) - set(d.outputs))
            if missing:
                raise SystemExit(f"--channels: {missing} not among the time series' {sorted(d.outputs)}")
            d = dataclasses.replace(d, outputs={k: v for k, v in d.outputs.items() if k in channels},
                                    units={k: v for k, v in d.units.items() if k in channels or k in d.inputs})
        out.append(d)
    return out


def run(model: str, case: str, stepped: bool = False, seed: int | None = None, channels=None,
        drive: str = "thesis", extra=()) -> dict:
    from bscomp.systems.truths import drive_overrides

    truth, data = load_case(model, case, seed, drive)
    if stepped:                     # the stepped sines at two amplitudes instead of the small-signal FRF
        data = stepped_frfs(model, case, data[1].conditions) + [data[1]]
    if channels:
        data = keep_channels(data, channels)
    t0 = time.perf_counter()
    cands = resolve_candidates(default_candidates() + list(extra)) if extra else None
    d = diagnose(MODELS[model], data, max_effects=2, overrides=drive_overrides(drive) or None, candidates=cands)
    wall = time.perf_counter() - t0
    stairs = dict(d.staircase)
    recal, final = stairs["re-calibrated"], d.staircase[-1][1]
    params = [f"{a.name}.{n} {a.values[n] / t - 1:+.1%}" for a, n, t in hidden_pairs(d, truth)]
    # named first: with the candidates the data cannot tell apart from it (bscomp.validate.equivalence)
    return {"model": model, "case": case, "seed": truth["seed"],
            "first": " ~ ".join(d.ranked[0].group_names) if d.ranked else "-",
            "runner_up": _runner_up(d), "accepted": [a.name for a in d.accepted], "params": params,
            "recalibrated": recal, "final": final, "values": {k: v for k, (v, _) in d.recalibrated.items()},
            "drop": 1 - final / recal if recal > 0 else 0.0, "wall_s": wall,
            "left": _left(d), "message": d.message}


def _left(d) -> str:
    """What the diagnosis says is left: an effect outside the candidates (error above ``UNEXPLAINED`` x the noise
    floor) and the residual's components periodic in the motor angle (:mod:`bscomp.validate.periodicity`)."""
    rest = d.remainder
    words = ["outside the candidates"] if not rest["within_noise"] and rest["error"] > UNEXPLAINED else []
    words += [f"{o.channel} order {o.order} (p {o.p_value:.1g})" for o in rest["orders"]]
    return ", ".join(words) or "-"


def _runner_up(d) -> str:
    """The best refined candidate outside the first one's group, with the test that tells them apart."""
    if not d.ranked:
        return "-"
    lead = d.ranked[0]
    for r in d.ranked[1:]:
        if r.refined and r.name not in lead.group_names and r.name in lead.compared:
            st = lead.compared[r.name]
            return f"{r.name} (z {st['z']:+.1f}, shared {st['shared']:.2f})"
    return "-"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", choices=list(MODELS), action="append")
    ap.add_argument("--case", choices=CASES + EXTRA, action="append")
    ap.add_argument("--candidate", action="append", default=[], help="a library candidate added to the defaults "
                    "(bscomp.validate.candidates.library; one already among them is tried once)")
    ap.add_argument("--json", help="also write the rows to this JSON file")
    ap.add_argument("--stepped", action="store_true", help="stepped-sine FRFs at 0.2 V and 2 V (stating their "
                    "amplitude) instead of the bundled small-signal FRF, beside the same time series")
    ap.add_argument("--seed", type=int, action="append", help="a truth drawn anew with this seed (generated once, "
                    "cached in benchmarks/.cache/truths) instead of the bundled one; repeat for several")
    ap.add_argument("--channels", help="keep only these time-series channels, comma-separated (e.g. "
                    "rotor.phi,table.s: positions only, an encoder and a linear scale)")
    ap.add_argument("--drive", default="thesis", help="whose truths: 'thesis' (default) or 'other', another drive "
                    "from the same components (bscomp.systems.truths.DRIVES; needs --seed)")
    args = ap.parse_args(argv)
    if args.stepped and args.drive != "thesis":
        raise SystemExit("--stepped uses the thesis drive's truths; leave out --drive")
    channels = args.channels.split(",") if args.channels else None
    rows = []
    print("| model | case | seed | named first | runner-up (Vuong z, shared) | accepted | main parameters vs truth | "
          "error re-calibrated -> final | left | wall |\n|---|---|---:|---|---|---|---|---|---|---:|")
    for model, case, seed in ((m, c, s) for s in args.seed or [None] for m in args.model or list(MODELS)
                              for c in args.case or CASES):
        if args.stepped and case == "delay":        # the truth's delay is applied to its data, not a System
            continue
        r = run(model, case, args.stepped, seed, channels, args.drive, args.candidate)
        rows.append(r)
        print(f"| {model} | {case} | {r['seed']} | {r['first']} | {r['runner_up']} | "
              f"{', '.join(r['accepted']) or 'nothing'} | "
              f"{', '.join(r['params']) or '-'} | {r['recalibrated']:.3g} -> {r['final']:.3g} "
              f"({-r['drop']:+.0%}) | {r['left']} | {r['wall_s']:.0f} s |", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
