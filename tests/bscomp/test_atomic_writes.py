"""Nothing half-written (issue 15, point 3): every writer of the library goes through ``bscomp.files``.

Each test writes a good file, then makes the writer fail midway (a row formatter, ``numpy.savetxt``, the
figure's ``savefig`` or the final ``fsync`` raising after part of the data is out) and checks that the old
file is intact byte for byte and that no temporary file is left in the folder.
"""

from __future__ import annotations

import types

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

import bscomp  # noqa: E402
from bscomp import files  # noqa: E402
from bscomp.errors import OutputFileError  # noqa: E402
from bscomp.plotting import base as plotting_base  # noqa: E402
from bscomp.systems import small_drive  # noqa: E402
from bscomp.validate import FrfData, TimeData, compare, write_report  # noqa: E402
from bscomp.validate import writers as measurement_writers  # noqa: E402
from bscomp.validate.calibration import Calibration  # noqa: E402
from bscomp.validate.diagnosis import Diagnosis  # noqa: E402


class Boom(RuntimeError):
    """The failure injected in the middle of a write."""


@pytest.fixture(scope="module")
def drive_frf():
    return bscomp.frf(small_drive(), "motor.tau", "table.s", np.linspace(5.0, 300.0, 40))


@pytest.fixture(scope="module")
def drive_modes():
    return bscomp.modes(small_drive())


def _frf_data(H):
    return FrfData(freqs=H.freqs, H={("motor.tau", "table.s"): H.H[:, 0, 0] * 1.1},
                   units={("motor.tau", "table.s"): "m/(N m)"}, source="test")


def _time_data():
    t = np.linspace(0.0, 0.1, 50)
    return TimeData(t=t, inputs={"motor.tau": np.sin(t)}, outputs={"table.s": np.cos(t)},
                    units={"motor.tau": "N m", "table.s": "m"}, source="test")


def _fail_after(n, exc=Boom):
    """A function that works ``n`` times, then raises (a formatter failing midway through the rows)."""
    calls = {"n": 0}

    def wrap(real):
        def f(*a, **k):
            calls["n"] += 1
            if calls["n"] > n:
                raise exc("injected failure midway")
            return real(*a, **k)
        return f
    return wrap


def _assert_intact(path, before):
    assert path.read_bytes() == before, f"{path.name} was changed by a failing write"
    leftovers = [p.name for p in path.parent.iterdir() if p.name != path.name]
    assert not leftovers, f"temporary files left behind: {leftovers}"


def _fail_at_fsync(monkeypatch):
    """The data are written to the temporary file, then the disk 'fills up' before the rename."""
    def fsync(fd):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(files.os, "fsync", fsync)


# ---- CSV -------------------------------------------------------------------------------------------------
def test_modes_csv_failing_midway_keeps_old_file(tmp_path, monkeypatch, drive_modes):
    path = tmp_path / "modes.csv"
    drive_modes.to_csv(path)
    before = path.read_bytes()
    import bscomp.linear.modal as modal
    monkeypatch.setattr(modal, "repr", _fail_after(3)(repr), raising=False)
    with pytest.raises(Boom):
        drive_modes.to_csv(path)
    _assert_intact(path, before)


def test_frf_csv_failing_midway_keeps_old_file(tmp_path, monkeypatch, drive_frf):
    path = tmp_path / "frf.csv"
    drive_frf.to_csv(path)
    before = path.read_bytes()
    import bscomp.linear.response as response
    monkeypatch.setattr(response, "repr", _fail_after(50)(repr), raising=False)
    with pytest.raises(Boom):
        drive_frf.to_csv(path)
    _assert_intact(path, before)


@pytest.mark.parametrize("kind", ["frf", "time"])
def test_measurement_csv_failing_midway_keeps_old_file(tmp_path, monkeypatch, drive_frf, kind):
    path = tmp_path / f"{kind}.csv"
    write = measurement_writers.write_frf_csv if kind == "frf" else measurement_writers.write_time_csv
    data = _frf_data(drive_frf) if kind == "frf" else _time_data()
    write(data, path)
    before = path.read_bytes()
    assert bscomp.validate.load(path) is not None
    with monkeypatch.context() as mp:       # a row that cannot be formatted, halfway through
        mp.setattr(measurement_writers, "_fmt", _fail_after(30)(measurement_writers._fmt))
        with pytest.raises(Boom):
            write(data, path)
    _assert_intact(path, before)
    _fail_at_fsync(monkeypatch)             # every row written, then the disk is full
    with pytest.raises(OSError, match="No space"):
        write(data, path)
    _assert_intact(path, before)


def test_simulation_csv_failing_in_savetxt_keeps_old_file(tmp_path, monkeypatch):
    res = bscomp.simulate(small_drive(), np.linspace(0.0, 0.01, 11), inputs={"motor.tau": 1.0})
    path = tmp_path / "sim.csv"
    res.to_csv(path)
    before = path.read_bytes()
    real = np.savetxt

    def savetxt(fname, X, **kw):
        real(fname, X[: len(X) // 2], **kw)         # half the rows are out, then the disk is full
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(np, "savetxt", savetxt)
    with pytest.raises(OSError, match="No space"):
        res.to_csv(path)
    _assert_intact(path, before)


# ---- JSON ------------------------------------------------------------------------------------------------
def _comparison(drive_frf):
    return compare(small_drive(), _frf_data(drive_frf))


def _stub(cls):
    """A Diagnosis/Calibration whose ``to_dict`` is small: only the writing is under test."""
    return types.SimpleNamespace(to_dict=lambda: {"kind": cls.__name__, "values": list(range(100))})


@pytest.mark.parametrize("what", ["modes", "frf", "comparison", "diagnosis", "calibration"])
def test_json_failing_before_rename_keeps_old_file(tmp_path, monkeypatch, drive_modes, drive_frf, what):
    write = {"modes": drive_modes.to_json, "frf": drive_frf.to_json,
             "comparison": _comparison(drive_frf).to_json,
             "diagnosis": lambda p: Diagnosis.to_json(_stub(Diagnosis), p),
             "calibration": lambda p: Calibration.to_json(_stub(Calibration), p)}[what]
    path = tmp_path / f"{what}.json"
    write(path)
    before = path.read_bytes()
    assert before.startswith(b"{")
    _fail_at_fsync(monkeypatch)
    with pytest.raises(OSError, match="No space"):
        write(path)
    _assert_intact(path, before)


def test_json_text_is_still_returned_without_a_path(drive_modes):
    assert drive_modes.to_json().startswith("{")


# ---- PNG -------------------------------------------------------------------------------------------------
def test_png_failing_in_savefig_keeps_old_figure(tmp_path, monkeypatch, drive_frf):
    path = tmp_path / "bode.png"
    drive_frf.plot(path)
    before = path.read_bytes()
    assert before.startswith(b"\x89PNG")
    from matplotlib.figure import Figure
    seen = []

    def savefig(self, fname, **kw):
        seen.append(str(fname))
        with open(fname, "wb") as fh:
            fh.write(b"\x89PNG half")             # part of the figure is out, then the writer fails
        raise Boom("injected failure in savefig")
    monkeypatch.setattr(Figure, "savefig", savefig)
    with pytest.raises(Boom):
        drive_frf.plot(path)
    assert seen and seen[0].endswith(".png"), "the temporary name must keep the suffix (format by extension)"
    _assert_intact(path, before)


@pytest.mark.parametrize("suffix", [".svg", ".pdf"])
def test_figure_format_still_follows_the_extension(tmp_path, drive_frf, suffix):
    path = tmp_path / f"bode{suffix}"
    drive_frf.plot(path)
    head = path.read_bytes()[:200]
    assert (b"<svg" in head or b"<?xml" in head) if suffix == ".svg" else head.startswith(b"%PDF")


def test_unknown_figure_extension_is_refused_before_writing(tmp_path, drive_frf):
    with pytest.raises(OutputFileError, match=r"bode\.xyz.*\.xyz.*\.png"):
        drive_frf.plot(tmp_path / "bode.xyz")
    assert list(tmp_path.iterdir()) == []


def test_save_figure_is_the_only_savefig_in_plotting():
    """Every figure writer goes through ``save_figure`` (atomic, suffix kept)."""
    import inspect
    import re

    from bscomp.plotting import control, validate
    for mod in (plotting_base, control, validate):
        calls = re.findall(r"^\s+[\w.]*\.savefig\((\w+)", inspect.getsource(mod), re.M)
        assert calls == (["tmp"] if mod is plotting_base else []), mod.__name__


# ---- the HTML report -------------------------------------------------------------------------------------
class _Result:
    """A Diagnosis-like object for the report; ``fail`` makes its figures fail after the first one."""

    def __init__(self, fail=False):
        self.fail = fail

    def table(self):
        return "candidate  drop\nbacklash   90 %"

    def plot(self, d):
        d.mkdir(parents=True, exist_ok=True)
        (d / "a.png").write_bytes(b"\x89PNG new")
        if self.fail:
            raise Boom("injected failure while drawing the second figure")
        return [d / "a.png"]


def _snapshot(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_report_failing_midway_keeps_old_report(tmp_path):
    out = tmp_path / "report"
    index = write_report([_Result()], out)
    assert index == out / "index.html" and index.read_text().startswith("<!DOCTYPE html>")
    before = _snapshot(out)
    with pytest.raises(Boom):
        write_report([_Result(), _Result(fail=True)], out)
    assert _snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["report"], "temporary folders left behind"


def test_report_failing_the_first_time_leaves_nothing(tmp_path):
    with pytest.raises(Boom):
        write_report([_Result(fail=True)], tmp_path / "report")
    assert list(tmp_path.iterdir()) == []


def test_report_failing_in_html_keeps_old_report(tmp_path, monkeypatch):
    import bscomp.validate.report as report
    out = tmp_path / "report"
    write_report([_Result()], out)
    before = _snapshot(out)
    monkeypatch.setattr(report, "_document", _fail_after(0)(report._document))
    with pytest.raises(Boom):
        write_report([_Result()], out)
    assert _snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["report"]


def test_report_never_replaces_a_folder_bscomp_did_not_write(tmp_path):
    mine = tmp_path / "thesis"
    mine.mkdir()
    (mine / "chapter1.tex").write_text("precious")
    with pytest.raises(OutputFileError, match=r"thesis.*chapter1\.tex"):
        write_report([_Result()], mine)
    assert (mine / "chapter1.tex").read_text() == "precious" and len(list(mine.iterdir())) == 1
