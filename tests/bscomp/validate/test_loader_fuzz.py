"""Property-based fuzzing of the measurement loader (hypothesis): whatever the file, sidecar and units, the
loader either returns data that are finite and monotonic or raises MeasurementFileError -- nothing else
escapes. A few thousand examples here; ``benchmarks/fuzz_loader.py`` runs 10⁵ and more.
"""

from __future__ import annotations

import atexit
import json
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bscomp.validate import FrfData, MeasurementFileError, TimeData, load

CI_EXAMPLES = int(os.environ.get("BSCOMP_FUZZ_EXAMPLES", "1500"))
_DIR = Path(tempfile.mkdtemp(prefix="bscomp-fuzz-"))
atexit.register(shutil.rmtree, _DIR, ignore_errors=True)   # one folder per process, gone at its exit

UNITS = ["m", "um", "mm", "N", "kN", "N m", "rad/s", "rad/s/(N m)", "m/s^2/(N m)", "Hz", "kHz", "s", "ms", "deg",
         "rpm", "1", "-", "kHz999", "um^99999/um^99999", "min⁻¹⁻¹", "m⁻²", "((m))", "(" * 30 + "m" + ")" * 30,
         "GHz^9 GHz^9 GHz^9 GHz^9", "nm^9/GHz^9", "m**2", "1/s", "", "µm", "rad/s/(N", "m^+3", "m^-0"]
CHANNELS = ["motor.tau", "rotor.w", "table.a", "table.s", "nut.f", "x", ""]
QUANT = ["re", "im", "mag", "mag_db", "phase_deg", "phase_rad", "coh"]
CELLS = ["nan", "inf", "-inf", "1e999", "-1e-999", "0x10", "1_0", "", " ", "abc", "1e", "7000", "-7000", "1e308",
         '"1"', "\x00", "é", "0", "1", "-1", "0.5", "2.5e-3", "1e-320", "-0.0", "0.99", "1.01", "3", "-2.5", "12.5"]
CELL = st.one_of(st.sampled_from(CELLS), st.sampled_from(CELLS), st.floats(-1e3, 1e3).map(repr))


@st.composite
def metadata(draw):
    lines = []
    for _ in range(draw(st.integers(0, 5))):
        kind = draw(st.sampled_from(["unit", "input", "output", "condition", "kind", "source", "junk"]))
        ch = draw(st.sampled_from(CHANNELS))
        if kind == "unit":
            lines.append(f"# unit {draw(st.sampled_from(CHANNELS))}/{ch}: {draw(st.sampled_from(UNITS))}")
        elif kind in ("input", "output"):
            lines.append(f"# {kind} {ch}: {draw(st.sampled_from(UNITS))}")
        elif kind == "condition":
            name = draw(st.sampled_from(["nut_position", "params", "table.m", "variant", "a b", "x/y"]))
            value = draw(st.sampled_from(["0.4", "../../etc/passwd", "x.toml", "nan", "~", "abc", "", "1e999",
                                          "a\\b", ".hidden", "/abs", "x" * 200, "true", "[1, 2]"]))
            lines.append(f"# condition {name}: {value}")
        elif kind == "kind":
            lines.append(f"# kind: {draw(st.sampled_from(['frf', 'time', 'FRF', 'other', '']))}")
        elif kind == "source":
            lines.append(f"# source: {draw(st.sampled_from(['bench', '', 'é', 'a: b']))}")
        else:
            lines.append("#" + draw(st.sampled_from([" unknown: 1", " input", " output x y", ":", " unit: m", ""])))
    return lines


@st.composite
def header(draw):
    first = draw(st.sampled_from(["f", "t", "freq", "time", "x", ""]))
    cols = [first]
    for _ in range(draw(st.integers(0, 4))):
        out, inp = draw(st.sampled_from(CHANNELS)), draw(st.sampled_from(CHANNELS))
        form = draw(st.integers(0, 2))
        q = draw(st.sampled_from(QUANT))
        cols.append(f"{q}({out}/{inp})" if form == 0 else f"{inp}->{out} {q}" if form == 1 else out)
    return cols


GOOD = st.floats(-1e3, 1e3, allow_nan=False).map(repr)
VALUE = st.tuples(st.integers(0, 40), GOOD, st.sampled_from(CELLS)).map(lambda v: v[2] if v[0] == 0 else v[1])
_FRF_SEED = [("rotor.w/motor.tau", "rad/s/(N m)"), ("table.a/motor.tau", "m/s^2/(N m)"), ("table.s/nut.f", "um/N")]


@st.composite
def seeded_file(draw):
    """A valid FRF or time-series file with a few values, units and steps changed (most still load)."""
    unit = st.tuples(st.integers(0, 5), st.sampled_from(UNITS)).map(lambda v: v[1] if v[0] == 0 else None)
    if draw(st.booleans()):
        pair, u = draw(st.sampled_from(_FRF_SEED))
        u = draw(unit) or u
        form = draw(st.sampled_from([("re", "im"), ("mag", "phase_deg"), ("mag_db", "phase_rad")]))
        cols = [f"{q}({pair})" for q in form] + ([f"coh({pair})"] if draw(st.booleans()) else [])
        lines = [f"# unit {pair}: {u}", "f," + ",".join(cols)]
        funit = draw(st.sampled_from([None, "Hz", "kHz", "rad/s", "kHz999"]))
        if funit:
            lines.insert(0, f"# unit f: {funit}")
        coh = st.one_of(st.floats(0, 1).map(repr), st.floats(0.5, 1).map(repr), st.sampled_from(["0", "1", "1.5"]))
        cells = lambda: [draw(VALUE) for _ in form] + ([draw(coh)] if len(cols) > 2 else [])  # noqa: E731
    else:
        ch = draw(st.sampled_from([("table.a", "m/s^2"), ("rotor.w", "rad/s"), ("table.s", "um")]))
        lines = [f"# input motor.tau: {draw(unit) or 'N m'}", f"# output {ch[0]}: {draw(unit) or ch[1]}",
                 f"t,motor.tau,{ch[0]}"]
        if draw(st.booleans()):
            lines.insert(0, f"# unit t: {draw(st.sampled_from(['s', 'ms', 'us', 'Hz', 'min', 'h']))}")
        cells = lambda: [draw(VALUE), draw(VALUE)]  # noqa: E731
    x = draw(st.sampled_from([0.0, 1.0, 10.0, 1e300]))
    for _ in range(draw(st.integers(1, 8))):
        lines.append(",".join([repr(x)] + cells()))
        x += draw(st.sampled_from([1.0] * 20 + [0.5, 1e-12, 0.0, -1.0, 1e308]))
    if draw(st.integers(0, 9)) == 0:
        lines.insert(0, f"# condition {draw(st.sampled_from(['nut_position', 'params', 'variant']))}: "
                        f"{draw(st.sampled_from(['0.4', '../x.toml', 'abc', 'nan']))}")
    return ("\n".join(lines) + "\n").encode(), None


def measurement_file():
    """(csv bytes, sidecar bytes or None): a mutated valid file, or a plausible file with mutated bytes."""
    return st.one_of(seeded_file(), any_file())


@st.composite
def any_file(draw):
    """(csv bytes, sidecar bytes or None): a plausible file, then mutated."""
    meta = draw(metadata())
    head = draw(header())
    n = len(head)
    x = draw(st.sampled_from([-1.0, 0.0, 0.5, 1.0, 7.0]))
    rows = []
    for cells in draw(st.lists(st.lists(CELL, min_size=max(n - 2, 0), max_size=n + 1), max_size=6)):
        x += draw(st.sampled_from([1.0, 1.0, 1.0, 0.5, 0.0, -1.0, 1e-300]))
        rows.append(",".join([repr(x)] + cells[: n - 1 if draw(st.integers(0, 5)) else len(cells)]))
    text = "\n".join(meta + [",".join(head)] + rows) + draw(st.sampled_from(["\n", "", "\r\n", "\n\n#x\n"]))
    data = text.encode("utf-8")
    for _ in range(draw(st.integers(0, 3))):          # byte mutations: Latin-1, NUL, truncation, swaps
        if not data:
            break
        k = draw(st.integers(0, len(data) - 1))
        data = data[:k] + draw(st.sampled_from([b"\xe9", b"\x00", b",", b"\n", b"#", b"-", b"e9", b""])) + data[k + 1:]
    side = None
    choice = draw(st.integers(0, 5))
    if choice == 1:
        side = json.dumps({"units": {draw(st.sampled_from(CHANNELS)): draw(st.sampled_from(UNITS))},
                           "conditions": {draw(st.sampled_from(["nut_position", "params"])):
                                          draw(st.sampled_from([0.4, float("nan"), "../p.toml", "ok"]))}}).encode()
    elif choice == 2:
        depth = draw(st.sampled_from([3, 50, 5000, 100000]))
        side = (b"[" * depth + b"]" * depth)
    elif choice == 3:
        side = draw(st.binary(max_size=40))
    elif choice == 4:
        leaf = st.sampled_from([None, True, 1, 1.5, float("nan"), "m", "../x", "frf", [], {}])
        key = st.sampled_from(["units", "conditions", "kind", "inputs", "outputs", "source", "x"])
        side = json.dumps(draw(st.dictionaries(key, st.one_of(leaf, st.dictionaries(st.sampled_from(CHANNELS), leaf,
                                                                                       max_size=2)), max_size=3)),
                          allow_nan=True).encode()
    return data, side


def check_one(data: bytes, side: bytes | None, name: str = "m.csv"):
    """Write the case, load it: MeasurementFileError or finite, monotonic data; any other exception escapes."""
    path = _DIR / name
    path.write_bytes(data)
    sc = _DIR / (name + ".json")
    if side is None:
        sc.unlink(missing_ok=True)
    else:
        sc.write_bytes(side)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            d = load(path)
        except MeasurementFileError:
            return "error"
    if isinstance(d, FrfData):
        assert np.all(np.isfinite(d.freqs)) and np.all(np.diff(d.freqs) > 0)
        assert all(np.all(np.isfinite(h)) for h in d.H.values())
        assert all(g is None or np.all((g >= 0) & (g <= 1)) for g in d.coherence.values())
    else:
        assert isinstance(d, TimeData)
        assert np.all(np.isfinite(d.t)) and np.all(np.diff(d.t) > 0)
        assert all(np.all(np.isfinite(v)) for v in (*d.inputs.values(), *d.outputs.values()))
    assert all(isinstance(v, (float, str)) and "/" not in str(v) for v in d.conditions.values())
    assert "params" not in d.conditions
    return "loaded"


@pytest.mark.filterwarnings("ignore")
@settings(max_examples=CI_EXAMPLES, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(measurement_file())
def test_only_measurement_file_errors_escape(case):
    assert check_one(*case) in ("error", "loaded")


@pytest.mark.parametrize("text", [
    "# unit rotor.w/motor.tau: rad/s/(N m)\nf,re(rotor.w/motor.tau),im(rotor.w/motor.tau)\n1,1,2\n2,3,4\n",
    "# input motor.tau: N m\n# output table.a: m/s^2\nt,motor.tau,table.a\n0,1,2\n0.1,3,4\n",
])
def test_the_seed_files_load(text):
    assert check_one(text.encode(), None) == "loaded"
