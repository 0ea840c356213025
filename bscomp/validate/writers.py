"""Writers of the measurement CSV format read by :mod:`bscomp.validate.readers` (``docs/measurements.md``):
``# key: value`` metadata lines (kind, source, conditions, units), a header row, one row per sample, values
in SI with full precision (``repr`` of the float), so a written file reads back bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bscomp.files import atomic_write
from bscomp.validate.datasets import FrfData, TimeData

__all__ = ["write_frf_csv", "write_time_csv"]


def _fmt(x):
    return repr(float(x))


def _write(path, lines, M):
    """The metadata/header ``lines`` then one row per line of ``M``, through a temporary file renamed into place
    when complete (an error while formatting leaves an existing file intact)."""
    with atomic_write(path, newline="\n") as fh:
        for line in lines:
            fh.write(line + "\n")
        for row in M:
            fh.write(",".join(_fmt(v) for v in row) + "\n")


def _meta_lines(kind, source, conditions):
    out = [f"# kind: {kind}"]
    if source:
        out.append(f"# source: {source}")
    for k, v in (conditions or {}).items():
        out.append(f"# condition {k}: {v}")
    return out


def write_frf_csv(data: FrfData, path, form: str = "reim") -> Path:
    """Write ``data`` as CSV with ``# key: value`` metadata (``form``: ``"reim"`` or ``"magphase"``)."""
    if form not in ("reim", "magphase"):
        raise ValueError(f"form must be 'reim' or 'magphase', got {form!r}")
    path = Path(path)
    lines = _meta_lines("frf", data.source, data.conditions)
    lines += [f"# excitation {k}: {v!r}" for k, v in data.excitation.items()]
    head = ["f"]
    cols = [np.asarray(data.freqs, float)]
    for (inp, out), h in data.H.items():
        p = f"{out}/{inp}"
        lines.append(f"# unit {p}: {data.units.get((inp, out), '1')}")
        if form == "reim":
            head += [f"re({p})", f"im({p})"]
            cols += [h.real, h.imag]
        else:
            head += [f"mag({p})", f"phase_deg({p})"]
            cols += [np.abs(h), np.degrees(np.angle(h))]
        g = data.coherence.get((inp, out))
        if g is not None:
            head.append(f"coh({p})")
            cols.append(np.asarray(g, float))
    lines.append(",".join(head))
    _write(path, lines, np.column_stack(cols))
    return path



def write_time_csv(data: TimeData, path) -> Path:
    """Write ``data`` as CSV with ``# input``/``# output`` unit lines and conditions."""
    path = Path(path)
    lines = _meta_lines("time", data.source, data.conditions)
    lines.append("# unit t: s")
    for n in data.inputs:
        lines.append(f"# input {n}: {data.units.get(n, '1')}")
    for n in data.outputs:
        lines.append(f"# output {n}: {data.units.get(n, '1')}")
    names = list(data.inputs) + list(data.outputs)
    lines.append(",".join(["t"] + names))
    M = np.column_stack([data.t] + [data.inputs[n] for n in data.inputs] + [data.outputs[n] for n in data.outputs])
    _write(path, lines, M)
    return path

