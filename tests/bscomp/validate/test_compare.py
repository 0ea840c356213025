"""compare(): data generated from small_drive itself, a mis-set coupling, peak picking, resid, signatures,
plots, JSON, HTML report and the CLI."""

import json

import numpy as np
import pytest

from bscomp.modal import modes
from bscomp.systems import small_drive
from bscomp.validate import (
    FrfData,
    MeasurementFileError,
    TimeData,
    compare,
    cost,
    fit_percent,
    frf_residuals,
    model_frf,
    model_time,
    peak_pick,
    resid,
    time_residuals,
    write_frf_csv,
    write_report,
    write_time_csv,
)

K_T = 3938.0
FREQS = np.logspace(1, 3, 400)
T = np.arange(0.0, 0.2, 2e-4)
U = np.sign(np.sin(2 * np.pi * 10 * T + 1e-9))   # square-wave torque, 1 N m
FRF_UNITS = {("motor.tau", "rotor.w"): "rad/s/(N m)", ("motor.tau", "table.a"): "m/s^2/(N m)"}


def frf_data(system, **kw):
    d = FrfData(FREQS, {p: np.zeros(FREQS.size, complex) for p in FRF_UNITS}, units=dict(FRF_UNITS), **kw)
    d.H = model_frf(system, d)
    return d


def time_data(system, **kw):
    d = TimeData(T, {"motor.tau": U}, {"rotor.w": np.zeros_like(T), "table.a": np.zeros_like(T)},
                 units={"motor.tau": "N m", "rotor.w": "rad/s", "table.a": "m/s^2"}, **kw)
    d.outputs = model_time(system, d)
    return d


@pytest.fixture(scope="module")
def own():
    s = small_drive()
    return [frf_data(s, source="own_frf"), time_data(s, source="own_time")]


@pytest.fixture(scope="module")
def soft():
    """'Truth' with the coupling 30 % softer than the model believes."""
    s = small_drive(k_T=0.7 * K_T)
    return [frf_data(s, source="soft_frf"), time_data(s, source="soft_time")]


def test_model_reproduces_its_own_data(own, tmp_path):
    s = small_drive()
    assert np.max(np.abs(frf_residuals(model_frf(s, own[0]), own[0]))) < 1e-12
    assert np.max(np.abs(time_residuals(model_time(s, own[1]), own[1]))) < 1e-12
    assert cost(s, own) < 1e-20
    # through files, with the build function and the system name
    paths = [write_frf_csv(own[0], tmp_path / "f.csv"), write_time_csv(own[1], tmp_path / "t.csv")]
    for model in (small_drive, "small_drive"):
        c = compare(model, paths)
        assert c.cost < 1e-20
        assert all(v > 99.999 for fc in c.frf for v in fc.fit.values())
        assert all(v > 99.999 for v in c.time[0].fit.values())
        assert not c.frf[0].unmatched_measured and not c.frf[0].unmatched_model
        assert len(c.frf[0].paired) == 2


def test_cost_increases_when_a_parameter_is_mis_set(own):
    c0 = cost(small_drive, own)
    c1 = cost(small_drive, own, {"coupling.c": 0.85 * K_T})
    c2 = cost(small_drive, own, {"coupling.c": 0.7 * K_T})
    assert c0 < 1e-20 < c1 < c2


def test_soft_coupling_shows_in_mode_table_and_fit(soft):
    c = compare(small_drive, soft)
    nominal = modes(small_drive(), inputs=["motor.tau"], outputs=["table.a"])
    truth = modes(small_drive(k_T=0.7 * K_T), inputs=["motor.tau"], outputs=["table.a"])
    fc = c.frf[0]
    assert len(fc.paired) == 2 and not fc.unmatched_measured and not fc.unmatched_model
    for m, fn, ft in zip(fc.paired, nominal.frequencies[1:], truth.frequencies[1:]):
        expected = 100 * (fn - ft) / ft
        assert m.model_f == pytest.approx(fn)
        assert m.measured.f == pytest.approx(ft, rel=0.012)
        assert m.freq_error_pct == pytest.approx(expected, abs=1.3)
    assert fc.paired[1].freq_error_pct > 12            # the coupling mode moves most (sqrt(1/0.7) ~ +20 %)
    assert min(fc.fit.values()) < 80 and min(c.time[0].fit.values()) < 95
    # the band holding the shifted coupling mode carries the error
    lo, hi, share = fc.worst_bands()[0]
    assert lo < truth.frequencies[2] < hi and share > 0.5
    text = c.summary()
    assert "frequency error" in text and f"{lo:.3g}-{hi:.3g} Hz" in text
    assert c.cost > 1e-3
    assert all(-1 <= v <= 1 for v in c.signatures.values())
    assert c.evidence["frf_max_freq_error_pct"] == pytest.approx(fc.paired[1].freq_error_pct)


def test_conditions_reach_the_build_function():
    truth = small_drive(k_T=0.7 * K_T)
    d = frf_data(truth, conditions={"k_T": 0.7 * K_T, "operator": "x"})
    assert cost(small_drive, [d]) < 1e-20               # build(k_T=...) used, unknown condition dropped
    assert cost(small_drive(), [d]) > 1e-3              # a System is used as is


def test_peak_picking_recovers_a_known_resonance():
    # small_drive's coupling mode seen in the table acceleration: pole magnitude and damping from modes()
    md = modes(small_drive(), inputs=["motor.tau"], outputs=["table.a"])
    p = md.poles[2]
    f_true, zeta_true = np.abs(p[0]) / (2 * np.pi), -p[0].real / np.abs(p[0])
    H = frf_data(small_drive()).H[("motor.tau", "table.a")]
    res = [r for r in peak_pick(FREQS, H) if r.f > 200]
    assert len(res) == 1
    assert res[0].f == pytest.approx(f_true, rel=0.01)
    assert res[0].zeta == pytest.approx(zeta_true, rel=0.10)
    # single-mode receptance: half-power estimate alone (no refinement) within 1 % / 10 %
    fn, z = 150.0, 0.02
    f = np.linspace(100, 200, 501)
    s = 2j * np.pi * f
    h = 1 / (s ** 2 + 2 * z * 2 * np.pi * fn * s + (2 * np.pi * fn) ** 2)
    r = peak_pick(f, np.abs(h), refine=False)[0]
    assert r.f == pytest.approx(fn, rel=0.01) and r.zeta == pytest.approx(z, rel=0.10)


def test_resid_flags_a_residual_that_follows_the_input():
    rng = np.random.default_rng(0)
    n = 4000
    u = np.sign(np.sin(np.arange(n) * 2 * np.pi / 200)) + 0.3 * rng.standard_normal(n)
    noise = rng.standard_normal(n)
    ok = resid(noise, u)
    assert ok.white and ok.independent
    bad = resid(noise + 0.5 * np.convolve(u, np.ones(5) / 5, mode="same"), u)
    assert not bad.independent and not bad.white
    assert np.max(np.abs(bad.xcf)) > bad.xcf_bound


def test_signatures_point_at_coulomb_friction(own):
    # measured = model minus a Coulomb force F_c sign(v) on the 250 kg table (acceleration channel)
    s = small_drive()
    d = own[1]
    from bscomp.validate.residuals import simulate_for

    res, _ = simulate_for(s, d, extra=["table.v"])
    v = res["table.v"]
    meas = dict(d.outputs)
    meas["table.a"] = d.outputs["table.a"] - 40.0 / 250.0 * np.sign(v)
    d2 = TimeData(d.t, d.inputs, meas, units=d.units, source="friction")
    c = compare(s, [d2])
    sig = c.signatures
    assert sig["sign_velocity"] < -0.9
    assert abs(sig["sign_velocity"]) > max(abs(sig[k]) for k in ("velocity", "acceleration", "screw_stretch",
                                                                   "input", "position"))
    assert c.time[0].fit["table.a"] < 99 and "sign_velocity" in c.summary()


def test_fit_percent():
    y = np.array([1.0, 2.0, 3.0])
    assert fit_percent(y, y) == 100.0
    assert fit_percent(np.full(3, 2.0), y) == pytest.approx(0.0)
    assert fit_percent(1j * y, 1j * y) == 100.0


def test_unknown_model_channel_names_the_column(tmp_path):
    d = TimeData(T[:5], {"motor.tau": U[:5]}, {"table.q": np.zeros(5)}, units={"motor.tau": "N m", "table.q": "m"})
    p = write_time_csv(d, tmp_path / "q.csv")
    with pytest.raises(MeasurementFileError) as ei:
        compare(small_drive, [p])
    assert ei.value.line is not None and ei.value.column == 3 and "table.q" in str(ei.value)


def test_plots_json_report_and_cli(soft, tmp_path, capsys):
    from bscomp.cli import main

    c = compare(small_drive, soft)
    pngs = c.plot(tmp_path / "figs")
    assert len(pngs) == 5 and all(p.stat().st_size > 1000 for p in pngs)
    d = json.loads(c.to_json(tmp_path / "c.json"))
    assert d["cost"] == pytest.approx(c.cost) and d["frf"][0]["modes"][1]["freq_error_pct"] > 12
    index = write_report(c, tmp_path / "report")
    html = index.read_text()
    assert "mode pairing" in html and "<img src='comparison1/" in html
    assert all((index.parent / src).is_file() for src in
               [s.split("'")[0] for s in html.split("<img src='")[1:]])
    paths = [write_frf_csv(soft[0], tmp_path / "soft_frf.csv"), write_time_csv(soft[1], tmp_path / "soft_t.csv")]
    assert main(["compare", "small_drive", *map(str, paths), "--json", "--set", "axial.c=1e8",
                 "--report", str(tmp_path / "r2")]) == 0
    assert json.loads(capsys.readouterr().out)["cost"] == pytest.approx(c.cost, rel=1e-6)
    assert (tmp_path / "r2" / "index.html").is_file()


def test_report_renders_other_results(tmp_path):
    class Dummy:
        def table(self):
            return "candidate  drop\nbacklash   90 %"

        def code(self):
            return 's.add("gap", Backlash(b=1e-5))'

        def plot(self, d):
            return []

    html = write_report([Dummy()], tmp_path).read_text()
    assert "backlash   90 %" in html and "Backlash(b=1e-5)" in html
