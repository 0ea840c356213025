"""Command line: a thin layer over the library (``bscomp demo``, ``bscomp modes``, ``bscomp frf``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _demo(args) -> int:
    from . import flatten, linearize
    from bscomp.systems import small_drive

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    system = small_drive()
    dae = flatten(system)
    print(f"bscomp demo: {system.description}")
    print(f"  flattened: {dae.nx} states {dae.x_names}, inputs {dae.u_names} "
          f"({dae.stats['flatten_s'] * 1e3:.1f} ms)")
    lin = linearize(dae, inputs=["motor.tau"], outputs=["rotor.w", "table.a"])
    ev = np.linalg.eigvals(lin.A)
    order = np.argsort(np.abs(ev))
    print("  modes (from the linearized DAE):")
    print(f"    {'#':>2} {'f_n [Hz]':>10} {'zeta [-]':>9}")
    k = 0
    for i in order:
        if ev[i].imag < 0:
            continue
        wn = abs(ev[i])
        zeta = -ev[i].real / wn if wn > 0 else 0.0
        k += 1
        print(f"    {k:>2} {wn / (2 * np.pi):>10.2f} {zeta:>9.4f}" + ("   (rigid body)" if wn < 1e-3 else ""))
    # J reflected at the motor (thesis Eq 4.2): rotor + screw + table r_g^2
    so = lin.second_order
    r_g = 0.010 / (2 * np.pi)
    J = so.M.diagonal()[0] + so.M.diagonal()[1] + so.M.diagonal()[2] * r_g**2
    print(f"  J reflected at the motor = {J:.4e} kg m^2 (thesis Eq 4.2: 8.55e-3 for the full test bed)")
    f = np.logspace(0, np.log10(2000), 600)
    H = so.frf(f)
    from .plotting import bode_plot
    png = out / "demo_bode.png"
    bode_plot(f, H[:, :, 0], labels=["motor.tau -> rotor.w [rad/s/(N m)]", "motor.tau -> table.a [m/s^2/(N m)]"],
              title="small_drive: open-loop FRF", path=png)
    print(f"  Bode plot written to {png}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bscomp", description="Ballscrew feed drives as acausal components.")
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("demo", help="build a small drive, print its modes, write a Bode plot")
    p.add_argument("--out", default="out", help="folder for figures (default: out)")
    p.set_defaults(func=_demo)
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
