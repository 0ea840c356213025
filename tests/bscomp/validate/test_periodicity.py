"""Order analysis of residuals (bscomp/validate/periodicity.py): a component periodic in the motor angle is found
with its order and amplitude; noise, smooth errors, time-frequency lines and ringing are not called periodic; at
a constant speed (where an order is a line) nothing is claimed. Then compare on data no candidate made: the
``ripple`` truth (a motor torque ripple, bscomp.systems.truths); diagnose on it:
tests/integration/test_diagnose_fe.py."""

import json
from importlib import resources

import numpy as np
import pytest

from bscomp.validate import conclusion as conc
from bscomp.validate.periodicity import (
    STEADY,
    angle_channel,
    periodic_in_angle,
    steady_fraction,
    tail,
)

T = np.arange(3001) * 2e-4                   # 0.6 s at 5 kHz, as the bundled time series


def _angle(profile):
    """Motor angle [rad] of a back-and-forth move at 5 Hz: ``ramp`` -- the speed swells and falls each half period
    (a current-controlled drive); ``steady`` -- nearly constant speed between quick reversals."""
    s = np.sin(2 * np.pi * 5 * T)
    w = 150 * s * np.abs(s) ** 0.3 if profile == "ramp" else 100.0 * np.tanh(5 * s)
    return np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * 2e-4)])


def _ar1(rng, rho):
    x, w = np.zeros(T.size), rng.standard_normal(T.size)
    for i in range(1, T.size):
        x[i] = rho * x[i - 1] + w[i]
    return x * np.sqrt(1 - rho ** 2)


def test_the_tail_is_the_exponential_order_statistics_own():
    """P(R > x M), M the 11th smallest of 20 others, all iid exponential: the closed form against 400,000 draws."""
    rng = np.random.default_rng(0)
    R = rng.exponential(size=400_000)
    M = np.sort(rng.exponential(size=(400_000, 20)), axis=1)[:, 10]
    for x in (1.0, 3.0, 8.0):
        p = np.mean(R > x * M)
        assert tail(x, 20) == pytest.approx(p, abs=4 * np.sqrt(p * (1 - p) / R.size) + 1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_a_periodic_component_is_found_with_its_order_and_amplitude(seed):
    rng = np.random.default_rng(seed)
    phi = _angle("ramp")
    e = 0.05 * rng.standard_normal(T.size) + 0.02 * np.sin(12 * phi + 1.0) + 0.3 * phi / phi.max()
    (o,) = periodic_in_angle({"table.a": e}, phi, T, "rotor.phi", {"table.a": "m/s^2"})
    assert (o.channel, o.angle, o.order, o.unit) == ("table.a", "rotor.phi", 12, "m/s^2")
    # 3 standard errors of a two-column fit to white noise (sigma sqrt(2/N)), x1.3 for the trend's and the removed
    # lines' overlap with the order's columns
    assert o.amplitude == pytest.approx(0.02, abs=3 * 0.05 * np.sqrt(2 / T.size) * 1.3) and o.p_value < 1e-3
    assert "12 periods per revolution" in o.describe()


def test_noise_smooth_errors_lines_and_ringing_are_not_called_periodic():
    """20 seeds of five residuals with no angle-periodic part: none reported (at p < 1e-3 per channel, Bonferroni
    over the orders; a line in time -- a resonance, the input's harmonics -- is removed before the test)."""
    phi = _angle("ramp")
    ring = sum(np.exp(-(T - t0) / 0.02) * (T >= t0) * np.sin(2 * np.pi * 150 * (T - t0))
               for t0 in np.arange(0, 0.6, 0.1))
    found = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        e = {"white": rng.standard_normal(T.size), "correlated": _ar1(rng, 0.95),
             "smooth": 3 * phi / phi.max() + 0.5 * (phi / phi.max()) ** 2 + 0.1 * _ar1(rng, 0.9),
             "line": np.sin(2 * np.pi * (137 + 10 * rng.random()) * T) + rng.standard_normal(T.size),
             "ringing": ring + 0.3 * rng.standard_normal(T.size)}
        found += periodic_in_angle(e, phi, T, "phi")
    assert found == []


def test_at_a_constant_speed_no_order_is_claimed():
    """At one speed an order is a sinusoid in time (a ringing mode looks the same): no claim, even for a real one."""
    phi = _angle("steady")
    assert steady_fraction(phi, T) > STEADY > steady_fraction(_angle("ramp"), T)
    e = 0.05 * np.random.default_rng(1).standard_normal(T.size) + 0.05 * np.sin(12 * phi)
    assert periodic_in_angle({"a": e}, phi, T, "phi") == []


def test_too_little_rotation_or_no_angle_channel():
    phi = 0.05 * 2 * np.pi * np.sin(2 * np.pi * 5 * T) ** 2       # a twentieth of a revolution
    assert periodic_in_angle({"a": np.sin(40 * phi)}, phi, T, "phi") == []
    assert angle_channel({"rotor.w": "rad/s", "rotor.phi": "rad"}) == "rotor.phi"
    assert angle_channel({"table.s": "m"}) is None


def test_the_conclusion_states_the_error_left():
    from types import SimpleNamespace

    big = {"error": 273.0, "within_noise": False, "orders": []}
    msg = conc.conclusion("", [], [], ("", ""), [], 1, None, {}, big)
    assert msg.startswith("an effect outside the candidates is missing") and "273x the noise floor" in msg
    assert "do not trust them" in msg
    small = dict(big, error=2.9)
    msg = conc.conclusion("", [], [], ("", ""), [], 1, None, {}, small)
    assert msg.startswith("no missing effect found") and msg.endswith("The error left is 2.9x the noise floor")
    found = SimpleNamespace(candidate=SimpleNamespace(title="guideway friction"), equivalent={})
    assert conc.conclusion("", [found], [], ("", ""), [], 2, None, {}, big).startswith(
        "1 missing effect(s) found: guideway friction. The error left is 273x the noise floor (above 5x")
    assert conc.conclusion("", [found], [], ("", ""), [], 2, None, {}, dict(big, within_noise=True)) == \
        "1 missing effect(s) found: guideway friction"
    view = dict(big, frf_values={"table.m": 269.2})
    assert "the FRFs alone give table.m = 269.2 (the fit to every dataset: -11.0 %)" in conc.conclusion(
        "", [], [], ("", ""), [], 1, None, {"table.m": 239.6}, view)


RIPPLE = resources.files("bscomp.systems") / "data" / "truths" / "axial_torsional" / "ripple"


def test_compare_at_the_truths_values_finds_the_ripples_order(tmp_path):
    """The ripple truth (2.9 % torque ripple, 12 per revolution) compared at its own mis-set values: the residual
    of table.a is periodic in rotor.phi at order 12; at the model's nominal values (a 7.7 % lighter table, whose
    error dominates the residual: p 2e-3) and on the control truth (no ripple): nothing claimed."""
    from bscomp.validate.comparison import compare

    truth = json.loads((RIPPLE / "truth.json").read_text())
    files = [str(RIPPLE / "frf.csv"), str(RIPPLE / "time.csv")]
    p = {k: v["truth"] for k, v in truth["misset"].items()}
    c = compare("testbed_axial_torsional", files, params=p)
    (o,) = c.time[0].orders
    assert (o.channel, o.order) == ("table.a", truth["hidden"]["ripple"]["p"]) and o.p_value < 1e-4
    assert "periodic in rotor.phi: 12 periods per revolution" in c.summary()
    # the figure's numbers: the spectrum peaks at the order, the folded bin means follow the fitted cosine
    assert int(np.argmax(o.spectrum)) + 1 == 12 and len(o.spectrum) >= 60
    th, m = np.asarray(o.folded).T
    assert np.corrcoef(m, o.amplitude * np.cos(th + o.phase))[0, 1] > 0.9
    assert any(p.name.endswith("_orders.png") and p.stat().st_size > 10_000 for p in c.plot(tmp_path))
    assert compare("testbed_axial_torsional", files).time[0].orders == []
    control = RIPPLE.parent / "control"
    files = [str(control / "frf.csv"), str(control / "time.csv")]
    assert compare("testbed_axial_torsional", files).time[0].orders == []


def test_a_friction_torque_is_not_accepted_while_the_residual_repeats_with_the_motor_angle():
    """``acceptance.ripple_left`` (rule for :attr:`Candidate.ripple_alike`, the friction torque at the motor): the
    residual a fit leaves, 12 periods per revolution of the ``rad`` channel beside noise and a smooth error, is the
    reason given; the same noise and smooth error without the ripple give none; no angle channel, none."""
    from bscomp.validate.acceptance import ripple_left
    from bscomp.validate.candidates import RotorFriction, default_candidates
    from bscomp.validate.datasets import TimeData

    rng = np.random.default_rng(3)
    phi = _angle("ramp")
    noise = 0.05 * rng.standard_normal(T.size) + 0.3 * phi / phi.max()
    units = {"motor.tau": "N m", "rotor.phi": "rad", "rotor.w": "rad/s"}
    d = TimeData(T, {"motor.tau": np.zeros_like(T)}, {"rotor.phi": phi, "rotor.w": noise}, units=units)
    fit = {"rotor.phi": phi, "rotor.w": -0.02 * np.sin(12 * phi + 1.0)}
    why = ripple_left([fit], [d])
    assert why.startswith("the residual it leaves repeats 12 times per motor revolution (rotor.w, p ")
    assert ripple_left([dict(fit, **{"rotor.w": np.zeros_like(T)})], [d]) == ""
    flat = TimeData(T, {"motor.tau": np.zeros_like(T)}, {"rotor.w": noise}, units={"motor.tau": "N m",
                                                                                   "rotor.w": "rad/s"})
    assert ripple_left([{"rotor.w": fit["rotor.w"]}], [flat]) == ""
    assert RotorFriction.ripple_alike and [c.name for c in default_candidates() if c.ripple_alike] == ["rotor_friction"]
