"""Command line: a thin layer over the library (``bscomp demo``, ``systems``, ``modes``, ``frf``,
``compare``, ``diagnose``, ``fmu``).

One error boundary (:func:`main`): every failure is one line ``bscomp <verb>: <ErrorName>: what is wrong --
how to fix it`` on stderr (with ``--json``: a JSON object ``{"error", "type", "hint"}`` on stdout), exit
code 2 for a user mistake and 1 for a solver that ran and failed; ``--debug`` shows the traceback.
Arguments are checked before any computation, and outputs are staged so that a failing second output
leaves the first unchanged (:mod:`bscomp.files`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bscomp import cli_checks as ck
from bscomp.cli_demo import demo as _demo

_parse_set = ck.parse_set           # the name other modules and tests import


def _build(args):
    """(system, overrides) from SYSTEM, --set and --position (the system's ``position_parameter``)."""
    from bscomp.linear.sweeps import build_system, position_parameter

    overrides = _parse_set(args.set)
    with ck.build_guard(args.system):
        if args.position is not None:
            base = ck.check_system(build_system(args.system, overrides), args.system)
            overrides[position_parameter(base)] = float(args.position)
        return ck.check_system(build_system(args.system, overrides), args.system)


FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def _outputs(args, csv_suffixes=(".csv",)):
    """Check ``--csv``/``--png`` paths before computing (folder exists, not a directory, known suffix)."""
    from bscomp.files import writable_path

    if getattr(args, "csv", None):
        writable_path(args.csv, "--csv file", csv_suffixes)
    if getattr(args, "png", None):
        writable_path(args.png, "--png file", FIGURE_SUFFIXES)


def _modes(args) -> int:
    from bscomp.files import staged
    from bscomp.linear.modal import modes

    _outputs(args)
    system = _build(args)
    md = modes(system, inputs=args.input or None, outputs=args.output or None, n=args.n, fmax=args.fmax)
    table = ck.reference_table(md, args.reference)   # an unknown --reference fails before anything is written
    with staged() as st:       # both files or neither
        if args.csv:
            md.to_csv(st.path(args.csv))
        if args.png:
            md.plot(st.path(args.png))
    if args.json:
        print(md.to_json())
    else:
        print(f"{system.name}: {len(md)} modes over {len(md.coordinates)} coordinates ({md.method}; damping: "
              f"{md.damping_method})")
        print(table)
        for note in md.notes:
            print(f"note: {note}")
    return 0


def _frf(args) -> int:
    from bscomp.errors import BscompError, UsageError
    from bscomp.files import staged
    from bscomp.linear.response import frf

    if args.fmax <= args.fmin:
        raise UsageError(f"--fmax {args.fmax:g} Hz must be above --fmin {args.fmin:g} Hz",
                         hint="give a frequency band, e.g. --fmin 1 --fmax 1000")
    if args.method != "modal" and not args.amplitude:
        raise UsageError(f"--method {args.method} applies to an FRF at an amplitude", hint="add --amplitude A")
    if args.harmonics != 1 and args.method != "describing":
        raise UsageError("--harmonics applies to --method describing", hint="add --amplitude A --method describing")
    _outputs(args)
    system, n = _build(args), args.n or (24 if args.amplitude and args.method != "describing" else 500)
    if args.amplitude:                  # at a real amplitude: friction and backlash as they act there
        from bscomp.simulation import describing_frf, stepped_sine
        freqs = np.geomspace(args.fmin, args.fmax, n)
        try:
            res = (describing_frf(system, args.input, args.output, freqs, args.amplitude, harmonics=args.harmonics)
                   if args.method == "describing" else
                   stepped_sine(system, args.input, args.output, freqs, args.amplitude, method=args.method,
                                jit=args.jit))
        except BscompError as exc:
            if "(use bscomp.frf)" not in str(exc):
                raise
            raise UsageError(f"--amplitude: '{system.name}' has no friction or backlash element, so its FRF is the "
                             "same at every amplitude", hint="drop --amplitude and --method for its FRF") from None
    else:
        res = frf(system, args.input, args.output, fmin=args.fmin, fmax=args.fmax, n=n)
    with staged() as st:
        if args.csv:
            res.to_csv(st.path(args.csv))
        if args.png:
            res.plot(st.path(args.png))
    if not args.csv and not args.png:
        res.to_csv(sys.stdout)
    else:
        k = int(np.argmax(h := np.abs(res.response())))
        print(f"{system.name}: {args.input} -> {args.output}, {res.freqs.size} points "
              f"{args.fmin:g}-{args.fmax:g} Hz; largest |H| = {h[k]:.4g} at {res.freqs[k]:.4g} Hz")
        if args.amplitude:
            print(f"  {res.summary()}")
        for f_ in (args.csv, args.png):
            if f_:
                print(f"  written {f_}")
    return 0


def _model_and_parameters(system: str, overrides: dict):
    """``(model, build arguments, dotted parameters)`` of ``--set`` values: the build arguments (no dot, as modes
    and diagnose take them) go into the model (a ModelSpec), the parameters to compare's ``params``."""
    from bscomp.model import ModelSpec, split_overrides

    plain, dotted = split_overrides(overrides)
    return (ModelSpec(system, plain) if plain else system), plain, dotted


def _compare(args) -> int:
    from bscomp.validate import compare, load_all, write_report

    if args.report:
        ck.output_folder(args.report, "--report")
    overrides = _parse_set(args.set)
    build, plain, dotted = _model_and_parameters(args.system, overrides)
    ck.check_file_system(args.system, plain)
    datasets = load_all(args.data)
    with ck.build_guard(args.system):
        comp = compare(build, datasets, params=dotted or None)
    if args.json:
        print(comp.to_json())
    else:
        print(comp.summary())
    if args.report:
        from bscomp.files import atomic_dir

        with atomic_dir(args.report) as tmp:      # a report is complete or absent
            write_report(comp, tmp)
        print(f"report written to {Path(args.report) / 'index.html'}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _diagnose(args) -> int:
    """``bscomp diagnose SYSTEM DATA...``: re-calibrate, fit candidate effects, accept the confirmed ones."""
    from bscomp.validate.diagnostics import diagnose
    from bscomp.validate.measurements import load_all

    uncertain = ck.parse_uncertain(args.uncertain)     # the formats and the folder first, then the model
    candidates = None
    if args.candidate:                                 # candidates beside the defaults, names checked now
        from bscomp.validate.arguments import resolve_candidates
        from bscomp.validate.candidates import default_candidates

        candidates = resolve_candidates(default_candidates() + list(args.candidate))
    if args.report:
        ck.output_folder(args.report, "--report")
    overrides = _parse_set(args.set)
    if args.position is not None:
        from bscomp.linear.sweeps import build_system, position_parameter

        with ck.build_guard(args.system):
            system = ck.check_system(build_system(args.system, overrides), args.system)
        overrides[position_parameter(system)] = float(args.position)
    else:
        ck.check_file_system(args.system, overrides)
    datasets = load_all(args.data)
    with ck.build_guard(args.system):
        diag = diagnose(args.system, datasets, uncertain=uncertain, max_effects=args.max_effects,
                        candidates=candidates, verbose=args.verbose, overrides=overrides or None,
                        progress=None if not args.json else False)
    if args.json:
        print(diag.to_json())
    else:
        print(diag.table())
        if args.apply:
            print("\nlines to add to the system file:\n" + diag.code())
    if args.report:
        _diagnosis_report(args, datasets, overrides, diag)
    return 0


def _diagnosis_report(args, datasets, overrides: dict, diag) -> None:
    """``diagnose --report DIR``: an HTML report -- the model compared with the data, the diagnosis, and (when it
    found effects) the model with them compared again at every dataset's conditions -- with diagnosis.json and
    diagnosis.txt; complete or absent."""
    from bscomp.files import atomic_dir
    from bscomp.validate import compare, write_report

    build, _, dotted = _model_and_parameters(args.system, overrides)
    with ck.build_guard(args.system):
        items = [compare(build, datasets, params=dotted or None), diag]
        if diag.accepted:                 # the user's --set values, except those the diagnosis re-calibrated
            kept = {k: v for k, v in dotted.items() if k not in diag.recalibrated}
            items.append(compare(diag.updated(build), datasets, params=kept or None))
    out = Path(args.report)
    with atomic_dir(out) as tmp:
        write_report(items, tmp, title=f"bscomp diagnose: {args.system}")
        diag.to_json(tmp / "diagnosis.json")
        (tmp / "diagnosis.txt").write_text(diag.table() + "\n\n" + diag.code() + "\n")
    if not args.json:
        print(f"report written to {out / 'index.html'} (the model compared with the data, the diagnosis"
              + (", the model with the effects found compared again" if diag.accepted else "")
              + "; diagnosis.json, diagnosis.txt)")


def _systems(args) -> int:
    """``bscomp systems``: the registered drives with their one-line descriptions."""
    from bscomp import systems

    rows = systems.available() if hasattr(systems, "available") else {
        name: ((fn.__doc__ or "").strip().splitlines() or [""])[0] for name, fn in systems.REGISTRY.items()}
    if args.json:
        import json

        print(json.dumps(rows, indent=2))
        return 0
    width = max(map(len, rows))
    for name, doc in rows.items():
        print(f"{name:<{width}}  {doc}")
    print("\n(or a path to a .py file that defines build() returning a bscomp.System)")
    return 0


def _fmu(args) -> int:
    """``bscomp fmu SYSTEM -o drive.fmu``: an FMI 3.0 model-exchange FMU of the drive (docs/fmu.md)."""
    from bscomp.files import writable_path
    from bscomp.fmu import export_fmu

    writable_path(args.output_file, "-o file", (".fmu",))
    ck.check_file_system(args.system, _parse_set(args.set))
    params = args.parameter or ()
    params = "all" if list(params) == ["all"] else params
    with ck.build_guard(args.system):
        path = export_fmu(args.system, args.output_file, inputs=args.input or None, outputs=args.output or None,
                          parameters=params, overrides=_parse_set(args.set) or None, nominal=args.nominal)
    print(f"written {path}")
    return 0


def _simulate(args) -> int:
    """``bscomp simulate SYSTEM --input NAME=SIGNAL --t-end T``: a time response (any method of
    :func:`bscomp.simulation.simulate`), summarised with units; CSV / figure on request."""
    import json

    from bscomp.errors import UsageError
    from bscomp.files import staged
    from bscomp.kernel.flattening import flatten
    from bscomp.kernel.signal_meta import measured_outputs, unit_of, unit_suffix
    from bscomp.simulation.dispatch import simulate
    from bscomp.simulation.signals import SPELLINGS, parse_signal

    inputs = {}
    for item in args.input or []:
        name, eq, spec = item.partition("=")
        if not eq or not name.strip():
            raise UsageError(f"--input expects NAME=SIGNAL (e.g. amp.u=square:2.125:5), got {item!r}",
                             hint=f"SIGNAL is {SPELLINGS}")
        inputs[name.strip()] = parse_signal(spec, f"--input {name.strip()}")
    n = ck.steps(args.t_end, args.dt)       # a whole number of steps: the run ends at --t-end
    _outputs(args)
    dae = flatten(_build(args))
    outputs = args.output or measured_outputs(dae)
    t = np.linspace(0.0, n * args.dt, n + 1)
    res = simulate(dae, t, inputs=inputs, outputs=outputs, method=args.method, rtol=args.rtol, atol=args.atol,
                   jit=args.jit)
    with staged() as st:       # both files or neither
        if args.csv:
            res.to_csv(st.path(args.csv))
        if args.png:
            res.plot(path=st.path(args.png), title=f"{dae.name}: {args.method}")
    summary = {o: {"unit": unit_of(dae, o), "min": float(np.min(res[o])) + 0.0, "max": float(np.max(res[o])) + 0.0,
                   "final": float(res[o][-1]) + 0.0} for o in outputs}         # + 0.0: no "-0" printed
    wall, rtf = res.stats.get("wall_s"), res.stats.get("real_time_factor")
    if args.json:
        print(json.dumps({"system": dae.name, "method": args.method, "t_end": float(t[-1]), "dt": args.dt,
                          "wall_s": wall, "real_time_factor": None if rtf is None else float(rtf),
                          "outputs": summary, "nut_travel": res.stats.get("nut_travel", {})}, indent=1))
        return 0
    speed = f"; {wall:.3g} s wall, {float(rtf):.3g}x real time" if wall and rtf else ""
    print(f"{dae.name}: method {args.method!r}, {t[-1]:g} s in {n} steps of {args.dt:g} s{speed}")
    width = max(len(o) for o in outputs)
    for o, v in summary.items():
        u = unit_suffix(v["unit"])
        print(f"  {o:<{width}}  min {v['min']:11.4g}{u}  max {v['max']:11.4g}{u}  final {v['final']:11.4g}{u}")
    for path, z in res.stats.get("nut_travel", {}).items():
        print(f"  nut of {path} between z = {z['z_min']:.6g} and {z['z_max']:.6g} m (its screw: {z['screw'][0]:.6g} to "
              f"{z['screw'][1]:.6g} m)")
    for f_ in (args.csv, args.png):
        if f_:
            print(f"  written {f_}")
    return 0


def _add_system_args(p):
    p.add_argument("system", help="a system registered in bscomp.systems (see `bscomp systems`) or a .py file "
                                  "defining build()")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter override (repeatable)")
    p.add_argument("--position", type=ck.number("--position"), metavar="X",
                   help="nut position: sets the system's position_parameter (declared by its build function)")


class _Parser(argparse.ArgumentParser):
    """argparse that raises :class:`~bscomp.errors.UsageError` instead of printing usage and exiting."""

    def error(self, message):
        from bscomp.errors import UsageError

        head, sep, rest = message.partition(": ")
        if sep and head.startswith("argument ") and head.split()[-1].split("/")[0] in rest:
            message = rest                       # "argument --n: --n must be > 0" -> "--n must be > 0"
        elif head == "argument cmd":
            message = rest
        raise UsageError(message or "bad arguments", hint=f"see `{self.prog} --help`")


def _parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", help="show the full traceback on an error")
    parser = _Parser(prog="bscomp", description="Ballscrew feed drives as acausal components.", parents=[common])
    sub = parser.add_subparsers(dest="cmd", required=True, parser_class=_Parser)
    p = sub.add_parser("demo", parents=[common], help="modes and Bode plot of the thesis test bed, then the "
                       "validation story on bundled measurements (compare, diagnose, report)")
    p.add_argument("--no-validation", action="store_true", help="only the modes and Bode plot (seconds)")
    p.add_argument("--out", default="out", help="folder for figures (default: out)")
    p.set_defaults(func=_demo)

    p = sub.add_parser("systems", parents=[common], help="list the registered drives")
    p.add_argument("--json", action="store_true", help="print the list as JSON")
    p.set_defaults(func=_systems)

    p = sub.add_parser("modes", parents=[common], help="natural frequencies, damping, modal masses and shapes")
    _add_system_args(p)
    p.add_argument("--input", action="append", help="input for the participation factors (repeatable)")
    p.add_argument("--output", action="append", help="output for the participation factors (repeatable)")
    p.add_argument("--n", type=ck.number("--n", 0, 100000, integer=True), help="keep the n lowest modes (>= 1)")
    p.add_argument("--fmax", type=ck.number("--fmax", 0), help="keep the modes up to FMAX [Hz]")
    p.add_argument("--reference", help="coordinate at which modal masses are reported (e.g. rotor.phi)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--csv", help="write the mode table and shapes to a CSV file")
    p.add_argument("--png", help="write a mode-shape plot (.png, .pdf or .svg)")
    p.set_defaults(func=_modes)

    p = sub.add_parser("frf", parents=[common], help="frequency response between an input and an output")
    _add_system_args(p)
    p.add_argument("--input", required=True, help="input name, e.g. motor.tau")
    p.add_argument("--output", required=True, help="output name, e.g. rotor.w")
    p.add_argument("--fmin", type=ck.number("--fmin", 0), default=1.0, help="lowest frequency [Hz] (default 1)")
    p.add_argument("--fmax", type=ck.number("--fmax", 0), default=1000.0, help="highest frequency [Hz] (default 1000)")
    p.add_argument("--n", type=ck.number("--n", 1, 10 ** 6, integer=True, open_low=False), default=None,
                   help="number of log-spaced frequencies (default 500; 24 with --amplitude)")
    p.add_argument("--amplitude", type=ck.number("--amplitude", 0),
                   help="the FRF at a sine of this amplitude (the input's unit), friction and backlash acting as they "
                        "do there: a stepped-sine test by simulation (default: the FRF linearized at rest)")
    p.add_argument("--method", choices=["modal", "idas", "describing"], default="modal",
                   help="--amplitude: the stepped sine's simulation method (default modal), or 'describing': one "
                        "harmonic by the describing function (milliseconds per frequency)")
    p.add_argument("--harmonics", type=ck.number("--harmonics", 1, 16, integer=True, open_low=False), default=1,
                   help="--method describing: odd harmonics balanced (orders 1, 3, .., 2N-1; default 1)")
    p.add_argument("--jit", action="store_true", help="--amplitude: compile the modal kernels to C (needs gcc)")
    p.add_argument("--csv", help="write the FRF to a CSV file (default: CSV on stdout when no --png)")
    p.add_argument("--png", help="write a Bode plot (.png, .pdf or .svg)")
    p.set_defaults(func=_frf)

    p = sub.add_parser("compare", parents=[common],
                       help="compare a model with measured FRFs / time series: where it fails")
    p.add_argument("system", help="a system registered in bscomp.systems (see `bscomp systems`) or a .py file "
                                  "defining build(); each file's conditions are passed to the build")
    p.add_argument("data", nargs="+", help="measurement CSV files (FRF or time series, see docs/measurements.md)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="parameter override or build argument (repeatable; a file's '# condition' of the same "
                        "build argument wins)")
    p.add_argument("--report", metavar="DIR", help="write an HTML report with figures to DIR")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.set_defaults(func=_compare)

    p = sub.add_parser("diagnose", parents=[common],
                       help="find the physical effects a model is missing, from measurements")
    _add_system_args(p)
    p.add_argument("data", nargs="+", help="measurement files (FRF or time-series CSV, see docs/measurements.md)")
    p.add_argument("--uncertain", action="append", metavar="NAME[=SPREAD][,...]",
                   help="parameters to re-calibrate first, each with its relative spread (default 0.2); default: "
                        "the drive's declared uncertain parameters")
    p.add_argument("--max-effects", type=ck.number("--max-effects", 0, 20, integer=True, open_low=False), default=3,
                   help="most effects accepted one after another")
    p.add_argument("--candidate", action="append", metavar="NAME",
                   help="a candidate effect of the library tried beside the defaults (repeatable; names already among "
                        "them are tried once -- every library candidate is a default today, rotor_friction since "
                        "2026-12-07)")
    p.add_argument("--apply", action="store_true", help="print the lines to add to the system file")
    p.add_argument("--report", metavar="DIR", help="write an HTML report to DIR: the model compared with the data, the "
                   "diagnosis (staircase, candidates), the model with the effects found compared again; JSON, text")
    p.add_argument("--json", action="store_true", help="print the diagnosis as JSON")
    p.add_argument("--verbose", action="store_true", help="print each round's fits (debug lines)")
    p.set_defaults(func=_diagnose)

    p = sub.add_parser("simulate", parents=[common],
                       help="time response to test signals (IDAS, fixed-step, exact ZOH, split or modal)")
    _add_system_args(p)
    p.add_argument("--input", action="append", metavar="NAME=SIGNAL",
                   help="input signal (repeatable): a number, step:A[:T0], square:A:F, sine:A:F or ramp:RATE[:T0], "
                        "e.g. amp.u=square:2.125:5 (the thesis's Ch 5 run); inputs not given are 0")
    p.add_argument("--output", action="append", help="observable to record (repeatable; default: the drive's "
                                                     "measured outputs)")
    p.add_argument("--t-end", type=ck.number("--t-end", 0), default=0.6, help="simulated time [s] (default 0.6)")
    p.add_argument("--dt", type=ck.number("--dt", 0), default=1e-4, help="output step [s] (default 1e-4)")
    p.add_argument("--method", choices=("idas", "fixed", "lti", "split", "modal"), default="idas",
                   help="integrator (default idas; modal: the fast exact-linear path for friction, backlash and a "
                        "moving nut, docs/nonlinear.md)")
    p.add_argument("--jit", action="store_true", help="compile the step to C (fixed, modal; cached on disk)")
    p.add_argument("--rtol", type=ck.number("--rtol", 0), default=1e-6, help="IDAS relative tolerance (default 1e-6)")
    p.add_argument("--atol", type=ck.number("--atol", 0), default=1e-9, help="IDAS absolute tolerance (default 1e-9)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--csv", help="write t and the outputs to a CSV file")
    p.add_argument("--png", help="write a time plot (.png, .pdf or .svg)")
    p.set_defaults(func=_simulate)

    p = sub.add_parser("fmu", parents=[common], help="export the drive as an FMI 3.0 model-exchange FMU (Simulink, "
                                                      "OpenModelica, FMPy; needs gcc)")
    p.add_argument("system", help="a system registered in bscomp.systems or a .py file defining build()")
    p.add_argument("-o", "--output-file", required=True, metavar="FILE.fmu", help="the FMU to write")
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="parameter or build override fixed in the FMU (repeatable)")
    p.add_argument("--parameter", action="append", metavar="NAME",
                   help="parameter exposed as a tunable FMU parameter (repeatable; 'all': every non-structural one)")
    p.add_argument("--input", action="append", help="input exposed (repeatable; default all)")
    p.add_argument("--output", action="append", help="output exposed (repeatable; default the measured outputs)")
    p.add_argument("--nominal", type=ck.number("--nominal", 0), metavar="VALUE",
                   help="nominal of every state, which importers scale their absolute tolerance by (default 1e-3 = "
                        "atol/rtol of bscomp.simulate's defaults)")
    p.set_defaults(func=_fmu)
    return parser


# ---- the error boundary ----------------------------------------------------------------------------------
_HINTS = {
    "FileNotFoundError": "check the path",
    "IsADirectoryError": "give a file, not a folder",
    "PermissionError": "choose a writable location",
    "OSError": "check the path and free disk space",
    "MemoryError": "use a coarser model or fewer points",
}


def _describe(exc: BaseException) -> tuple[str, str, str, int]:
    """(type name, message, hint, exit code) of any exception, for the one-line report."""
    from bscomp.errors import BscompError

    name = type(exc).__name__
    if isinstance(exc, BscompError):
        return name, str(exc), exc.hint or "", exc.exit_code
    if isinstance(exc, OSError):
        where = f" {exc.filename!r}" if getattr(exc, "filename", None) else ""
        return name, f"{exc.strerror or exc}{where}", _HINTS.get(name, _HINTS["OSError"]), 2
    if isinstance(exc, (ValueError, TypeError, KeyError, ArithmeticError, MemoryError, RecursionError)):
        msg = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
        return name, msg or repr(exc), _HINTS.get(name, "check the arguments (rerun with --debug for details)"), 2
    return name, str(exc) or repr(exc), "this is a bug in bscomp: rerun with --debug and report the traceback", 2


def one_line_warning(verb: str):
    """A ``warnings.formatwarning`` that prints a warning as one line, like the errors:
    ``bscomp <verb>: warning: <Category>: <message>`` (no file, line or source)."""
    def fmt(message, category, filename, lineno, line=None):
        return f"bscomp{' ' + verb if verb else ''}: warning: {category.__name__}: {' '.join(str(message).split())}\n"
    return fmt


def _run_json(args, verb: str) -> int:
    """A command with ``--json``: its warnings go to stderr as one line each *and* into the printed JSON object
    (``"warnings": [{"type", "message"}]``), so a script reading stdout sees them too."""
    import contextlib
    import io
    import json
    import warnings

    buf = io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(buf):
        code = args.func(args)
    with warnings.catch_warnings():           # re-issued: still Python warnings that filters and recorders see
        warnings.formatwarning = one_line_warning(verb)
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    text = buf.getvalue()
    if caught:
        try:
            obj = json.loads(text)
        except ValueError:
            obj = None
        if isinstance(obj, dict):
            obj["warnings"] = [{"type": w.category.__name__, "message": " ".join(str(w.message).split())}
                               for w in caught]
            text = json.dumps(obj, indent=1) + "\n"
    sys.stdout.write(text)
    return code


def main(argv=None) -> int:
    """Run one command; every failure is one line (or a JSON object with ``--json``), see the module doc."""
    import warnings

    argv = sys.argv[1:] if argv is None else list(argv)
    as_json, debug = "--json" in argv, "--debug" in argv
    verb = next((a for a in argv if not a.startswith("-")), "")

    args = None
    fmt = warnings.formatwarning              # put back after the run: a caller's later warnings keep their format
    try:
        with ck.sigterm_as_interrupt():         # SIGTERM like Ctrl-C: the with-blocks remove their temporary files
            args = _parser().parse_args(argv)
            verb = args.cmd
            if as_json and not debug:
                return _run_json(args, verb)
            with warnings.catch_warnings():
                if not debug:
                    warnings.formatwarning = one_line_warning(verb)   # still a Python warning: filters see it
                return args.func(args)
    except KeyboardInterrupt as exc:
        term = isinstance(exc, ck.Terminated)
        print(f"bscomp {verb}: {'terminated' if term else 'interrupted'}".replace("  ", " "), file=sys.stderr)
        return 143 if term else 130
    except SystemExit as exc:
        if args is None or debug:            # --help, or a traceback asked for
            raise
        return _report(_exit_error(exc, args), verb, as_json)
    except BaseException as exc:
        if debug:
            raise
        return _report(exc, verb, as_json)
    finally:
        warnings.formatwarning = fmt


def _exit_error(exc: SystemExit, args):
    """A ``sys.exit()`` in user code (a system file's build()) as a named error."""
    from bscomp.errors import ModelDefinitionError

    src = getattr(args, "system", None)
    where = f"system file {src}" if src and str(src).endswith(".py") else "user code"
    return ModelDefinitionError(f"{where} called sys.exit({exc.code!r}) while bscomp {args.cmd} ran",
                                hint="build() must return a bscomp.System; raise an exception to report a problem")


def _report(exc: BaseException, verb: str, as_json: bool) -> int:
    """Print the one line (or JSON object) of an error; its exit code."""
    import json

    name, msg, hint, code = _describe(exc)
    msg = " ".join(msg.split())
    if as_json:
        print(json.dumps({"error": msg, "type": name, "hint": hint}))
    else:
        print(f"bscomp{' ' + verb if verb else ''}: {name}: {msg}" + (f" -- {hint}" if hint else ""), file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
