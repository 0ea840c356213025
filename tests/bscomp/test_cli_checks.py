"""Bad input named at the door (CLI and library): the option in the message, nothing written, valid input works."""

import json
import os
import signal
import textwrap

import numpy as np
import pytest
import scipy.sparse as sp

from bscomp import errors
from bscomp.cli import main
from bscomp.cli_checks import Terminated, parse_uncertain, sigterm_as_interrupt, steps
from bscomp.files import atomic_dir, staged
from bscomp.kernel.condensation import massless_split

FRF_DATA = os.path.join(os.path.dirname(__file__), "..", "..", "systems", "data", "validation", "frf.csv")


def _one_line(capsys, verb, kind, *words):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"bscomp {verb}: {kind}: "), err
    for w in words:
        assert w in err[0], (w, err[0])
    return err[0]


# ---- 1: --t-end must be a whole number of --dt steps --------------------------------------------------------
@pytest.mark.parametrize("dt", ["1", "0.25"])
def test_simulate_t_end_not_a_multiple_of_dt(dt, capsys):
    assert main(["simulate", "validation_drive", "--t-end", "0.6", "--dt", dt]) == 2
    _one_line(capsys, "simulate", "UsageError", "--t-end", "--dt", "give --dt")


def test_steps_accepts_float_multiples():
    assert steps(0.6, 1e-4) == 6000 and steps(0.6, 0.1) == 6 and steps(1.0, 1.0) == 1
    with pytest.raises(errors.UsageError, match="--dt 0.2"):
        steps(0.6, 0.25)


# ---- 2: --reference checked before any file is written ------------------------------------------------------
def test_modes_bad_reference_writes_nothing(tmp_path, capsys):
    csv = tmp_path / "m.csv"
    assert main(["modes", "validation_drive", "--csv", str(csv), "--reference", "rotor.zz"]) == 2
    _one_line(capsys, "modes", "UnknownNameError", "--reference", "rotor.phi")
    assert list(tmp_path.iterdir()) == [] and capsys.readouterr().out == ""


# ---- 3: a parameter is not a signal ---------------------------------------------------------------------------
@pytest.mark.parametrize("out", ["table.m", "rotor.J"])
def test_frf_of_a_parameter_is_refused(out, capsys):
    assert main(["frf", "validation_drive", "--input", "amp.u", "--output", out, "--n", "5"]) == 2
    _one_line(capsys, "frf", "UnknownNameError", out, "parameter, not a signal", out.split(".")[0] + ".")


def test_frf_api_refuses_a_parameter_and_keeps_signals():
    from bscomp.linear.response import frf

    with pytest.raises(errors.UnknownNameError, match="'table.m' .* is a parameter"):
        frf("validation_drive", "amp.u", ["table.a", "table.m"], n=3)
    res = frf("validation_drive", "amp.u", ["table.a", "rotor.w"], n=3)
    assert np.all(np.abs(res.H) > 0)


# ---- 4: SIGTERM takes the Ctrl-C path: temporary files removed ----------------------------------------------
def test_sigterm_raises_terminated_and_cleans_staged_files(tmp_path):
    target = tmp_path / "big.csv"
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated), sigterm_as_interrupt(), staged() as st:
        st.path(target).write_text("partial")
        os.kill(os.getpid(), signal.SIGTERM)
    assert list(tmp_path.iterdir()) == [] and signal.getsignal(signal.SIGTERM) is before


def test_sigterm_during_a_cli_write_exits_143_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    from bscomp.linear import modal

    def to_csv(self, path):
        with open(path, "w") as fh:
            fh.write("half a table\n")
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(modal.Modes, "to_csv", to_csv)
    assert main(["modes", "small_drive", "--csv", str(tmp_path / "m.csv")]) == 143
    assert "terminated" in capsys.readouterr().err and list(tmp_path.iterdir()) == []


# ---- 5: output folders checked up front and named -------------------------------------------------------------
def test_report_below_a_file_is_refused_before_computing(tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    assert main(["compare", "validation_drive", FRF_DATA, "--report", str(tmp_path / "afile" / "rep")]) == 2
    _one_line(capsys, "compare", "OutputFileError", "--report", "is a file, not a folder")
    assert capsys.readouterr().out == ""


def test_demo_out_is_a_file(tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    assert main(["demo", "--out", str(tmp_path / "afile")]) == 2
    _one_line(capsys, "demo", "OutputFileError", "--out", "is a file, not a folder")


def test_report_in_read_only_folder_named_before_computing(tmp_path, monkeypatch, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(ro) else real(p, mode))
    assert main(["diagnose", "validation_drive", FRF_DATA, "--report", str(ro / "rep")]) == 2
    line = _one_line(capsys, "diagnose", "OutputFileError", "--report", "not writable")
    assert ".rep." not in line and capsys.readouterr().out == ""


def test_atomic_dir_never_names_its_temporary_folder(tmp_path, monkeypatch):
    import tempfile

    def refuse(*a, **k):
        raise PermissionError(13, "Permission denied", str(tmp_path / ".rep.abcd"))

    monkeypatch.setattr(tempfile, "mkdtemp", refuse)
    with pytest.raises(errors.OutputFileError) as info, atomic_dir(tmp_path / "rep"):
        pass
    assert ".rep.abcd" not in str(info.value) and "'" + str(tmp_path / "rep") + "'" in str(info.value)


# ---- 6: --uncertain format ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("spec", ["table", "=0.2", "table.m=-1", "table.m=abc", ","])
def test_uncertain_format_named(spec, capsys):
    assert main(["diagnose", "validation_drive", FRF_DATA, "--uncertain", spec]) == 2
    _one_line(capsys, "diagnose", "UsageError", "--uncertain")


def test_uncertain_valid_forms():
    assert parse_uncertain(["table.m=0.3,coupling.c", "rotor.J"]) == {"table.m": 0.3, "coupling.c": 0.2,
                                                                       "rotor.J": 0.2}
    assert parse_uncertain(None) is None


# ---- 7: a system file's build() ---------------------------------------------------------------------------------
@pytest.mark.parametrize("body, words", [("return 42", ["returned int", "build()"]),
                                         ("import sys\n    sys.exit(3)", ["sys.exit(3)", "build()"])])
@pytest.mark.parametrize("verb", ["modes", "compare"])
def test_bad_build_named(tmp_path, capsys, body, words, verb):
    path = tmp_path / "bad.py"
    path.write_text(textwrap.dedent(f"def build():\n    {body}\n"))
    argv = [verb, str(path)] + ([FRF_DATA] if verb == "compare" else [])
    assert main(argv) == 2
    _one_line(capsys, verb, "ModelDefinitionError", str(path), *words)


# ---- 8: CLI wording -----------------------------------------------------------------------------------------------
def test_fmu_nominal_named(tmp_path, capsys):
    assert main(["fmu", "validation_drive", "-o", str(tmp_path / "d.fmu"), "--nominal", "-1"]) == 2
    _one_line(capsys, "fmu", "UsageError", "--nominal")
    assert list(tmp_path.iterdir()) == []


def test_amplitude_on_a_linear_drive_says_drop_it(capsys):
    argv = ["frf", "validation_drive", "--input", "amp.u", "--output", "table.a", "--amplitude", "2",
            "--method", "describing", "--n", "3"]
    assert main(argv) == 2
    line = _one_line(capsys, "frf", "UsageError", "--amplitude", "drop --amplitude")
    assert "bscomp.frf" not in line


def test_compare_takes_build_arguments_in_set(capsys):
    assert main(["compare", "validation_drive", FRF_DATA, "--set", "k_axial=1e8", "--json"]) == 0
    with_set = json.loads(capsys.readouterr().out)["cost"]
    assert main(["compare", "validation_drive", FRF_DATA, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cost"] != with_set
    assert main(["compare", "validation_drive", FRF_DATA, "--set", "k_axiall=1e8"]) == 2
    _one_line(capsys, "compare", "UnknownNameError", "k_axiall")


# ---- 9: simulate()'s arguments --------------------------------------------------------------------------------------
T = np.linspace(0.0, 0.01, 11)


@pytest.mark.parametrize("kw, error, words", [
    ({"method": "modal", "modal_options": {"f_keep": -5}}, errors.UsageError, "f_keep"),
    ({"method": "modal", "modal_options": {"f_keep": float("nan")}}, errors.UsageError, "f_keep"),
    ({"method": "modal", "modal_options": {"tol": -1}}, errors.UsageError, "tol"),
    ({"method": "modal", "modal_options": {"window": -3}}, errors.UsageError, "window"),
    ({"method": "modal", "modal_options": {"tool": 1}}, errors.UsageError, "did you mean 'tol'"),
    ({"method": "modal", "modal_options": [1]}, errors.ArgumentTypeError, "modal_options"),
    ({"max_order": 9}, errors.UsageError, "max_order"),
    ({"controllers": [42]}, errors.ArgumentTypeError, "SampledController"),
    ({"controllers": 42}, errors.ArgumentTypeError, "SampledController"),
    ({"jit": "no"}, errors.ArgumentTypeError, "jit"),
    ({"progress": "no"}, errors.ArgumentTypeError, "progress"),
    ({"method": "lti", "inputs": {"amp.u": 1e300}, "outputs": ["table.a"]}, errors.UsageError,
     "'amp.u' = 1e.300 on the interval"),
])
def test_simulate_arguments_checked(kw, error, words):
    from bscomp.simulation import simulate

    t = np.linspace(0.0, 0.01, 101)                 # long enough for 1e300 V to overflow
    with pytest.raises(error, match=words.replace("(", r"\(")):
        simulate("validation_drive", t, **kw)


def test_simulate_valid_modal_options_still_work():
    from bscomp.simulation import simulate

    r = simulate("validation_drive", T, method="modal", modal_options={"f_keep": None, "window": 0},
                 outputs=["table.a"], inputs={"amp.u": 1.0})
    assert np.all(np.isfinite(r["table.a"])) and np.max(np.abs(r["table.a"])) > 0


def test_simulate_model_without_states():
    from bscomp import System
    from bscomp.components import Gain, Saturation
    from bscomp.simulation import simulate

    s = System("static")
    s.add("g", Gain(k=2.0))
    s.add("sat", Saturation(y_max=1.0))
    s.connect("g.y", "sat.u")
    with pytest.raises(errors.UsageError, match="no states"):
        simulate(s, T)


@pytest.mark.parametrize("kw, words", [({"rtoll": 1}, "did you mean 'rtol'"), ({"inputs": {}}, "'inputs'"),
                                       ({"x0": {}}, "'x0'")])
def test_stepped_sine_options_named(kw, words):
    from bscomp.simulation import stepped_sine

    with pytest.raises(errors.UsageError, match=words):
        stepped_sine("validation_drive", "amp.u", "rotor.w", [10.0], 1.0, **kw)


# ---- 10: a heavy table does not make the rotor massless ------------------------------------------------------------
def test_heavy_table_keeps_light_coordinates(capsys):
    assert main(["modes", "validation_drive", "--set", "table.m=1e12"]) == 0
    out = capsys.readouterr().out
    assert "3 modes over 3 coordinates" in out and "massless" not in out


def test_massless_split_cases():
    assert massless_split(np.diag([1e12, 1e-3, 2.0]))[0].size == 0
    assert list(massless_split(np.diag([1.0, 0.0, 2.0]))[0]) == [1]
    assert list(massless_split(np.zeros((2, 2)))[0]) == [0, 1]
    noise = np.array([[1.0, 1e-17], [1e-17, 1e-17]])            # round-off of a coupled projection
    assert list(massless_split(noise)[0]) == [1]
    for M in (np.diag([1e12, 1e-3, 2.0]), np.diag([1.0, 0.0, 2.0]), np.zeros((2, 2)), noise, np.zeros((0, 0))):
        dense, sparse = massless_split(M), massless_split(sp.csr_matrix(M))    # the dense path: the same rule
        assert all(np.array_equal(a, b) for a, b in zip(dense, sparse, strict=True))


def test_a_system_file_returning_no_system_is_named_by_the_library(tmp_path):
    """bscomp.systems.get (the Python API) names the file when build() returns something else."""
    import bscomp.systems

    path = tmp_path / "b42.py"
    path.write_text("def build():\n    return 42\n")
    with pytest.raises(errors.ModelDefinitionError, match=r"b42.py: build\(\) returned int 42, not a bscomp.System"):
        bscomp.systems.get(str(path))


def test_main_puts_the_warning_format_back(tmp_path, capsys):
    """The CLI prints warnings on one line while it runs; a caller's later warnings keep Python's format."""
    import warnings

    before = warnings.formatwarning
    assert main(["modes", "validation_drive"]) == 0
    assert warnings.formatwarning is before
