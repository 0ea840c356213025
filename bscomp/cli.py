"""Command line: a thin layer over the library (``bscomp demo``, ``bscomp modes``, ``bscomp frf``,
``bscomp compare``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _demo(args) -> int:
    from bscomp.systems import small_drive

    from . import flatten, linearize
    from .modal import modes

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    system = small_drive()
    dae = flatten(system)
    print(f"bscomp demo: {system.description}")
    print(f"  flattened: {dae.nx} states {dae.x_names}, inputs {dae.u_names} "
          f"({dae.stats['flatten_s'] * 1e3:.1f} ms)")
    lin = linearize(dae, inputs=["motor.tau"], outputs=["rotor.w", "table.a"])
    so = lin.second_order
    md = modes(so)
    print("  modes (undamped K phi = w^2 M phi; damping from the damped poles):")
    print("    " + md.table("rotor.phi").replace("\n", "\n    "))
    # J reflected at the motor (thesis Eq 4.2): the rigid-body modal mass at the motor angle
    J = md.reflected_inertia("rotor.phi")
    print(f"  J reflected at the motor = {J:.4e} kg m^2 (thesis Eq 4.2: 8.55e-3 for the full test bed), "
          f"B = {md.reflected_damping('rotor.phi'):.4g} N m s/rad")
    f = np.logspace(0, np.log10(2000), 600)
    H = so.frf(f)
    from .plotting import bode_plot
    png = out / "demo_bode.png"
    bode_plot(f, H[:, :, 0],
              labels=["motor.tau -> rotor.w [rad/s/(N m)]", "motor.tau -> table.a [m/s^2/(N m)]"],
              title="small_drive: open-loop FRF", path=png)
    print(f"  Bode plot written to {png}")
    if args.no_validation:
        return 0
    return _demo_validation(out)


def _demo_validation(out: Path) -> int:
    """The headline story on the bundled (synthetic) measurements: compare, diagnose, add, compare."""
    from importlib import resources

    from .systems import get
    from .validate.compare import compare
    from .validate.diagnose import diagnose
    from .validate.measurements import load_all
    from .validate.report import write_report

    data_dir = resources.files("bscomp.systems") / "data" / "validation"
    files = [str(data_dir / "frf.csv"), str(data_dir / "time.csv")]
    datasets = load_all(files)
    nominal = get("validation_drive")
    print("\nbscomp demo, part 2: model vs measurements (bundled synthetic test-bed data, "
          "systems/data/validation/README.md)")
    comp = compare(nominal, datasets)
    print("  " + comp.summary().replace("\n", "\n  "))
    print("  diagnosing: re-calibrate uncertain parameters, then rank candidate effects (a few minutes)...",
          flush=True)
    diag = diagnose(nominal, datasets, verbose=True)
    print("  " + diag.table().replace("\n", "\n  "))
    if diag.accepted:
        print("  lines to add to the system file:\n    " + diag.code().replace("\n", "\n    "))
    rep = out / "validation"
    path = write_report([comp, diag], rep, title="bscomp demo: the nominal drive meets the measurements")
    diag.to_json(rep / "diagnosis.json")
    print(f"  report written to {path}")
    return 0


def _parse_set(items) -> dict:
    from .errors import ParameterError

    out = {}
    for item in items or []:
        name, eq, value = item.partition("=")
        if not eq or not name.strip():
            raise ParameterError(f"--set expects NAME=VALUE (e.g. coupling.c=45940), got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            out[name.strip()] = value.strip()
    return out


def _build(args):
    """(system, overrides) from SYSTEM, --set and --position (the system's ``position_parameter``)."""
    from .sweep import build_system, position_parameter

    overrides = _parse_set(args.set)
    if args.position is not None:
        base = build_system(args.system, overrides)
        overrides[position_parameter(base)] = float(args.position)
    return build_system(args.system, overrides)


def _modes(args) -> int:
    from .modal import modes

    system = _build(args)
    md = modes(system, inputs=args.input or None, outputs=args.output or None, n=args.n, fmax=args.fmax)
    if args.json:
        print(md.to_json())
    else:
        print(f"{system.name}: {len(md)} modes over {len(md.coordinates)} coordinates ({md.method}; damping: "
              f"{md.damping_method})")
        print(md.table(args.reference) if args.reference else md.table())
        for note in md.notes:
            print(f"note: {note}")
    if args.csv:
        md.to_csv(args.csv)
    if args.png:
        md.plot(args.png)
    return 0


def _frf(args) -> int:
    from .frf import frf

    system = _build(args)
    res = frf(system, args.input, args.output, fmin=args.fmin, fmax=args.fmax, n=args.n)
    if args.csv:
        res.to_csv(args.csv)
    if args.png:
        res.plot(args.png)
    if not args.csv and not args.png:
        res.to_csv(sys.stdout)
    else:
        h = np.abs(res.response())
        k = int(np.argmax(h))
        print(f"{system.name}: {args.input} -> {args.output}, {res.freqs.size} points "
              f"{args.fmin:g}-{args.fmax:g} Hz; largest |H| = {h[k]:.4g} at {res.freqs[k]:.4g} Hz")
        for f_ in (args.csv, args.png):
            if f_:
                print(f"  written {f_}")
    return 0


def _compare(args) -> int:
    from .validate import compare, load_all, write_report

    build = args.system
    overrides = _parse_set(args.set)
    datasets = load_all(args.data)
    comp = compare(build, datasets, params=overrides or None)
    if args.json:
        print(comp.to_json())
    else:
        print(comp.summary())
    if args.report:
        path = write_report(comp, args.report)
        print(f"report written to {path}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _diagnose(args) -> int:
    """``bscomp diagnose SYSTEM DATA...``: re-calibrate, rank candidate effects, accept the ones that pay."""
    from .validate.diagnose import diagnose
    from .validate.measurements import load_all

    system = _build(args)
    datasets = load_all(args.data)
    uncertain = None
    if args.uncertain:
        uncertain = [u for item in args.uncertain for u in item.split(",") if u]
    diag = diagnose(system, datasets, uncertain=uncertain, max_effects=args.max_effects, verbose=args.verbose)
    if args.json:
        print(diag.to_json())
    else:
        print(diag.table())
        if args.apply:
            print("\nlines to add to the system file:\n" + diag.code())
    if args.report:
        out = Path(args.report)
        out.mkdir(parents=True, exist_ok=True)
        paths = diag.plot(out)
        diag.to_json(out / "diagnosis.json")
        (out / "diagnosis.txt").write_text(diag.table() + "\n\n" + diag.code() + "\n")
        if not args.json:
            print(f"report written to {out} ({', '.join(p.name for p in paths)}, diagnosis.json, diagnosis.txt)")
    if args.apply and diag.accepted:
        try:
            from .validate.residuals import cost

            before = cost(system, datasets)
            after = cost(diag.apply(system), datasets)
            if not args.json:
                print(f"compare: error {before:.4g} -> {after:.4g} on the updated system")
        except Exception as exc:  # the fast engine's numbers above stand; report the simulator problem
            print(f"bscomp: note: re-running compare on the updated system failed ({type(exc).__name__}: "
                  f"{str(exc)[:200]})", file=sys.stderr)
    return 0


def _add_system_args(p):
    p.add_argument("system", help="a system registered in bscomp.systems (e.g. small_drive) or a .py file "
                                  "defining build()")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter override (repeatable)")
    p.add_argument("--position", type=float, metavar="X",
                   help="nut position: sets the system's position_parameter (declared by its build function)")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bscomp",
                                     description="Ballscrew feed drives as acausal components.")
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("demo", help="modes and Bode plot of a small drive, then the validation story on "
                                    "bundled data (compare, diagnose, report)")
    p.add_argument("--no-validation", action="store_true", help="only the modes and Bode plot (seconds)")
    p.add_argument("--out", default="out", help="folder for figures (default: out)")
    p.set_defaults(func=_demo)

    p = sub.add_parser("modes", help="natural frequencies, damping, modal masses and shapes")
    _add_system_args(p)
    p.add_argument("--input", action="append", help="input for the participation factors (repeatable)")
    p.add_argument("--output", action="append", help="output for the participation factors (repeatable)")
    p.add_argument("--n", type=int, help="keep the n lowest modes")
    p.add_argument("--fmax", type=float, help="keep the modes up to FMAX [Hz]")
    p.add_argument("--reference", help="coordinate at which modal masses are reported (e.g. rotor.phi)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--csv", help="write the mode table and shapes to a CSV file")
    p.add_argument("--png", help="write a mode-shape plot")
    p.set_defaults(func=_modes)

    p = sub.add_parser("frf", help="frequency response between an input and an output")
    _add_system_args(p)
    p.add_argument("--input", required=True, help="input name, e.g. motor.tau")
    p.add_argument("--output", required=True, help="output name, e.g. rotor.w")
    p.add_argument("--fmin", type=float, default=1.0, help="lowest frequency [Hz] (default 1)")
    p.add_argument("--fmax", type=float, default=1000.0, help="highest frequency [Hz] (default 1000)")
    p.add_argument("--n", type=int, default=500, help="number of log-spaced frequencies (default 500)")
    p.add_argument("--csv", help="write the FRF to a CSV file (default: CSV on stdout when no --png)")
    p.add_argument("--png", help="write a Bode plot")
    p.set_defaults(func=_frf)

    p = sub.add_parser("compare", help="compare a model with measured FRFs / time series: where it fails")
    p.add_argument("system", help="a system registered in bscomp.systems (e.g. small_drive) or a .py file "
                                  "defining build(); each file's conditions are passed to the build")
    p.add_argument("data", nargs="+", help="measurement CSV files (FRF or time series, see docs/measurements.md)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter override (repeatable)")
    p.add_argument("--report", metavar="DIR", help="write an HTML report with figures to DIR")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.set_defaults(func=_compare)

    p = sub.add_parser("diagnose", help="find the physical effects a model is missing, from measurements")
    _add_system_args(p)
    p.add_argument("data", nargs="+", help="measurement files (FRF or time-series CSV, see docs/measurements.md)")
    p.add_argument("--uncertain", action="append", metavar="NAME[,NAME]",
                   help="parameters to re-calibrate first (default: the system's own list)")
    p.add_argument("--max-effects", type=int, default=3, help="most effects accepted one after another")
    p.add_argument("--apply", action="store_true", help="print the system-file lines and the error after applying")
    p.add_argument("--report", metavar="DIR", help="write the staircase figure, JSON and text to DIR")
    p.add_argument("--json", action="store_true", help="print the diagnosis as JSON")
    p.add_argument("--verbose", action="store_true", help="print progress")
    p.set_defaults(func=_diagnose)

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except Exception as exc:  # report named errors cleanly
        from .errors import BscompError
        if isinstance(exc, BscompError):
            print(f"bscomp: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 2
        raise


if __name__ == "__main__":
    sys.exit(main())
