"""compare(): data generated from small_drive itself, a mis-set coupling, peak picking (modal fit) on
synthetic and test-bed FRFs, conditions, the user-facing errors, resid, signatures, plots, JSON, HTML report
and the CLI."""

import json
import warnings

import numpy as np
import pytest

from bscomp.linear.modal import modes
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
from bscomp.validate.comparison import user_errors
from bscomp.validate.residuals import ConditionIgnoredWarning, build_for

K_T = 3938.0
FREQS = np.logspace(1, 3, 400)
T = np.arange(0.0, 0.2, 2e-4)
U = np.sign(np.sin(2 * np.pi * 10 * T + 1e-9))   # square-wave torque, 1 N m
FRF_UNITS = {("motor.tau", "rotor.w"): "rad/s/(N m)", ("motor.tau", "table.a"): "m/s^2/(N m)"}


def pole_freqs(md):
    """|p| / 2 pi of each mode's damped pole pair (what the modal fit estimates)."""
    return np.array([np.sqrt(abs(np.prod(p))) / (2 * np.pi) for p in md.poles])


def frf_data(system, conditions=None, **kw):
    d = FrfData(FREQS, {p: np.zeros(FREQS.size, complex) for p in FRF_UNITS}, units=dict(FRF_UNITS), **kw)
    d.H = model_frf(system, d)
    d.conditions = dict(conditions or {})           # the file's conditions (the data come from `system`)
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
    for m, fn, ft in zip(fc.paired, pole_freqs(nominal)[1:], pole_freqs(truth)[1:]):
        expected = 100 * (fn - ft) / ft
        assert m.model_f == pytest.approx(fn)
        assert m.measured.f == pytest.approx(ft, rel=1e-3)        # noise-free data: the modal fit is exact
        assert m.freq_error_pct == pytest.approx(expected, abs=0.1)
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
    d = frf_data(truth, conditions={"k_T": 0.7 * K_T, "operator": "x"}, source="run7.csv")
    with pytest.warns(ConditionIgnoredWarning, match="run7.csv: condition 'operator' ignored: not a build "
                      "argument of system 'small_drive'") as rec:
        assert cost(small_drive, [d]) < 1e-20           # build(k_T=...) used, unknown condition dropped
    assert len(rec) == 1 and "\n" not in str(rec[0].message)
    with pytest.warns(ConditionIgnoredWarning) as rec:
        assert cost(small_drive(), [d]) > 1e-3          # a System is used as is
    assert sorted(str(w.message) for w in rec) == [
        f"run7.csv: condition '{k}' ignored: the model was given as a built System (pass its build function or "
        "name to honour it)" for k in ("k_T", "operator")]


def test_conditions_of_a_registered_system_behave_like_a_callables(tmp_path):
    # validation_drive takes no nut_position: the condition is dropped with one warning line, not an error
    s = __import__("bscomp.systems", fromlist=["validation_drive"]).validation_drive()
    units = {("amp.u", "rotor.w"): "rad/s/V", ("amp.u", "table.a"): "m/s^2/V"}
    d = FrfData(FREQS, {p: np.zeros(FREQS.size, complex) for p in units}, units=units)
    d.H = model_frf(s, d)
    d.conditions = {"nut_position": 0.4, "table.m": 250.0}
    t = TimeData(T, {"amp.u": U}, {"table.s": np.zeros_like(T)}, units={"amp.u": "V", "table.s": "m"})
    t.outputs = model_time(s, t)
    t.conditions = {"nut_position": 0.4}
    paths = [write_frf_csv(d, tmp_path / "f.csv"), write_time_csv(t, tmp_path / "t.csv")]
    for model in ("validation_drive", __import__("bscomp.systems", fromlist=["x"]).validation_drive):
        with pytest.warns(ConditionIgnoredWarning) as rec:
            c = compare(model, paths)
        msgs = [str(w.message) for w in rec if w.category is ConditionIgnoredWarning]
        assert len(msgs) == 2 and all("condition 'nut_position' ignored: not a build argument of system "
                                      "'validation_drive' (build arguments: k_axial)" in m for m in msgs)
        assert c.cost < 1e-18
    # a dotted condition is a parameter override, with no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert build_for("validation_drive", {"table.m": 260.0}).get("table.m") == 260.0
        assert build_for(s, {"table.m": 260.0}).get("table.m") == 260.0
        assert s.get("table.m") == 250.0                # a System given is copied, not changed
    # a .py file: build()'s signature is read from the file
    f = tmp_path / "my_drive.py"
    f.write_text("from bscomp.systems import validation_drive\n\n\ndef build(k_axial=1.357e8):\n"
                 "    return validation_drive(k_axial=k_axial)\n")
    with pytest.warns(ConditionIgnoredWarning, match="'nut_position' ignored: not a build argument of system "
                      f"'{f}'"):
        assert build_for(str(f), {"nut_position": 0.4, "k_axial": 1e8}).get("axial.c") == pytest.approx(1e8)


def _testbed_input(system):
    from bscomp.kernel.flattening import flatten

    return next(n for n in flatten(system).u_names if n != "Fd.f")


def _testbed_frf(system, freqs, seed, **kw):
    """The test bed's FRF to rotor.w and table.a with 2 % complex noise (seeded)."""
    from bscomp.linear.response import frf

    u = _testbed_input(system)
    unit = {"tau": "N m", "u": "V", "f": "N"}.get(u.rsplit(".", 1)[-1], "1")
    outs = {"rotor.w": "rad/s", "table.a": "m/s^2"}
    r = frf(system, input=[u], output=list(outs), freqs=freqs)
    rng = np.random.default_rng(seed)
    H = {}
    for o in outs:
        noise = (rng.standard_normal(freqs.size) + 1j * rng.standard_normal(freqs.size)) / np.sqrt(2)
        H[(u, o)] = r.response(o, u) * (1 + 0.02 * noise)
    return FrfData(freqs, H, units={(u, o): f"{un}/({unit})" for o, un in outs.items()}, **kw)


@pytest.mark.parametrize("name", ["testbed_axial_torsional", pytest.param("testbed", marks=pytest.mark.slow)])
def test_testbed_resonances_paired_by_their_poles(name):
    # model and 'measurement' share every mode: no false mode-shift alarm on the 10 %-damped second mode
    from bscomp.systems import get

    s = get(name)
    f = np.logspace(0, 3, 600)
    d = _testbed_frf(s, f, seed=3, source="noisy")
    c = compare(s, [d])
    fc = c.frf[0]
    assert not fc.unmatched_measured and not fc.unmatched_model
    assert len(fc.paired) == 2                           # 118.9 Hz (6 %), 275.1 Hz (10 %); lateral modes unseen
    md = modes(s, inputs=d.inputs, outputs=d.outputs, fmax=1100)
    el = np.flatnonzero(~md.rigid_body)
    for m in fc.paired:
        k = el[np.argmin(np.abs(md.frequencies[el] - m.model_f))]
        assert m.model_f == pytest.approx(md.frequencies[k], rel=1e-4)
        assert abs(m.freq_error_pct) < 1.0
        assert m.measured.zeta == pytest.approx(md.damping[k], rel=0.2)
        assert m.measured.refined
    assert fc.paired[1].model_zeta == pytest.approx(0.1, abs=0.005)
    # the raw peak of the 10 %-damped mode is 5 % off (it sits just above an antiresonance in rotor.w)
    assert abs(fc.paired[1].measured.f_peak / fc.paired[1].model_f - 1) > 0.03
    assert abs(c.evidence["frf_max_freq_error_pct"]) < 1.0 and "no model counterpart" not in c.summary()


def test_nut_position_condition_reaches_the_test_bed():
    # the file's nut position is honoured by the test-bed builders (testbed_*(**kw) forward to testbed(...))
    from bscomp.systems import get

    f = np.logspace(np.log10(60), np.log10(400), 200)
    first = {}
    for x in (0.2, 0.7):
        d = _testbed_frf(get("testbed_axial_torsional", {"nut_position": x}), f, seed=1,
                         conditions={"nut_position": x})
        with warnings.catch_warnings():
            warnings.simplefilter("error", ConditionIgnoredWarning)
            fc = compare("testbed_axial_torsional", [d]).frf[0]
        assert len(fc.paired) == 2 and not fc.unmatched_measured and not fc.unmatched_model
        assert all(abs(m.freq_error_pct) < 1.0 for m in fc.paired)
        first[x] = fc.paired[0].model_f
    # thesis L/R trend (Table 4.1): the first axial mode rises as the nut moves away from the motor end
    assert first[0.7] > 1.1 * first[0.2]


def test_modal_fit_two_modes_with_known_poles():
    # acceleration, velocity and displacement FRFs of a rigid body plus two modes (zeta 0.1 and 0.06)
    f = np.logspace(1, 3, 500)
    s = 2j * np.pi * f
    for (f1, z1), (f2, z2) in [((100.0, 0.10), (160.0, 0.06)), ((150.0, 0.06), (220.0, 0.10)),
                               ((100.0, 0.10), (125.0, 0.06))]:
        w1, w2 = 2 * np.pi * f1, 2 * np.pi * f2
        g = 1 / (50 * s ** 2) + 0.05 / (s ** 2 + 2 * z1 * w1 * s + w1 ** 2) \
            + 0.033 / (s ** 2 + 2 * z2 * w2 * s + w2 ** 2)
        for r in (0, 1, 2):
            for seed in (None, 0, 1):
                h = s ** r * g
                if seed is not None:
                    rng = np.random.default_rng(seed)
                    h = h * (1 + 0.02 * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) / np.sqrt(2))
                res = peak_pick(f, h)
                assert len(res) == 2, (f1, f2, r, seed)
                for est, (ft, zt) in zip(res, [(f1, z1), (f2, z2)]):
                    assert est.refined
                    tol = 1e-6 if seed is None else 5e-3
                    assert est.f == pytest.approx(ft, rel=tol), (f1, f2, r, seed)
                    assert est.zeta == pytest.approx(zt, rel=1e-5 if seed is None else 0.15), (f1, f2, r, seed)


def test_hump_without_a_lightly_damped_pole_is_not_a_resonance():
    # an antiresonance at 100 Hz followed by real poles: |H| rises and falls again (a peak of 12 dB
    # prominence at 267 Hz, half-power 'damping' 0.6) although no mode is there
    f = np.logspace(1, 3, 500)
    s = 2j * np.pi * f
    wz, wa = 2 * np.pi * 100, 2 * np.pi * 300
    h = (s ** 2 + 0.1 * wz * s + wz ** 2) / wz ** 2 / (1 + s / wa) ** 3 / (1 + s / (2 * np.pi * 20))
    assert len(peak_pick(f, np.abs(h), min_prominence_db=1.0, refine=False)) == 1
    assert peak_pick(f, h, min_prominence_db=1.0) == []


def test_user_errors_known_answer():
    d = frf_data(small_drive())
    model = {p: h * 10 for p, h in d.H.items()}             # one decade too high, no phase error
    e = user_errors([model], [d])[0]
    assert e["time"] == [] and [r["pair"] for r in e["frf"]] == list(d.H)
    for r in e["frf"]:
        assert r["mag_mean_abs_dlog10"] == pytest.approx(1.0, abs=1e-12)
        assert r["mag_db_rms"] == pytest.approx(20.0, abs=1e-10)
        assert r["phase_deg_rms"] == pytest.approx(0.0, abs=1e-10)
    rot = {p: h * np.exp(-1j * np.radians(10.0)) for p, h in d.H.items()}
    assert user_errors(rot, d)[0]["frf"][0]["phase_deg_rms"] == pytest.approx(10.0)
    tt = np.arange(1000) * 1e-3
    y = np.sin(2 * np.pi * 5 * tt)                           # zero mean over whole periods
    td = TimeData(tt, {"motor.tau": y}, {"rotor.w": y, "table.a": 2 * y}, units={"motor.tau": "N m",
                  "rotor.w": "rad/s", "table.a": "m/s^2"})
    e = user_errors({1: {"rotor.w": y, "table.a": y}}, [d, td])
    assert list(e) == [1] and e[1]["frf"] == []
    assert e[1]["time"] == [{"channel": "rotor.w", "fit_percent": 100.0},
                            {"channel": "table.a", "fit_percent": pytest.approx(50.0)}]
    with pytest.raises(KeyError, match="table.a"):
        user_errors([{"rotor.w": y}], [td])


def test_compare_exposes_the_user_errors(soft):
    c = compare(small_drive, soft)
    fc, tc = c.frf[0], c.time[0]
    ue = c.user_errors()
    assert list(ue) == [0, 1]
    assert ue == user_errors([fc.model, tc.model], soft)
    for r in ue[0]["frf"]:
        assert fc.pair_errors[r["pair"]]["mag_db_rms"] == r["mag_db_rms"] > 0
    assert {r["channel"]: r["fit_percent"] for r in ue[1]["time"]} == tc.fit
    assert "per pair: " in c.summary() and json.loads(c.to_json())["frf"][0]["pair_errors"]


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


def test_a_zero_or_nan_row_is_never_a_resonance():
    """Issue 15: one |H| = 0 row made its neighbour a 'resonance' with negative damping; such rows (0, NaN,
    inf) are skipped, so the resonances are those of the clean FRF, none with zeta <= 0."""
    fn, z = 150.0, 0.02
    f = np.geomspace(50, 400, 300)
    s = 2j * np.pi * f
    h = 1 / (s ** 2 + 2 * z * 2 * np.pi * fn * s + (2 * np.pi * fn) ** 2)
    clean = [(r.f, r.zeta) for r in peak_pick(f, np.abs(h), refine=False)]
    assert len(clean) == 1 and clean[0][0] == pytest.approx(fn, rel=0.01)
    for bad in (0.0, np.nan, np.inf):
        for k in (40, 200, 280):
            hb = np.abs(h).copy()
            hb[k] = bad
            got = [(r.f, r.zeta) for r in peak_pick(f, hb, refine=False)]
            assert len(got) == 1 and got[0][0] == pytest.approx(fn, rel=0.01) and got[0][1] > 0, (bad, k, got)
    hb = h.copy()
    hb[250] = 0.0
    assert [r.f for r in peak_pick(f, hb)] == pytest.approx([r.f for r in peak_pick(f, h)], rel=1e-3)


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


def _with_friction():
    """small_drive with a 40 N Coulomb friction from the table to ground."""
    from bscomp.components.coulomb_friction import CoulombFriction
    from bscomp.components.fixed import Fixed

    s = small_drive()
    s.add("guide_ground", Fixed())
    s.add("friction", CoulombFriction(F_c=40.0, v_reg=1e-4))
    s.connect("friction.flange_a", "guide_ground.flange")
    s.connect("friction.flange_b", "table.flange_b")
    return s


def test_a_nonlinear_model_is_compared_through_the_modal_method_as_accurately_as_tight_idas():
    """compare's time series of a model with friction runs ``method="modal"`` at ``MODAL_TOL`` (it took IDAS at rtol
    1e-7: on the demo's FE model 11 s against 0.15-0.27 s, and 20x further from IDAS at rtol 1e-10 on table.a); here
    the lumped drive with a Coulomb friction at the table that sticks and slides: within 1e-4 of IDAS at rtol 1e-10
    on every channel (measured: table.a 9.5e-6, rotor.w 4.2e-7; IDAS at compare's former rtol 1e-7: 8.5e-4, 3.8e-5)."""
    from bscomp.kernel.flattening import flatten
    from bscomp.simulation.dispatch import simulate
    from bscomp.validate.residuals import MODAL_TOL, simulate_for

    s = _with_friction()
    d = TimeData(T, {"motor.tau": 3.0 * U}, {"rotor.w": np.zeros_like(T), "table.a": np.zeros_like(T)},
                 units={"motor.tau": "N m", "rotor.w": "rad/s", "table.a": "m/s^2"}, source="friction")
    res, _ = simulate_for(s, d, extra=["table.v"])
    assert res.stats["method"] == "modal" and res.stats["options"]["tol"] == MODAL_TOL
    ref = simulate(flatten(s), T, inputs={"motor.tau": 3.0 * U}, outputs=["rotor.w", "table.a", "table.v"],
                   method="idas", rtol=1e-10, atol=1e-13)
    v = np.asarray(ref["table.v"])
    assert np.any(np.abs(v) < 1e-4) and np.max(np.abs(v)) > 1e-2      # it sticks and slides
    for n in ("rotor.w", "table.a", "table.v"):
        y, y0 = np.asarray(res[n]), np.asarray(ref[n])
        assert np.sqrt(np.mean((y - y0) ** 2)) < 1e-4 * np.sqrt(np.mean(y0 ** 2)), n


def test_a_model_the_modal_method_refuses_is_compared_through_idas(monkeypatch):
    """A model ``method="modal"`` does not take (ModalSimulationError: a nonlinearity it does not correct) is
    simulated by IDAS at simulate_for's tolerances, not refused."""
    from bscomp.simulation import modal_channels
    from bscomp.validate import residuals

    calls = []
    real = residuals.simulate

    def refusing(dae, t, method, **kw):
        calls.append((method, kw.get("rtol")))
        if method == "modal":
            raise modal_channels.ModalSimulationError("refused on purpose")
        return real(dae, t, method=method, **kw)

    monkeypatch.setattr(residuals, "simulate", refusing)
    s = _with_friction()
    d = TimeData(T[:200], {"motor.tau": 3.0 * U[:200]}, {"table.a": np.zeros(200)}, units={"motor.tau": "N m",
                 "table.a": "m/s^2"}, source="friction")
    res, _ = residuals.simulate_for(s, d)
    assert calls == [("modal", None), ("idas", 1e-7)] and res.stats["method"] == "idas"
    assert np.all(np.isfinite(res["table.a"]))


def test_fit_percent():
    y = np.array([1.0, 2.0, 3.0])
    assert fit_percent(y, y) == 100.0
    assert fit_percent(np.full(3, 2.0), y) == pytest.approx(0.0)
    assert fit_percent(1j * y, 1j * y) == 100.0


def test_unknown_model_channel_names_the_column(tmp_path):
    d = TimeData(T[:12], {"motor.tau": U[:12]}, {"table.q": np.zeros(12)}, units={"motor.tau": "N m", "table.q": "m"})
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


def test_a_measured_resonance_is_marked_on_each_pairs_own_curve():
    """A resonance seen in two FRF pairs is marked on each at that pair's measured |H| (its fitted amplitude is of
    one pair only: on the FE truth's table.a the 122.8 Hz mark sat at -2.7 dB, the motor speed pair's amplitude,
    17 dB below the curve)."""
    from importlib import resources

    import matplotlib.pyplot as plt

    from bscomp.plotting.validate import frf_comparison_plot
    from bscomp.validate.measurements import load_all

    root = resources.files("bscomp.systems") / "data" / "truths" / "axial_torsional" / "joint_friction"
    fc = compare("testbed_axial_torsional", load_all([str(root / "frf.csv")])).frf[0]
    fig = frf_comparison_plot(fc)
    shared = [m.measured for m in fc.modes if m.measured is not None and len(m.measured.pairs) > 1]
    assert shared, "the truth's first mode is seen in both pairs"
    checked = 0
    for j, p in enumerate(fc.measured):
        marks = [ln for ln in fig.axes[j].lines if ln.get_marker() == "x"]     # row 0: the magnitudes
        for r in shared:
            mark = next(ln for ln in marks if ln.get_xdata()[0] == r.f)
            level = 20 * np.log10(np.interp(r.f, fc.freqs, np.abs(fc.measured[p])))
            assert mark.get_ydata()[0] == pytest.approx(level, abs=1.0), (p, r.f)
            checked += 1
    plt.close(fig)
    assert checked >= 2
