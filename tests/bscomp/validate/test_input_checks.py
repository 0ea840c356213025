"""Bad input to the validation functions is a named error pointing at the file's line or the argument."""

import warnings
from pathlib import Path

import numpy as np
import pytest

from bscomp.errors import ArgumentTypeError, UnknownNameError, UsageError
from bscomp.validate import calibrate, compare, diagnose, load
from bscomp.validate.arguments import check_diagnose, resolve_candidates
from bscomp.validate.datasets import MIN_FRF_POINTS, MIN_TIME_SAMPLES, FrfData, MeasurementFileError
from bscomp.validate.residuals import ConditionIgnoredWarning

DATA = Path(__file__).resolve().parents[3] / "systems" / "data" / "validation"
FRF_LINES = (DATA / "frf.csv").read_text().splitlines()
TIME_LINES = (DATA / "time.csv").read_text().splitlines()
FRF_HEAD = 5          # '# kind', '# source', two '# unit' lines, the header
TIME_HEAD = 9


def _frf(tmp_path, meta=(), rows=40, replace=None, name="frf.csv"):
    """A copy of the bundled FRF file: ``meta`` lines after '# source', ``rows`` data rows, ``replace``
    {old: new} applied to the metadata lines."""
    head = FRF_LINES[:2] + list(meta) + FRF_LINES[2:FRF_HEAD]
    for old, new in (replace or {}).items():
        head = [h.replace(old, new) for h in head]
    p = tmp_path / name
    p.write_text("\n".join(head + FRF_LINES[FRF_HEAD:FRF_HEAD + rows]) + "\n")
    return p


def _time(tmp_path, meta=(), rows=200, replace=None, name="time.csv"):
    head = TIME_LINES[:2] + list(meta) + TIME_LINES[2:TIME_HEAD]
    for old, new in (replace or {}).items():
        head = [h.replace(old, new) for h in head]
    p = tmp_path / name
    p.write_text("\n".join(head + TIME_LINES[TIME_HEAD:TIME_HEAD + rows]) + "\n")
    return p


# ---- the files alone ----------------------------------------------------------------------------------------
def test_valid_files_read_as_before(tmp_path):
    d = load(DATA / "frf.csv")
    row = [float(x) for x in FRF_LINES[FRF_HEAD].split(",")]
    assert d.freqs[0] == row[0] and d.H[("amp.u", "rotor.w")][0] == complex(row[1], row[2])
    assert d.path == str(DATA / "frf.csv") and d.source.startswith("synthetic FRF")
    t = load(DATA / "time.csv")
    assert t.t[1] == 0.0005 and t.inputs["amp.u"][0] == 2.1240234375 and t.units["amp.u"] == "V"
    assert load(_frf(tmp_path, rows=MIN_FRF_POINTS)).freqs.size == MIN_FRF_POINTS


def test_frequency_zero_is_refused_with_its_line(tmp_path):
    p = _frf(tmp_path)
    lines = p.read_text().splitlines()
    lines.insert(FRF_HEAD, "0.0" + lines[FRF_HEAD][lines[FRF_HEAD].index(","):])
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeasurementFileError, match=rf"{p}, line {FRF_HEAD + 1}, column 1 \('f'\): frequency 0 Hz"):
        load(p)


@pytest.mark.parametrize("col, unit_name", [("T", "t"), ("time", "t"), ("t", "time")])
def test_time_unit_found_whatever_the_first_column_is_called(tmp_path, col, unit_name):
    p = _time(tmp_path, replace={"# unit t: s": f"# unit {unit_name}: ms", "t,amp.u": f"{col},amp.u"})
    assert load(p).t[1] == pytest.approx(0.0005e-3)


def test_frequency_unit_found_whatever_its_name(tmp_path):
    d = load(_frf(tmp_path, meta=["# unit freq: kHz"]))
    assert d.freqs[0] == pytest.approx(2000.0)


def test_a_unit_line_naming_no_column_is_an_error(tmp_path):
    p = _time(tmp_path, meta=["# unit rotor.q: m"])
    with pytest.raises(MeasurementFileError, match=rf"{p}, line 3, column \d+ \('rotor.q'\): unit given for "
                       r"'rotor.q', which is not the time column or a channel column \(did you mean 'rotor.w'\?\): "
                       r"a unit line must name one of \['amp.u', 'rotor.phi'"):
        load(p)
    p = _frf(tmp_path, meta=["# unit table.x: m"])
    with pytest.raises(MeasurementFileError, match=r"line 3.*'table.x'.*a unit line must name one of"):
        load(p)


def test_too_few_points_name_the_file_and_the_minimum(tmp_path):
    p = _frf(tmp_path, rows=1)
    assert load(p).freqs.size == 1                          # a short file reads; the analyses refuse it
    with pytest.raises(MeasurementFileError, match=rf"^{p}: frf data with 1 frequencies: compare needs at least "
                       rf"{MIN_FRF_POINTS} \(a fit %"):
        compare("validation_drive", p)
    p = _time(tmp_path, rows=2)
    with pytest.raises(MeasurementFileError, match=rf"^{p}: time data with 2 samples: compare needs at least "
                       rf"{MIN_TIME_SAMPLES}"):
        compare("validation_drive", p)
    with pytest.raises(MeasurementFileError, match=rf"^{p}: time data with 2 samples: diagnose needs"):
        diagnose("validation_drive", p)
    p = _time(tmp_path, rows=8)                             # the table has not moved yet: table.s is 0
    with pytest.raises(MeasurementFileError, match=rf"^{p}, line {TIME_HEAD}, column 5 \('table.s'\): output "
                       "table.s is 0 in every sample: diagnose whitens"):
        diagnose("validation_drive", p)
    short = FrfData(np.array([1.0, 2.0]), {("amp.u", "rotor.w"): np.array([1, 2j])}, source="bench")
    with pytest.raises(MeasurementFileError, match="^bench: frf data with 2 frequencies: calibrate needs"):
        calibrate("validation_drive", [short])


# ---- units against the model ---------------------------------------------------------------------------------
def test_frf_unit_of_another_dimension_than_the_model_is_refused(tmp_path):
    for unit in ("mm/V", "N"):
        p = _frf(tmp_path, replace={"rotor.w/amp.u: rad/s/V": f"rotor.w/amp.u: {unit}"})
        with pytest.raises(MeasurementFileError, match=rf"{p}, line 3, column \d+ \('rotor.w/amp.u'\): .* "
                           r"so the response is in rad/s/\(V\)"):
            compare("validation_drive", p)


def test_compatible_prefix_is_converted(tmp_path):
    p = _frf(tmp_path, replace={"table.a/amp.u: m/s^2/V": "table.a/amp.u: mm/s^2/V"})
    d, ref = load(p), load(_frf(tmp_path, name="ref.csv"))
    np.testing.assert_allclose(d.H[("amp.u", "table.a")], 1e-3 * ref.H[("amp.u", "table.a")])
    from bscomp.kernel.flattening import flatten
    from bscomp.systems import validation_drive
    from bscomp.validate.units_check import check_units
    check_units(flatten(validation_drive()), d)             # the dimension fits: no error


def test_time_input_and_excitation_units_are_checked_against_the_model(tmp_path):
    p = _time(tmp_path, replace={"# input amp.u: V": "# input amp.u: N"})
    with pytest.raises(MeasurementFileError, match=rf"{p}, line 4, .*'amp.u'.* the input amp.u does not fit model "
                       "'validation_drive', which has it in V"):
        compare("validation_drive", p)
    p = _frf(tmp_path, meta=["# excitation amp.u: 2 N"])
    with pytest.raises(MeasurementFileError, match=rf"{p}, line 3, .*excitation of amp.u in 'N'.* in V"):
        compare("validation_drive", p)


def test_calibrate_checks_units_where_the_data_meet_the_model(tmp_path):
    p = _frf(tmp_path, replace={"rotor.w/amp.u: rad/s/V": "rotor.w/amp.u: N"})
    with pytest.raises(MeasurementFileError, match=rf"{p}, line 3.*rad/s/\(V\)"):
        calibrate("validation_drive", p, ["table.m"], max_nfev=1)


# ---- conditions ---------------------------------------------------------------------------------------------
def test_bad_condition_lines_name_the_file_and_line(tmp_path):
    p = _frf(tmp_path, meta=["# condition table.zz: 5"])
    with pytest.raises(MeasurementFileError, match=rf"{p}, line 3, column \d+ \('table.zz'\): condition "
                       r"table.zz = 5.0: .*has no parameter 'zz'"):
        compare("validation_drive", p)
    p = _frf(tmp_path, meta=["# condition k_axial: -1"])
    with pytest.raises(MeasurementFileError, match=rf"{p}, line 3, .*condition k_axial = -1.0: .*must be > 0"):
        compare("validation_drive", p)


def test_warnings_name_the_path_with_the_source_text(tmp_path):
    p = _frf(tmp_path, meta=["# condition operator: x"])
    with pytest.warns(ConditionIgnoredWarning, match=rf"^{p} \(synthetic FRF .*\): condition 'operator' ignored"):
        compare("validation_drive", p, bands=[(2, 10)])


# ---- arguments ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kw, match", [
    (dict(pair_tolerance=-1), "pair_tolerance must be > 0"), (dict(pair_tolerance=0), "pair_tolerance must be > 0"),
    (dict(pair_tolerance=np.nan), "pair_tolerance must be finite"),
    (dict(bands=[(-5, 100)]), r"bands\[0\] = \(-5, 100\): .*0 < lo < hi"),
    (dict(bands=[(500, 100)]), r"bands\[0\] = \(500, 100\)"), (dict(bands=[(np.nan, 100)]), r"bands\[0\]"),
    (dict(bands=[(5000, 8000)]), r"bands\[0\] = \(5000, 8000\) Hz holds no measured frequency"),
    (dict(bands="abc"), "bands must be a list of"), (dict(bands=[(1, 2, 3)]), r"bands\[0\] must be a pair"),
    (dict(n_windows=-3), "n_windows must be >= 1"), (dict(n_windows=2.5), "n_windows must be an integer"),
])
def test_compare_arguments(kw, match):
    with pytest.raises(UsageError, match=match):
        compare("validation_drive", DATA / "frf.csv", **kw)


@pytest.mark.parametrize("fn", [compare, diagnose, calibrate])
def test_no_dataset_is_a_usage_error(fn):
    with pytest.raises(UsageError, match="datasets is empty") as e:
        fn("validation_drive", [])
    assert "frf.csv" in e.value.hint


@pytest.mark.parametrize("kw, cls, match", [
    (dict(max_effects=-1), UsageError, "max_effects must be >= 0"),
    (dict(max_effects=1.5), UsageError, "max_effects must be an integer"),
    (dict(n_screen=0), UsageError, "n_screen must be >= 1"),
    (dict(max_effect=2), UsageError, "unknown keyword argument 'max_effect': did you mean 'max_effects'"),
    (dict(foo=1), UsageError, "unknown keyword argument 'foo'"),
    (dict(candidates=42), ArgumentTypeError, "candidates must be a list"),
    (dict(candidates=[42]), ArgumentTypeError, r"candidates\[0\] must be a candidate name.*nut_table_joint"),
    (dict(candidates=["nut_table_jiont"]), UnknownNameError, "did you mean 'nut_table_joint'"),
    (dict(default_spread=-1), UsageError, "default_spread must be > 0"),
])
def test_diagnose_arguments(kw, cls, match):
    with pytest.raises(cls, match=match):
        diagnose("validation_drive", DATA / "frf.csv", **kw)


def test_diagnose_takes_candidate_names_and_ignores_legacy_keywords():
    (c,) = resolve_candidates(["nut_table_joint"])
    assert c.name == "nut_table_joint"
    with pytest.warns(DeprecationWarning, match="n_starts no longer"):
        check_diagnose({"n_starts": 2}, ["max_effects"], max_effects=1)


@pytest.mark.parametrize("kw, match", [
    (dict(max_nfev=0), "max_nfev must be >= 1"), (dict(max_nfev=-1), "max_nfev must be >= 1"),
    (dict(default_spread=-1), "default_spread must be > 0"), (dict(default_spread=-0.5), "default_spread must be > 0"),
    (dict(default_spread=0), "default_spread must be > 0"),
])
def test_calibrate_arguments(kw, match):
    with pytest.raises(UsageError, match=match):
        calibrate("validation_drive", DATA / "frf.csv", ["table.m"], **kw)


def test_calibrate_names_uncertain_parameters_as_component_parameter():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(UnknownNameError, match="uncertain parameter 'k_T' is not a parameter of "
                           "'validation_drive': uncertain parameters are named 'component.parameter', e.g. "):
            calibrate("validation_drive", DATA / "frf.csv", {"k_T": 0.2})
