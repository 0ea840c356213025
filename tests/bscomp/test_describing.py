"""bscomp.describing_frf: the FRF at an excitation amplitude by the describing function (one-harmonic balance).

Checked against what it did not make: the closed-form describing functions of Coulomb friction and of a dead
zone (on the elements' own laws), the stepped-sine simulation (bscomp.stepped_sine: time integration, every
harmonic) on a Coulomb oscillator and on the FE test bed with Table 5.2 friction, and bscomp.frf (sparse solves
of the linearized model) in the small-amplitude limit; named errors."""

import warnings

import numpy as np
import pytest

import bscomp
from bscomp.components import Backlash, CoulombFriction
from bscomp.errors import ArgumentTypeError, ModelLimitationWarning, UnknownNameError, UsageError
from bscomp.simulation.compiled import _Element
from bscomp.simulation.describing import DescribingFunctionError, describing_frf, first_harmonic, spans
from bscomp.simulation.harmonic_balance import HarmonicBalance, odd_harmonics, odd_harmonics_tangent
from bscomp.systems import friction_oscillator, get
from bscomp.systems.thesis_effects import with_friction_backlash

K, M, F_C = 1.0e4, 1.0, 1.0          # omega_n = 100 rad/s; Coulomb friction 1 N


def oscillator(friction=True):
    return bscomp.flatten(friction_oscillator(M, K, F_C if friction else None))



def _element(path, comp):
    el = _Element(path, comp)
    el.pvec = np.array([el.values[n] for n in el.pnames])
    return el


def test_first_harmonic_of_coulomb_friction_and_of_a_dead_zone():
    """Coulomb friction (v_reg 1e-9 of the velocity amplitude): 4 F_c / pi in phase with the velocity, to 1e-4;
    a clearance b with contact stiffness c: c (1 - (2/pi)(asin beta + beta sqrt(1 - beta^2))) S, beta = b / 2|S|,
    to 1e-4 at three amplitudes, and 0 inside the clearance."""
    fr = _element("fr", CoulombFriction(F_c=2.0, v_reg=1e-12))
    for V in (1e-3, 0.5j, 3.0 - 4.0j):
        F = first_harmonic(fr.law, fr.pvec, 0.0, 0.0, 0.0, V, points=512)
        assert abs(F - 4 * 2.0 / np.pi * V / abs(V)) < 1e-4 * 8 / np.pi, V
    bl = _element("bl", Backlash(b=2e-3, c=5e6))
    for S in (1.5e-3, 4e-3 * np.exp(0.7j), 0.1):
        beta = 1e-3 / abs(S)
        ref = 5e6 * (1 - 2 / np.pi * (np.arcsin(beta) + beta * np.sqrt(1 - beta ** 2))) * S
        F = first_harmonic(bl.law, bl.pvec, 0.0, 0.0, S, 0.0, points=512)
        assert abs(F / ref - 1) < 1e-4, (S, F, ref)
    assert first_harmonic(bl.law, bl.pvec, 0.0, 0.0, 0.9e-3, 0.0) == 0.0


def test_odd_harmonics_of_coulomb_friction_are_its_square_wave_series():
    """Coulomb friction under v = Re(V e^{j theta}): F_k = (4 F_c / (pi k)) (-1)^((k-1)/2) (V/|V|)^k for the odd k
    (the Fourier series of F_c sign(cos)), to 1e-3; the first order is first_harmonic's."""
    fr = _element("fr", CoulombFriction(F_c=2.0, v_reg=1e-12))
    orders = (1, 3, 5, 7)
    for V in (0.5j, 3.0 - 4.0j):
        F = odd_harmonics(fr.law, fr.pvec, 0.0, 0.0, np.zeros(4, complex), np.array([V, 0, 0, 0]), orders, 1024)
        ref = [4 * 2.0 / (np.pi * k) * (-1) ** ((k - 1) // 2) * (V / abs(V)) ** k for k in orders]
        np.testing.assert_allclose(F, ref, rtol=0, atol=1e-3 * 8 / np.pi)
        assert abs(F[0] - first_harmonic(fr.law, fr.pvec, 0.0, 0.0, 0.0, V, points=1024)) < 1e-12


def test_the_balances_jacobian_is_the_derivative_of_its_residual():
    """HarmonicBalance.jacobian (the law's tangent at the phases and the turn of the phases with the fundamental's)
    against central differences of the residual, for friction and a clearance together and 1-3 odd orders; the
    differences converge to it (relative gap < 1e-6 at step 1e-6, where the clearance's corners spoil a step
    of 1e-4), and odd_harmonics_tangent's F is odd_harmonics' bit for bit. A Coulomb friction's harmonics turn
    with the velocity: dF_1 / dV along i V is i F_1 (a pure turn, 1e-9)."""
    fr = _element("fr", CoulombFriction(F_c=300.0, v_reg=1e-4))
    bl = _element("bl", Backlash(b=2e-5, c=1e8, d=50.0))
    rng = np.random.default_rng(3)
    n = 2
    for nh in (1, 2, 3):
        hb = HarmonicBalance([fr.law, bl.law], [fr.pvec, bl.pvec], [0, 0], [0, 0], [0.0, 1e8], [0.0, 50.0], 256, nh)
        Ts = [1e-6 * (rng.standard_normal((2 * n + 1, n + 1)) + 1j * rng.standard_normal((2 * n + 1, n + 1)))
              for _ in range(nh)]
        for T in Ts:
            T[1:2 * n:2] *= 100                      # velocities: rows 1, 3
        g = 100 * (rng.standard_normal((nh, n)) + 1j * rng.standard_normal((nh, n)))
        r, _, J = hb.jacobian(g, Ts, 3.0)
        np.testing.assert_array_equal(r, hb.residual(g, Ts, 3.0)[0])
        m = g.size
        x = np.r_[g.real.ravel(), g.imag.ravel()]

        def res(x, hb=hb, m=m, g=g, Ts=Ts):
            rr = hb.residual((x[:m] + 1j * x[m:]).reshape(g.shape), Ts, 3.0)[0]
            return np.r_[rr.real.ravel(), rr.imag.ravel()]

        h = 1e-6 * np.abs(x).max()
        Jd = np.column_stack([(res(x + h * e) - res(x - h * e)) / (2 * h) for e in np.eye(2 * m)])
        assert np.abs(J - Jd).max() < 1e-6 * np.abs(Jd).max(), nh
    V = np.array([0.02 - 0.01j, 0.0])
    S = np.zeros(2)
    F, dF = odd_harmonics_tangent(fr.law, fr.pvec, 0.0, 0.0, S, V, (1, 3))
    np.testing.assert_array_equal(F, odd_harmonics(fr.law, fr.pvec, 0.0, 0.0, S, V, (1, 3)))
    turn = (dF[0, 4] * (1j * V[0]).real + dF[0, 6] * (1j * V[0]).imag) / abs(V[0])   # unit step along i V_1
    assert abs(turn - 1j * F[0] / abs(V[0])) < 1e-9 * abs(F[0] / V[0])
    turn3 = (dF[1, 4] * (1j * V[0]).real + dF[1, 6] * (1j * V[0]).imag) / abs(V[0])  # the third turns 3x as fast
    assert abs(turn3 - 3j * F[1] / abs(V[0])) < 1e-9 * abs(F[0] / V[0])


def test_higher_harmonics_converge_to_the_stepped_sine_where_the_mass_sticks():
    """F_c / F_0 = 1/3: at 0.38 omega_n the mass sticks for part of each period (distortion 16 %) and one harmonic
    is 17 % (1.5 dB) below the stepped sine (time integration, every harmonic; 60 periods settled); balancing the
    odd orders up to 5 and 15 brings it to 2.2 % and 0.9 % (measured), at 3 omega_n 4.8 -> 0.95 -> 0.48 %."""
    dae = oscillator()
    f = np.array([0.38, 3.0]) * 100.0 / (2 * np.pi)
    ss = bscomp.stepped_sine(dae, "F.f", "m.s", f, 3.0, settle=60, periods=8)
    err = {h: np.abs(describing_frf(dae, "F.f", "m.s", f, 3.0, harmonics=h).H[:, 0, 0] / ss.H[:, 0, 0] - 1)
           for h in (1, 3, 8)}
    assert np.all(err[1] > 0.04) and np.all(err[8] < 0.012), err
    assert np.all(err[3] < err[1]) and np.all(err[8] < err[3]), err


def test_coulomb_oscillator_matches_the_closed_form_and_the_stepped_sine():
    """Mass-spring with Coulomb friction (F_c / F_0 = 0.1) at 0.5-3 x omega_n: |X| = sqrt(F_0^2 - (4 F_c/pi)^2) /
    |k - m w^2| to 2e-3 (measured 6.4e-4; the law's v_reg = 1e-4 m/s takes the rest), the same within 0.5 % of
    the stepped-sine simulation (measured 0.2-0.3 %: the harmonics it keeps); the acceleration is -w^2 x the
    position; below breakaway (F_0 < 4 F_c / pi) the mass stays in the regularisation band (stuck) and moves
    10x less per newton."""
    dae = oscillator()
    r = np.array([0.5, 0.8, 1.25, 2.0, 3.0])
    f = r * 100.0 / (2 * np.pi)
    w = 2 * np.pi * f
    d = describing_frf(dae, "F.f", ["m.s", "m.a"], f, 10.0)
    X_df = np.sqrt(10.0 ** 2 - (4 * F_C / np.pi) ** 2) / np.abs(K - M * w ** 2)
    np.testing.assert_allclose(np.abs(d.H[:, 0, 0]) * 10.0, X_df, rtol=2e-3)
    np.testing.assert_allclose(d.H[:, 1, 0], -w ** 2 * d.H[:, 0, 0], rtol=1e-10)
    assert d.residual.max() < 1e-8 and d.elements == ["fr"] and d.amplitude == 10.0
    ss = bscomp.stepped_sine(dae, "F.f", "m.s", f[[1, 3]], 10.0)
    assert np.abs(d.H[[1, 3], 0, 0] / ss.H[:, 0, 0] - 1).max() < 5e-3
    stuck = describing_frf(dae, "F.f", "m.s", f, 0.5)           # 0.5 N < 4/pi N: the friction holds the mass
    assert np.abs(stuck.velocity[:, 0]).max() < 1e-4          # below v_reg
    assert np.all(np.abs(stuck.H[:, 0, 0]) < 0.1 * np.abs(d.H[:, 0, 0]))


def test_small_amplitude_is_the_linear_frf():
    """At 1e-9 N the elements stay on their rest tangents: the linearized FRF (bscomp.frf, another path) to 1e-9."""
    dae = oscillator()
    f = np.array([3.0, 15.9, 40.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelLimitationWarning)
        ref = bscomp.frf(dae, "F.f", ["m.s", "m.v"], f)
    d = describing_frf(dae, "F.f", ["m.s", "m.v"], f, 1e-9)
    assert np.abs(d.H / ref.H - 1).max() < 1e-9


def test_deviation_from_the_tangent_at_rest_says_where_friction_stays_stuck():
    """``DescribingFrf.deviation``: for tanh friction driven at velocity amplitude ``x v_reg`` the fundamental is
    ``F_c (x - x^3/4 + x^5/12 - 17 x^7 / 576 ...)`` against the tangent ``F_c x``, so the deviation is
    ``x^2/4 - x^4/12 + 17 x^6 / 576``: matched to 1e-4 at x = 0.05, 0.2, 0.3 (the oscillator held by friction's
    slope at rest, F_0 < F_c), and the
    summary names the element as measured at its slope at rest; sliding (F_0 = 10 N, away from resonance) it
    is ~1 and the summary says nothing of it."""
    dae = oscillator()
    f = np.array([5.0, 100 / (2 * np.pi), 40.0])
    for F0 in (0.05, 0.2, 0.3):
        d = describing_frf(dae, "F.f", "m.v", f, F0)
        x = np.abs(d.velocity[:, 0]) / 1e-4                    # v_reg of friction_oscillator
        assert 0.04 < x.min() and x.max() < 0.32
        series = x ** 2 / 4 - x ** 4 / 12 + 17 * 35 / (315 * 64) * x ** 6     # tanh's series, cos^n's fundamentals
        np.testing.assert_allclose(d.deviation[:, 0], series, rtol=1e-4)
        assert "fr stays within 5 % of its tangent at rest at every frequency" in d.summary()
        assert set(d.small_signal()) == {"fr"} and d.small_signal()["fr"].size == 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelLimitationWarning)
        slide = describing_frf(dae, "F.f", "m.v", [5.0, 40.0], 10.0)
    assert slide.deviation.min() > 0.99 and slide.small_signal() == {} and "tangent at rest" not in slide.summary()
    f5 = np.array([10.0, 20.0, 30.0, 40.0, 50.0])               # the summary's frequency runs
    assert spans(f5, [10.0, 20.0, 40.0, 50.0]) == "10-20, 40-50" and spans(f5[::-1], [30.0, 50.0]) == "30, 50"


@pytest.fixture(scope="module")
def bed():
    return bscomp.flatten(with_friction_backlash(get("testbed_axial_torsional"), backlash=False))


def test_testbed_with_guideway_friction_against_the_stepped_sine(bed):
    """The FE test bed with Table 5.2 friction, amp.u -> table.a and rotor.w at 10 and 20 Hz. At 0.2 V the table
    stays stuck (the stepped sine's distortion <= 2.3 %) and the describing function equals the stepped sine to
    1 % (measured 0.04-0.24 %); at 2 V the table slides through each period, the stepped sine's acceleration is
    distorted by ~250 % (stick-slip spikes) and one harmonic is an approximation: within 25 % (measured 7.8-18 %),
    against a factor > 20 (73 at 10 Hz) for the FRF linearized at rest."""
    f = np.array([10.0, 20.0])
    outs = ["table.a", "rotor.w"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelLimitationWarning)
        lin = bscomp.frf(bed, "amp.u", outs, f)
    for A, bar in ((0.2, 1e-2), (2.0, 0.25)):
        d = describing_frf(bed, "amp.u", outs, f, A)
        ss = bscomp.stepped_sine(bed, "amp.u", outs, f, A, settle=6, periods=2)
        err = np.abs(d.H[:, :, 0] / ss.H[:, :, 0] - 1)
        assert err.max() < bar, (A, err)
        assert d.residual.max() < 1e-7
        # stuck at 0.2 V (the friction's fundamental within 5 % of its slope at rest), sliding at 2 V
        assert (d.deviation.max() < 0.05) if A == 0.2 else (d.deviation.min() > 0.5), (A, d.deviation)
    assert np.abs(ss.H[:, 0, 0] / lin.H[:, 0, 0]).min() > 20     # what the linearized FRF misses at 2 V
    assert np.abs(d.H[:, 0, 0] / lin.H[:, 0, 0]).min() > 20


def test_testbed_stick_slip_by_higher_harmonics(bed):
    """The test bed with Table 5.2 friction at 2 V, 20 Hz (the table sticks and slips: table.a distortion ~280 %):
    against a stepped sine settled 60 periods, one harmonic is off by 11 % (table.a) and 18 % (rotor.w); the odd
    orders up to 9 bring them to 1.3 % and 0.3 % (measured)."""
    outs = ["table.a", "rotor.w"]
    ss = bscomp.stepped_sine(bed, "amp.u", outs, [20.0], 2.0, settle=60, periods=8)
    one = np.abs(describing_frf(bed, "amp.u", outs, [20.0], 2.0).H[0, :, 0] / ss.H[0, :, 0] - 1)
    five = np.abs(describing_frf(bed, "amp.u", outs, [20.0], 2.0, harmonics=5).H[0, :, 0] / ss.H[0, :, 0] - 1)
    assert one[1] > 0.1 and five[1] < 0.01 and five[0] < 0.03, (one, five)


def test_named_errors(bed):
    dae = oscillator()
    for kw, err in (({"freqs": [-1.0]}, UsageError), ({"freqs": "x"}, UsageError), ({"amplitude": 0.0}, UsageError),
                    ({"points": 8}, UsageError), ({"input": "F.g"}, UnknownNameError),
                    ({"input": ["F.f"]}, ArgumentTypeError), ({"output": 3}, ArgumentTypeError),
                    ({"harmonics": 0}, UsageError), ({"harmonics": 1.5}, UsageError),
                    ({"harmonics": 20}, UsageError)):
        args = {"input": "F.f", "output": "m.s", "freqs": [10.0], "amplitude": 1.0, **kw}
        with pytest.raises(err):
            describing_frf(dae, **args)
    with pytest.raises(DescribingFunctionError, match="bscomp.frf"):
        describing_frf(oscillator(friction=False), "F.f", "m.s", [10.0], 1.0)
    # the amplifier's current limit, active at 2 V, is not an element: refused, not linearized silently
    with pytest.raises(DescribingFunctionError, match="amp"):
        describing_frf(bed, "amp.u", "table.a", [10.0], 2.0, params={"amp.i_max": 1.0})
    with pytest.warns(ModelLimitationWarning, match="nonlinear in the states"):
        describing_frf(dae, "F.f", "fr.f", [10.0], 10.0)


def test_cli_frf_by_the_describing_function(tmp_path, capsys):
    """``bscomp frf FILE --amplitude A --method describing``: the CSV read back equals describing_frf (1e-12); the
    method without an amplitude, and a drive without friction or backlash, are one named line and exit code 2."""
    from bscomp.cli import main
    from bscomp.validate import load

    model = tmp_path / "osc.py"
    model.write_text("from bscomp.systems import friction_oscillator\n\n\ndef build():\n"
                     "    return friction_oscillator()\n")
    path = tmp_path / "df.csv"
    rc = main(["frf", str(model), "--input", "F.f", "--output", "m.s", "--amplitude", "10", "--method", "describing",
               "--fmin", "5", "--fmax", "50", "--n", "7", "--csv", str(path)])
    assert rc == 0 and "describing function at 10 of fr" in capsys.readouterr().out
    data = load(path)
    ref = describing_frf(oscillator(), "F.f", "m.s", data.freqs, 10.0)
    np.testing.assert_allclose(data.H[("F.f", "m.s")], ref.H[:, 0, 0], rtol=1e-12)
    assert main(["frf", str(model), "--input", "F.f", "--output", "m.s", "--method", "describing"]) == 2
    assert "add --amplitude" in capsys.readouterr().err
    assert main(["frf", "small_drive", "--input", "motor.tau", "--output", "table.v", "--amplitude", "1",
                 "--method", "describing"]) == 2
    assert "has no friction or backlash element" in capsys.readouterr().err
    rc = main(["frf", str(model), "--input", "F.f", "--output", "m.s", "--amplitude", "3", "--method", "describing",
               "--harmonics", "3", "--fmin", "5", "--fmax", "50", "--n", "4", "--csv", str(path)])
    ref = describing_frf(oscillator(), "F.f", "m.s", load(path).freqs, 3.0, harmonics=3)
    assert rc == 0 and "odd harmonics up to 5" in capsys.readouterr().out
    np.testing.assert_allclose(load(path).H[("F.f", "m.s")], ref.H[:, 0, 0], rtol=1e-12)
    for extra in (["--harmonics", "3"], ["--harmonics", "3", "--amplitude", "3"], ["--harmonics", "0"]):
        assert main(["frf", str(model), "--input", "F.f", "--output", "m.s", *extra]) == 2
        assert "--harmonics" in capsys.readouterr().err


def test_params_are_the_overridden_model(bed):
    """``params=`` on the flattened Dae is the System flattened with the override (friction force halved: the table
    slides more, |H| of table.a at 10 Hz up 25 %), bit for bit."""
    over = {"friction.F_c_pos": 1000.0, "friction.F_c_neg": 1000.0}
    a = describing_frf(bed, "amp.u", "table.a", [10.0, 20.0], 2.0)
    b = describing_frf(bed, "amp.u", "table.a", [10.0, 20.0], 2.0, params=over)
    c = describing_frf(bscomp.flatten(with_friction_backlash(get("testbed_axial_torsional"), backlash=False)
                                      .with_parameters(over)), "amp.u", "table.a", [10.0, 20.0], 2.0)
    np.testing.assert_array_equal(b.H, c.H)
    assert abs(b.H[0, 0, 0]) > 1.2 * abs(a.H[0, 0, 0])


def test_compiled_model_at_an_amplitude_is_the_describing_frf():
    """CompiledModel.frf(amplitude=) -- the fit engine's modal model (modes below 6 kHz, the rest as residual
    flexibility, the friction cut out as a force) balanced by the same HarmonicBalance -- against
    describing_frf on the flattened model (all states): the Coulomb oscillator's closed form to 2e-3 and
    describing_frf to 1e-5 (measured 1.2e-6 near resonance: the balances' Newton tolerance); a model without
    elements, or an input without an amplitude, is the small-signal FRF (an amplitude for an unknown input is
    refused); a law parameter override moves the balance (F_c 1 -> 3 N lowers |X| as the closed form says)."""
    from bscomp.simulation.compiled import CompiledModel

    r = np.array([0.5, 1.25, 3.0])
    f = r * 100.0 / (2 * np.pi)
    w = 2 * np.pi * f
    pair = [("F.f", "m.s")]
    cm = CompiledModel(friction_oscillator(M, K, F_C), ["F.f"], ["m.s"])
    H = cm.frf({}, f, pair, amplitude={"F.f": 10.0})[pair[0]]
    np.testing.assert_allclose(np.abs(H) * 10.0, np.sqrt(100.0 - (4 * F_C / np.pi) ** 2) / np.abs(K - M * w ** 2),
                               rtol=2e-3)
    ref = describing_frf(oscillator(), "F.f", "m.s", f, 10.0)
    assert np.abs(H / ref.H[:, 0, 0] - 1).max() < 1e-5
    H3 = cm.frf({"fr.F_c_pos": 3.0, "fr.F_c_neg": 3.0}, f, pair, amplitude={"F.f": 10.0})[pair[0]]
    np.testing.assert_allclose(np.abs(H3) * 10.0, np.sqrt(100.0 - (12.0 / np.pi) ** 2) / np.abs(K - M * w ** 2),
                               rtol=2e-3)
    small = cm.frf({}, f, pair)[pair[0]]
    assert np.all(np.isfinite(small))
    H5 = cm.frf({}, f, pair, amplitude={"F.f": 3.0}, harmonics=5)[pair[0]]     # the orders up to 9 (at 9 f too)
    ref5 = describing_frf(oscillator(), "F.f", "m.s", f, 3.0, harmonics=5)
    assert np.abs(H5 / ref5.H[:, 0, 0] - 1).max() < 1e-5
    with pytest.raises(UsageError, match="points"):
        cm.frf({}, f, pair, amplitude={"F.f": 3.0}, harmonics=17)
    with pytest.raises(UnknownNameError, match="'other.u', which is not an input"):
        cm.frf({}, f, pair, amplitude={"other.u": 1.0})            # an amplitude for no input is a mistake
    lin = CompiledModel(friction_oscillator(M, K, None), ["F.f"], ["m.s"])
    assert np.array_equal(lin.frf({}, f, pair, amplitude={"F.f": 10.0})[pair[0]], lin.frf({}, f, pair)[pair[0]])


def test_compiled_model_at_an_amplitude_on_the_testbed(bed):
    """The FE test bed with Table 5.2 friction at 0.2 V and 2 V: the fit engine's balance equals describing_frf on
    the flattened model to 1e-4 (measured 9e-6 on 14 frequencies 10-200 Hz: the modes above 6 kHz taken
    statically)."""
    from bscomp.simulation.compiled import CompiledModel

    f = np.array([10.0, 33.0, 120.0])
    outs = ["rotor.w", "table.a"]
    cm = CompiledModel(with_friction_backlash(get("testbed_axial_torsional"), backlash=False), ["amp.u"], outs)
    for A in (0.2, 2.0):
        H = cm.frf({}, f, [("amp.u", o) for o in outs], amplitude={"amp.u": A})
        ref = describing_frf(bed, "amp.u", outs, f, A)
        for k, o in enumerate(outs):
            assert np.abs(H[("amp.u", o)] / ref.H[:, k, 0] - 1).max() < 1e-4, (A, o)


def test_an_order_that_does_not_converge_keeps_the_balance_below_it(monkeypatch):
    """Where adding an odd order to the balance does not converge (forced here: any solve with more than one order
    reports a residual of 1), the first-harmonic balance is kept there, said in a ModelLimitationWarning and the
    notes -- not a number from an unconverged balance, not NaN where one order converged."""
    from bscomp.simulation.harmonic_balance import HarmonicBalance

    solve = HarmonicBalance.solve

    def failing(self, Ts, U, g0, tol, max_iter=40):
        g, rel = solve(self, Ts, U, g0, tol, max_iter)
        return g, (1.0 if len(Ts) > 1 else rel)

    f = np.array([0.5, 3.0]) * 100.0 / (2 * np.pi)
    one = describing_frf(oscillator(), "F.f", "m.s", f, 3.0)
    monkeypatch.setattr(HarmonicBalance, "solve", failing)
    with pytest.warns(ModelLimitationWarning, match="did not converge"):
        d = describing_frf(oscillator(), "F.f", "m.s", f, 3.0, harmonics=3)
    np.testing.assert_allclose(d.H, one.H, rtol=1e-6)          # the same balance, to its Newton tolerance
    assert any("fewer orders" in n for n in d.notes)
