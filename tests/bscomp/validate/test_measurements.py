"""Measurement files: round trips, sidecars, units, and every bad-file class naming line and column."""

import json

import numpy as np
import pytest

from bscomp.errors import BscompError
from bscomp.validate import (
    FrfData,
    MeasurementFileError,
    TimeData,
    load,
    read_frf_csv,
    read_time_csv,
    write_frf_csv,
    write_time_csv,
)

PAIR = ("motor.tau", "rotor.w")
F = np.array([10.0, 20.0, 50.0, 100.0])


def _frf():
    H = {PAIR: np.array([1 + 2j, -0.5 + 1j, 0.25 - 3j, 1e-3 + 1e-4j]),
         ("motor.tau", "table.a"): np.array([0.1 + 0j, 0.2 - 0.1j, -0.3j, 4.0 + 0j])}
    return FrfData(F, H, units={PAIR: "rad/s/(N m)", ("motor.tau", "table.a"): "m/s^2/(N m)"},
                   conditions={"nut_position": 0.43, "operator": "abc"},
                   coherence={PAIR: np.array([0.9, 0.95, 1.0, 0.5]), ("motor.tau", "table.a"): None},
                   source="bench")


def _time():
    t = np.linspace(0, 0.01, 11)
    return TimeData(t, {"motor.tau": np.sin(100 * t)}, {"table.a": np.cos(100 * t), "rotor.w": t ** 2},
                    units={"motor.tau": "N m", "table.a": "m/s^2", "rotor.w": "rad/s"},
                    conditions={"nut_position": 0.1}, source="run 1")


@pytest.mark.parametrize("form", ["reim", "magphase"])
def test_frf_round_trip(tmp_path, form):
    d = _frf()
    p = write_frf_csv(d, tmp_path / "x.csv", form=form)
    r = load(p)
    assert isinstance(r, FrfData) and r.pairs == d.pairs
    np.testing.assert_allclose(r.freqs, F)
    for k in d.H:
        np.testing.assert_allclose(r.H[k], d.H[k], rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(r.coherence[PAIR], d.coherence[PAIR])
    assert r.coherence[("motor.tau", "table.a")] is None
    assert r.units == d.units and r.conditions == d.conditions and r.source == "bench"


def test_time_round_trip(tmp_path):
    d = _time()
    r = read_time_csv(write_time_csv(d, tmp_path / "t.csv"))
    assert isinstance(r, TimeData) and list(r.inputs) == ["motor.tau"] and list(r.outputs) == ["table.a", "rotor.w"]
    np.testing.assert_array_equal(r.t, d.t)
    for k in d.outputs:
        np.testing.assert_array_equal(r.outputs[k], d.outputs[k])
    assert r.units == d.units and r.conditions == {"nut_position": 0.1}


def test_units_are_converted_to_si(tmp_path):
    p = tmp_path / "u.csv"
    p.write_text("# input motor.tau: N m\n# output table.s: um\n# output rotor.w: rpm\n# unit t: ms\n"
                 "t,motor.tau,table.s,rotor.w\n0,1,5,60\n1,1,7,120\n")
    d = read_time_csv(p)
    np.testing.assert_allclose(d.t, [0, 1e-3])
    np.testing.assert_allclose(d.outputs["table.s"], [5e-6, 7e-6])
    np.testing.assert_allclose(d.outputs["rotor.w"], [2 * np.pi, 4 * np.pi])
    assert d.units["table.s"] == "m"


def test_mag_db_phase_and_json_sidecar(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("f,mag_db(table.s/motor.tau),phase_deg(table.s/motor.tau)\n1,0,90\n2,-20,180\n")
    (tmp_path / "m.csv.json").write_text(json.dumps({"kind": "frf", "units": {"table.s/motor.tau": "mm/(N m)"},
                                                     "conditions": {"nut_position": 0.2}}))
    d = read_frf_csv(p)
    np.testing.assert_allclose(d.H[("motor.tau", "table.s")], [1e-3j, -1e-4], atol=1e-15)
    assert d.conditions == {"nut_position": 0.2}


def test_toml_sidecar(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("t,motor.tau,table.v\n0,1,2\n0.1,1,2\n")
    (tmp_path / "m.toml").write_text('kind = "time"\n[inputs]\n"motor.tau" = "N m"\n[outputs]\n"table.v" = "mm/s"\n')
    d = load(p)
    np.testing.assert_allclose(d.outputs["table.v"], [2e-3, 2e-3])


BAD = {
    # name: (file text, expected line, expected column, words in the message)
    "nan": ("# input motor.tau: N m\n# output table.a: m/s^2\nt,motor.tau,table.a\n0,1,2\n0.1,nan,2\n", 5, 2,
            "finite"),
    "text": ("# input motor.tau: N m\n# output table.a: m/s^2\nt,motor.tau,table.a\n0,1,2\n0.1,1,abc\n", 5, 3,
             "not a number"),
    "time_not_monotonic": ("# input motor.tau: N m\n# output table.a: m/s^2\nt,motor.tau,table.a\n0,1,2\n0.2,1,2\n"
                           "0.1,1,2\n", 6, 1, "increasing"),
    "freq_not_monotonic": ("# unit rotor.w/motor.tau: rad/s/(N m)\nf,re(rotor.w/motor.tau),im(rotor.w/motor.tau)\n"
                           "1,1,1\n3,1,1\n3,1,1\n", 5, 1, "increasing"),
    "unknown_channel": ("# input motor.tau: N m\n# output table.a: m/s^2\nt,motor.tau,table.a,table.x\n"
                        "0,1,2,3\n1,1,2,3\n",
                        3, 4, "unknown channel"),
    "unknown_frf_column": ("# unit rotor.w/motor.tau: rad/s/(N m)\nf,re(rotor.w/motor.tau),imag(rotor.w/motor.tau)\n"
                           "1,1,1\n", 2, 3, "unknown column"),
    "missing_unit": ("# input motor.tau: N m\n# output table.a\nt,motor.tau,table.a\n0,1,2\n1,1,2\n", 3, 3,
                     "missing unit"),
    "bad_unit": ("# input motor.tau: N m\n# output table.a: furlong/s\nt,motor.tau,table.a\n0,1,2\n1,1,2\n", 2, 19,
                 "unknown unit"),
    "wrong_unit": ("# input motor.tau: N m\n# output table.a: m/s\nt,motor.tau,table.a\n0,1,2\n1,1,2\n", 2, 19,
                   "wrong unit"),
    "wrong_frf_unit": ("# unit table.a/motor.tau: m/(N m)\nf,re(table.a/motor.tau),im(table.a/motor.tau)\n1,1,1\n",
                       1, 27, "wrong unit"),
    "empty": ("", 1, 1, "empty"),
    "header_only": ("# input motor.tau: N m\nt,motor.tau\n", 2, 1, "no data"),
    "ragged": ("# input motor.tau: N m\n# output table.a: m/s^2\nt,motor.tau,table.a\n0,1\n", 4, 3, "fields"),
    "coherence_range": ("# unit rotor.w/motor.tau: rad/s/(N m)\n"
                        "f,re(rotor.w/motor.tau),im(rotor.w/motor.tau),coh(rotor.w/motor.tau)\n1,1,1,1.2\n", 3, 4,
                        "coherence"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_files_name_line_and_column(tmp_path, case):
    text, line, col, words = BAD[case]
    p = tmp_path / f"{case}.csv"
    p.write_text(text)
    with pytest.raises(MeasurementFileError) as ei:
        load(p)
    e = ei.value
    assert isinstance(e, BscompError)
    assert e.path == str(p) and e.line == line and e.column == col, str(e)
    msg = str(e)
    assert str(p) in msg and f"line {line}" in msg and f"column {col}" in msg and words in msg


def test_bad_json_sidecar_names_its_line(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text("t,motor.tau\n0,1\n")
    (tmp_path / "s.csv.json").write_text('{\n  "kind": "time",\n  "inputs": {"motor.tau": "N m",}\n}\n')
    with pytest.raises(MeasurementFileError) as ei:
        load(p)
    assert ei.value.path.endswith("s.csv.json") and ei.value.line == 3


def test_file_conditions_as_documented(tmp_path, capsys):
    # `# condition nut_position: 0.4` in a file compared with validation_drive (which has no nut position):
    # dropped with a one-line warning; `# condition table.m: 260` is a parameter override
    from bscomp.cli import main
    from bscomp.systems import validation_drive
    from bscomp.validate import compare, model_frf
    from bscomp.validate.residuals import ConditionIgnoredWarning

    pairs = {("amp.u", "rotor.w"): "rad/s/V", ("amp.u", "table.a"): "m/s^2/V"}
    f = np.logspace(1, 3, 50)
    d = FrfData(f, {p: np.zeros(f.size, complex) for p in pairs}, units=pairs)
    d.H = model_frf(validation_drive().with_parameters({"table.m": 260.0}), d)
    d.conditions = {"nut_position": 0.4, "table.m": 260.0}
    path = write_frf_csv(d, tmp_path / "data.csv")
    text = path.read_text()
    assert "# condition nut_position: 0.4" in text and "# condition table.m: 260" in text
    assert load(path).conditions == {"nut_position": 0.4, "table.m": 260.0}
    with pytest.warns(ConditionIgnoredWarning) as rec:
        c = compare("validation_drive", [path])
    assert [str(w.message) for w in rec] == [
        f"{path}: condition 'nut_position' ignored: not a build argument of system 'validation_drive' (build "
        "arguments: k_axial) nor a parameter ('component.parameter')"]
    assert c.cost < 1e-18                            # built with table.m = 260
    with pytest.warns(ConditionIgnoredWarning):
        assert main(["compare", "validation_drive", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cost"] < 1e-18


def test_frf_to_csv_reads_back_with_units_and_names(tmp_path):
    from bscomp.linear.response import frf

    res = frf("small_drive", "motor.tau", ["rotor.w", "table.a"], fmin=1, fmax=500, n=40)
    units = {("motor.tau", "rotor.w"): "rad/s/(N m)", ("motor.tau", "table.a"): "m/s^2/(N m)"}
    plain, noted = tmp_path / "plain.csv", tmp_path / "noted.csv"
    res.to_csv(plain)                                         # a plain table: units implied by the names
    res.to_csv(noted, conditions={"nut_position": 0.3})       # with '#' metadata lines
    assert len(plain.read_text().splitlines()) == 41 and noted.read_text().startswith("# kind: frf\n")
    for path in (plain, noted):
        d = load(path)
        assert isinstance(d, FrfData) and d.pairs == [("motor.tau", "rotor.w"), ("motor.tau", "table.a")]
        np.testing.assert_array_equal(d.freqs, res.freqs)
        np.testing.assert_array_equal(d.H[("motor.tau", "rotor.w")], res.response("rotor.w"))
        np.testing.assert_array_equal(d.H[("motor.tau", "table.a")], res.response("table.a"))
        assert d.units == units and all(g is None for g in d.coherence.values())
    assert load(noted).conditions == {"nut_position": 0.3} and load(noted).source == "small_drive"
    assert load(plain).conditions == {} and load(plain).source == str(plain)


def test_frf_to_csv_on_a_stream_and_with_given_units(tmp_path):
    import io

    from bscomp.linear.response import frf

    res = frf("validation_drive", "amp.u", ["rotor.w"], fmin=2, fmax=200, n=20)
    for units, expected in ((None, "rad/s"), ({"amp.u": "V"}, "rad/s/(V)")):   # a signal input is '1' by default
        buf = io.StringIO()
        res.to_csv(buf, units=units)
        path = tmp_path / "stdout.csv"
        path.write_text(buf.getvalue())
        d = load(path)
        assert d.units == {("amp.u", "rotor.w"): expected}
        np.testing.assert_array_equal(d.H[("amp.u", "rotor.w")], res.response())
    with pytest.raises(ValueError, match="not SI"):
        res.to_csv(tmp_path / "rpm.csv", units={"rotor.w": "rpm"})


def test_redundant_magnitude_and_phase_must_agree(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("# unit rotor.w/motor.tau: rad/s/(N m)\n"
                 "freq_hz,motor.tau->rotor.w re,motor.tau->rotor.w im,motor.tau->rotor.w mag_db,"
                 "motor.tau->rotor.w phase_deg\n1,1,0,0,0\n2,0,1,0,91\n")
    with pytest.raises(MeasurementFileError) as ei:
        load(p)
    assert ei.value.line == 4 and ei.value.column == 4 and "disagree" in str(ei.value)
