"""Writers and exporters refuse bad arguments with a named error before writing anything.

FMU export (duplicate or split names, flags, a "compiler" that compiles nothing), the HTML report (objects
that are no result, swapped arguments), JSON/CSV files with the wrong extension or no file name at all,
SimulationResult indexing and signal names, and validation plots into a file instead of a folder.
"""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest

import bscomp
from bscomp.errors import ArgumentTypeError, BscompError, FmuExportError, OutputFileError, UsageError
from bscomp.fmu import export_fmu
from bscomp.simulation.result import SimulationResult
from bscomp.systems import get
from bscomp.validate.comparison import Comparison
from bscomp.validate.diagnosis import Diagnosis
from bscomp.validate.report import write_report

needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc to compile an FMU")


def _listing(folder):
    return sorted(p.name for p in folder.iterdir())


# ---- FMU export --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kw, what, name", [
    ({"inputs": ["motor.tau", "motor.tau"]}, "inputs", "motor.tau"),
    ({"outputs": ["table.s", "table.a", "table.s"]}, "outputs", "table.s"),
    ({"parameters": ["rotor.J", "rotor.J"]}, "parameters", "rotor.J"),
])
def test_fmu_refuses_a_name_listed_twice(tmp_path, kw, what, name):
    with pytest.raises(UsageError, match=rf"export_fmu: {what} lists '{name}' twice: give each name once"):
        export_fmu("small_drive", tmp_path / "d.fmu", **kw)
    assert _listing(tmp_path) == []


@pytest.mark.parametrize("kw, match", [
    ({"inputs": 3}, r"export_fmu: inputs must be a name or a list of names .*got int 3"),
    ({"outputs": [1.0]}, r"export_fmu: outputs must be a name or a list of names"),
    ({"flags": 2}, r"export_fmu: flags must be a string .* or a list of strings"),
    ({"flags": ["-O2", None]}, r"export_fmu: flags must be"),
])
def test_fmu_refuses_arguments_of_the_wrong_type(tmp_path, kw, match):
    with pytest.raises(ArgumentTypeError, match=match):
        export_fmu("small_drive", tmp_path / "t.fmu", **kw)
    assert _listing(tmp_path) == []


def _fmu_variables(path):
    with zipfile.ZipFile(path) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    return [(v.get("name"), v.get("causality")) for v in root.find("ModelVariables")]


@needs_gcc
def test_fmu_one_string_is_one_name_and_flags_may_be_a_string(tmp_path):
    path = export_fmu("small_drive", tmp_path / "s.fmu", inputs="motor.tau", outputs="table.a",
                      parameters="table.m", flags="-O1 -g0")
    variables = _fmu_variables(path)
    names = [n for n, _ in variables]
    assert len(names) == len(set(names))
    assert [n for n, c in variables if c == "input"] == ["motor.tau"]
    assert [n for n, c in variables if c == "output"] == ["table.a"]
    assert [n for n, c in variables if c == "parameter"] == ["table.m"]


@needs_gcc
def test_fmu_compiler_that_compiles_nothing_is_an_error(tmp_path):
    true = shutil.which("true")
    if true is None:
        pytest.skip("no 'true' program")
    with pytest.raises(FmuExportError, match=r"with 'true' reported success but .*fmi3InstantiateModelExchange.*"
                                             r"nothing was written"):
        export_fmu("small_drive", tmp_path / "g.fmu", compiler="true")
    assert _listing(tmp_path) == []


# ---- SimulationResult ----------------------------------------------------------------------------------
@pytest.fixture
def result():
    t = np.linspace(0.0, 1.0, 11)
    x = np.column_stack([t, 2 * t])
    return SimulationResult(t=t, x=x, xd=np.ones_like(x), z=np.zeros((11, 0)), u=np.zeros((11, 1)),
                            x_names=["table.s", "table.v"], z_names=[], u_names=["motor.tau"],
                            outputs={"table.s": t, "table.a": 0 * t})


@pytest.mark.parametrize("key", [slice(0, 5), 0, ("table.s", "table.a")])
def test_result_indexed_by_something_else_than_a_name(result, key):
    with pytest.raises(ArgumentTypeError, match=r"indexed by one signal name .*time window.*r\.t >= t0"):
        result[key]


@pytest.mark.parametrize("name", ["f.png", "f.xyz", "f"])
def test_result_csv_needs_the_csv_extension(result, tmp_path, name):
    with pytest.raises(OutputFileError, match=rf"SimulationResult.to_csv: path '.*{name}' has the extension.*\.csv"):
        result.to_csv(tmp_path / name)
    assert _listing(tmp_path) == []


@pytest.mark.parametrize("path", [None, 5, ["a.csv"]])
def test_result_csv_path_of_the_wrong_type(result, path):
    with pytest.raises(ArgumentTypeError, match=r"SimulationResult.to_csv: path must be a file name"):
        result.to_csv(path)


def test_result_csv_names(result, tmp_path):
    p = tmp_path / "a.csv"
    result.to_csv(p, names="table.s")
    assert p.read_text().splitlines()[0] == "t,table.s"
    result.to_csv(p, names=["table.a", "table.v"])                 # overwritten in place
    assert p.read_text().splitlines()[0] == "t,table.a,table.v"
    with pytest.raises(UsageError, match=r"to_csv: names lists 'table.s' twice"):
        result.to_csv(tmp_path / "b.csv", names=["table.s", "table.s"])
    with pytest.raises(ArgumentTypeError, match=r"to_csv: names must be a name or a list of names"):
        result.to_csv(tmp_path / "b.csv", names=3)
    assert _listing(tmp_path) == ["a.csv"]


def test_result_plot_names_and_path(result, tmp_path):
    fig = result.plot("table.s", path=tmp_path / "p.png")
    assert len(fig.axes) == 1 and fig.axes[0].get_ylabel() == "table.s"
    assert (tmp_path / "p.png").stat().st_size > 0
    with pytest.raises(ArgumentTypeError, match=r"SimulationResult.plot: path must be a file name"):
        result.plot(path=3)
    with pytest.raises(OutputFileError, match=r"figure file '.*p\.csv' has the extension '\.csv'"):
        result.plot(path=tmp_path / "p.csv")
    assert _listing(tmp_path) == ["p.png"]


# ---- Comparison / Diagnosis: JSON and figure folders ------------------------------------------------------
@pytest.fixture
def comparison():
    return Comparison(system="small_drive", frf=[], time=[], cost=0.5, signatures={})


@pytest.fixture
def diagnosis():
    return Diagnosis(system=get("small_drive"), uncertain=[], recalibrated={}, ranked=[], accepted=[], rounds=[],
                     staircase=[("nominal", 4.0), ("re-calibrated", 1.5)], message="nothing found")


@pytest.mark.parametrize("kind", ["comparison", "diagnosis"])
def test_to_json_checks_the_path(request, tmp_path, kind):
    obj = request.getfixturevalue(kind)
    cls = type(obj).__name__
    for name in ("x.png", "x.xyz"):
        with pytest.raises(OutputFileError, match=rf"{cls}.to_json: path '.*{name}' has the extension.*\.json"):
            obj.to_json(tmp_path / name)
    with pytest.raises(ArgumentTypeError, match=rf"{cls}.to_json: path must be a file name .*got int 3"):
        obj.to_json(3)
    assert _listing(tmp_path) == []
    text = obj.to_json(tmp_path / "x.json")
    assert json.loads((tmp_path / "x.json").read_text()) == json.loads(text)


@pytest.mark.parametrize("kind, arg", [("comparison", "out_dir"), ("diagnosis", "directory")])
def test_plot_into_a_file_or_no_folder(request, tmp_path, kind, arg):
    obj = request.getfixturevalue(kind)
    cls = type(obj).__name__
    mine = tmp_path / "notes.txt"
    mine.write_text("mine")
    with pytest.raises(OutputFileError, match=rf"{cls}.plot: {arg} '.*notes.txt' is a file, not a folder"):
        obj.plot(mine)
    assert mine.read_text() == "mine"
    with pytest.raises(ArgumentTypeError, match=rf"{cls}.plot: {arg} must be a folder name .*got NoneType"):
        obj.plot(None)
    with pytest.raises(OutputFileError, match=rf"{cls}.plot: {arg} '.*fig.png' looks like a figure file.*"
                                              r"folder name, e.g. '.*fig'"):
        obj.plot(tmp_path / "fig.png")
    assert _listing(tmp_path) == ["notes.txt"]


def test_diagnosis_plot_twice_into_the_same_folder(diagnosis, tmp_path):
    first = diagnosis.plot(tmp_path / "figs")
    second = diagnosis.plot(tmp_path / "figs")                       # figures are replaced, not refused
    assert first == second and all(p.stat().st_size > 0 for p in second)
    assert _listing(tmp_path / "figs") == ["candidates.png", "error_staircase.png"]


def test_the_candidates_figure_has_a_panel_per_round_with_what_each_round_accepted(tmp_path):
    """Round 2's accepted effect is drawn in its own round (the round-1 chart alone showed a table part at its
    7 % screening value, green, beside the 99 % it removed in round 2); a screened-only candidate has no bar; an
    error increase beyond CLIP_PERCENT is clipped and its value written."""
    from types import SimpleNamespace

    import matplotlib
    import matplotlib.pyplot as plt

    from bscomp.plotting.validate import CLIP_PERCENT, _round_bars
    from bscomp.validate.diagnosis import EffectFit

    def fit(name, before, after, refined=True, rnd=1):
        return EffectFit(SimpleNamespace(name=name), {}, {}, before, after, -1.0, refined=refined, round=rnd)

    round1 = [fit("friction", 1e6, 100.0), fit("inertia", 1e6, 2e5), fit("part", 1e6, 9.3e5, refined=False)]
    round2 = [fit("part", 100.0, 1.3, rnd=2), fit("joint", 100.0, 800.0, rnd=2), fit("delay", 100.0, 1e5, False, 2)]
    fig, ax = plt.subplots()
    _round_bars(ax, round2, {"part"}, 2)
    widths = [b.get_width() for b in ax.patches][::-1]                  # best-ranked first
    colors = [matplotlib.colors.to_hex(b.get_facecolor()) for b in ax.patches][::-1]
    labels = [t.get_text() for t in ax.get_yticklabels()][::-1]
    texts = [t.get_text() for t in ax.texts]
    plt.close(fig)
    assert widths == pytest.approx([98.7, CLIP_PERCENT, 0.0])
    assert colors[0] == matplotlib.colors.to_hex("tab:green") and colors[1] == matplotlib.colors.to_hex("tab:gray")
    assert labels == ["part", "joint", "delay (screened only)"]
    assert texts == [" -700 %"]
    part = round2[0]
    diag = Diagnosis(system=None, uncertain=[], recalibrated={}, ranked=round1, accepted=[round1[0], part],
                     rounds=[round1, round2], staircase=[("nominal", 1e6), ("+ friction", 100.0), ("+ part", 1.3)],
                     message="2 found")
    paths = diag.plot(tmp_path)
    assert [p.name for p in paths] == ["error_staircase.png", "candidates.png"]
    assert all(p.stat().st_size > 0 for p in paths)


# ---- write_report ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("obj, error, match", [
    ("hello", ArgumentTypeError, r"write_report: got str 'hello', not a result to report: give a Comparison"),
    (3, ArgumentTypeError, r"write_report: got int 3, not a result to report"),
    ([], UsageError, r"write_report: nothing to report \(an empty list\)"),
    (None, ArgumentTypeError, r"write_report: got NoneType None"),
])
def test_report_refuses_what_is_no_result(tmp_path, obj, error, match):
    with pytest.raises(error, match=match):
        write_report(obj, tmp_path / "report")
    assert _listing(tmp_path) == []


def test_report_names_the_bad_item_of_a_list(tmp_path, comparison):
    with pytest.raises(ArgumentTypeError, match=r"item 1 of the list is str 'x'"):
        write_report([comparison, "x"], tmp_path / "report")
    assert _listing(tmp_path) == []


def test_report_arguments_swapped(tmp_path, comparison):
    with pytest.raises(ArgumentTypeError, match=r"arguments are swapped .*call write_report\(result, out_dir\)"):
        write_report(tmp_path / "report", comparison)
    with pytest.raises(ArgumentTypeError, match=r"swapped"):
        write_report(str(tmp_path / "report"), [comparison])
    with pytest.raises(ArgumentTypeError, match=r"write_report: out_dir must be a folder name"):
        write_report(comparison, 3)
    assert _listing(tmp_path) == []


def test_report_of_results_still_written(tmp_path, comparison, diagnosis):
    index = write_report([comparison, diagnosis], tmp_path / "report")
    html = index.read_text()
    assert "Comparison 1" in html and "Diagnosis 2" in html and "error_staircase.png" in html


@pytest.mark.parametrize("write, name", [
    (lambda tmp: bscomp.frf("small_drive", "motor.tau", "table.s", [10.0, 20.0]).to_csv(tmp / "h.png"), "Frf.to_csv"),
    (lambda tmp: bscomp.frf("small_drive", "motor.tau", "table.s", [10.0, 20.0]).to_json(tmp / "h.csv"),
     "Frf.to_json"),
    (lambda tmp: bscomp.modes("small_drive").to_csv(tmp / "m.json"), "Modes.to_csv"),
    (lambda tmp: bscomp.modes("small_drive").to_json(tmp / "m.txt"), "Modes.to_json"),
])
def test_every_result_writer_checks_its_suffix(tmp_path, write, name):
    """CSV into x.png or JSON into x.csv is refused by name, and nothing is written."""
    with pytest.raises(BscompError, match=name):
        write(tmp_path)
    assert not list(tmp_path.iterdir())


def test_figure_titles_fit_and_band_ticks_read_in_hertz():
    """A data file's source can be a long sentence: titles are wrapped to the figure (the time overlay's was cut at
    both ends); band centres read 125, 250, 500, 1000 Hz, not 1e+03."""
    from bscomp.plotting.validate import _hz, _wrapped

    src = "synthetic square-wave run of an FE test-bed truth (bscomp.systems.truths, seed 1305; see truth.json)"
    lines = _wrapped(src + ": measured vs model (shaded: windows carrying most error)", 90).split("\n")
    assert len(lines) == 2 and max(map(len, lines)) <= 90 and " ".join(lines).startswith(src)
    assert [_hz(f) for f in (1.953, 15.63, 62.5, 125.0, 999.7, 1000.0)] == ["1.95", "15.6", "62.5", "125", "1000",
                                                                           "1000"]
