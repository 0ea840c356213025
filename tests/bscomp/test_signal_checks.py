"""Outputs must be signals, and the arguments of the compiled, swept and reduced analyses are checked.

A parameter (``rotor.J``, ``m.m``) is an observable of a model, but its response to any input is 0 at every
frequency: every FRF-like analysis refuses it through one check, :meth:`bscomp.Dae.require_signals`. Counts
(``n_modes``, ``workers``, ``chunksize``), amplitudes, frequencies and CMS tolerances are refused with an error
naming the argument instead of a silently wrong result; valid calls are unchanged.
"""

import numpy as np
import pytest

import bscomp
from bscomp.design_sweep import design_study
from bscomp.errors import ArgumentTypeError, ParameterError, UnknownNameError, UsageError
from bscomp.linear import second_order
from bscomp.linear.reduction import cms_reduce, reduce_second_order
from bscomp.linear.sweeps import position_sweep
from bscomp.simulation.compiled import CompiledModel
from bscomp.simulation.describing import describing_frf
from bscomp.simulation.stepped import stepped_sine
from bscomp.systems import friction_oscillator, mass_spring_chain

K, M, F_C = 1.0e4, 1.0, 1.0
PAIR = [("F.f", "m.s")]
F = np.array([8.0, 20.0, 40.0])


@pytest.fixture(scope="module")
def osc():
    return bscomp.flatten(friction_oscillator(M, K, F_C))


@pytest.fixture(scope="module")
def cm():
    return CompiledModel(friction_oscillator(M, K, F_C), ["F.f"], ["m.s"])


def chain4():
    return mass_spring_chain((1.0, 2.0, 1.5, 1.0), (1.0e4, 2.0e4, 1.5e4, 1.0e4))


# ---- 1: one check that an output is a signal ---------------------------------------------------------------------
def test_dae_require_signals(osc):
    assert osc.require_signals("m.s", "me") == ["m.s"]
    assert osc.require_signals(["m.s", "m.a", "fr.f"]) == ["m.s", "m.a", "fr.f"]
    assert osc.is_signal("m.v") and not osc.is_signal("m.m")
    with pytest.raises(UnknownNameError, match=r"me: output 'm\.m' of .* is a parameter, not a signal.*"
                                               r"outputs of 'm': \[.*'m\.s'") as exc:
        osc.require_signals(["m.s", "m.m"], "me")
    assert "'m.m'" not in str(exc.value).split("outputs of")[1] and exc.value.hint
    with pytest.raises(UnknownNameError, match=r"me: no output named 'm\.ss'"):
        osc.require_signals(["m.ss"], "me")


@pytest.mark.parametrize("call", [
    lambda d: bscomp.frf(d, "F.f", "m.m", [10.0]),
    lambda d: describing_frf(d, "F.f", ["m.s", "m.m"], F, 10.0),
    lambda d: stepped_sine(d, "F.f", "m.m", [10.0], 10.0),
    lambda d: CompiledModel(d, ["F.f"], ["m.s", "m.m"]),
], ids=["frf", "describing_frf", "stepped_sine", "CompiledModel"])
def test_a_parameter_is_not_an_output(osc, call):
    with pytest.raises(UnknownNameError, match=r"'m\.m' .*is a parameter, not a signal"):
        call(osc)


def test_sweeps_refuse_a_parameter_output():
    with pytest.raises(UnknownNameError, match=r"position_sweep: output 'm1\.m' .* parameter, not a signal"):
        position_sweep(chain4, [1.0e4, 2.0e4], "k2.c", freqs=[10.0], outputs=["m1.m"])
    with pytest.raises(UnknownNameError, match=r"design_study: output 'rotor\.J' .* parameter, not a signal"):
        design_study("small_drive", {"table.m": [200.0]}, "frf", workers=1, inputs=["motor.tau"],
                     outputs=["rotor.J"], freqs=[10.0, 100.0])
    one = design_study("small_drive", {"table.m": [200.0]}, "frf", workers=1, inputs="motor.tau",
                       outputs="table.a", freqs=[10.0, 100.0])          # one str is one name
    assert one.columns == ["table.m", "peak[table.a/motor.tau]", "f_peak[table.a/motor.tau]"]
    assert one.data[0, 1] > 0


# ---- 2: CompiledModel ----------------------------------------------------------------------------------------------
def test_compiled_frf_at_an_amplitude_equals_describing_frf(cm, osc):
    H = cm.frf({}, F, PAIR, amplitude={"F.f": 10.0})[PAIR[0]]
    ref = describing_frf(osc, "F.f", "m.s", F, 10.0)
    assert np.abs(H / ref.H[:, 0, 0] - 1).max() < 1e-5
    lin = cm.frf({}, F, PAIR)[PAIR[0]]
    assert np.all(np.isfinite(lin)) and np.abs(lin / H - 1).max() > 1e-3    # friction matters at 10 N


@pytest.mark.parametrize("kwargs, error, words", [
    ({"amplitude": {"F.f": 0.0}}, UsageError, ["amplitude['F.f']", "> 0"]),
    ({"amplitude": {"F.f": -1.0}}, UsageError, ["amplitude['F.f']", "> 0"]),
    ({"amplitude": {"F.f": float("nan")}}, UsageError, ["amplitude['F.f']", "finite"]),
    ({"amplitude": {"F.f": float("inf")}}, UsageError, ["amplitude['F.f']", "finite"]),
    ({"amplitude": {"F.f": "1"}}, UsageError, ["amplitude['F.f']", "number"]),
    ({"amplitude": {"amp.u": 1.0}}, UnknownNameError, ["amp.u", "not an input", "F.f"]),
    ({"amplitude": 1.0}, ArgumentTypeError, ["amplitude", "dict"]),
    ({"freqs": [0.0, 10.0]}, UsageError, ["freqs", "positive"]),
    ({"freqs": [-10.0]}, UsageError, ["freqs", "positive"]),
    ({"freqs": [np.nan]}, UsageError, ["freqs", "finite"]),
    ({"pairs": [("F.f", "m.v")]}, UnknownNameError, ["'m.v'", "not an output", "m.s"]),
    ({"pairs": [("amp.u", "m.s")]}, UnknownNameError, ["'amp.u'", "not an input", "F.f"]),
    ({"pairs": ["F.f"]}, ArgumentTypeError, ["pair", "(input, output)"]),
    ({"delay": -1.0}, UsageError, ["delay", ">= 0"]),
])
def test_compiled_frf_arguments(cm, kwargs, error, words):
    args = {"freqs": F, "pairs": PAIR, **kwargs}
    with pytest.raises(error) as exc:
        cm.frf({}, args.pop("freqs"), args.pop("pairs"), **args)
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_compiled_model_takes_a_name_a_dae_and_one_str(osc):
    sd = CompiledModel("small_drive", "motor.tau", "table.a")
    assert sd.inputs == ["motor.tau"] and sd.outputs == ["table.a"]
    assert CompiledModel(osc, "F.f", "m.s").inputs == ["F.f"]
    with pytest.raises(ArgumentTypeError, match="CompiledModel: system must be a bscomp.System, a system name"):
        CompiledModel(3, ["F.f"], ["m.s"])
    with pytest.raises(UnknownNameError, match=r"CompiledModel: 'fr\.w' is not an input .*\['F\.f'\]"):
        CompiledModel(osc, ["fr.w"], ["m.s"])
    with pytest.raises(UnknownNameError, match=r"CompiledModel.simulate: 'x\.u' is not an input"):
        sd.simulate({}, np.linspace(0, 0.01, 11), {"x.u": np.zeros(11)})


# ---- 3: sweeps -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, error, words", [
    ({"n_modes": -1}, UsageError, ["n_modes", ">= 1", "-1"]),
    ({"n_modes": 0}, UsageError, ["n_modes", ">= 1"]),
    ({"n_modes": 1.5}, ArgumentTypeError, ["n_modes", "whole number"]),
    ({"workers": "2"}, ArgumentTypeError, ["workers", "'2'"]),
    ({"workers": 0}, UsageError, ["workers", ">= 1"]),
    ({"workers": -3}, UsageError, ["workers", ">= 1"]),
])
def test_position_sweep_counts(kwargs, error, words):
    with pytest.raises(error) as exc:
        position_sweep(chain4, [1.0e4, 2.0e4], "k2.c", **kwargs)
    assert "position_sweep" in str(exc.value) and all(w in str(exc.value) for w in words), str(exc.value)


def test_position_sweep_valid_and_plot_errors():
    sw = position_sweep(chain4, [1.0e4, 2.0e4], "k2.c", n_modes=3, freqs=[5.0, 10.0], outputs="m4.s")
    assert sw.frequencies.shape == (2, 3) and np.all(np.isfinite(sw.frequencies)) and sw.outputs == ["m4.s"]
    full = position_sweep(chain4, [1.0e4, 2.0e4], "k2.c")
    np.testing.assert_allclose(sw.frequencies, full.frequencies[:, :3], rtol=1e-9)
    with pytest.raises(UsageError, match="kind must be 'frequencies' or 'frf', got 'x'"):
        sw.plot(kind="x")
    with pytest.raises(UnknownNameError, match=r"'nope' is not an output of this sweep; outputs: \['m4\.s'\]"):
        sw.plot(kind="frf", output="nope")
    with pytest.raises(UsageError, match="no FRFs: pass freqs"):
        full.plot(kind="frf")


G = {"table.m": [200.0, 250.0]}


@pytest.mark.parametrize("kwargs, error, words", [
    ({"n_modes": 2.9}, ArgumentTypeError, ["n_modes", "whole number", "2.9"]),
    ({"n_modes": 0}, UsageError, ["n_modes", ">= 1"]),
    ({"workers": "x"}, ArgumentTypeError, ["workers", "'x'"]),
    ({"workers": 0}, UsageError, ["workers", ">= 1"]),
    ({"workers": 2, "chunksize": 0}, UsageError, ["chunksize", ">= 1"]),
    ({"workers": 2, "chunksize": -1}, UsageError, ["chunksize", ">= 1"]),
])
def test_design_study_counts(kwargs, error, words):
    with pytest.raises(error) as exc:
        design_study("small_drive", G, **kwargs)
    assert "design_study" in str(exc.value) and all(w in str(exc.value) for w in words), str(exc.value)


def _none(spec):
    return None


def _text(spec):
    return {"a": "x"}


def _fails(spec):
    return 1 / 0


def _keys(spec):
    return {"a": 1.0} if spec.overrides["table.m"] < 220 else {"b": 2.0}


def _ok(spec):
    return {"m": spec.overrides["table.m"] * 2}


@pytest.mark.parametrize("analysis, error, words", [
    (_none, ArgumentTypeError, ["'_none'", "dict of numbers", "NoneType", "variant 0"]),
    (_text, ArgumentTypeError, ["'_text'", "numbers", "variant 0"]),
    (_fails, UsageError, ["'_fails'", "ZeroDivisionError", "variant 0 {'table.m': 200.0}"]),
    (_keys, UsageError, ["'_keys'", "['b']", "variant 1 {'table.m': 250.0}", "same keys"]),
])
def test_design_study_callable_results(analysis, error, words):
    with pytest.raises(error) as exc:
        design_study("small_drive", G, analysis, workers=1)
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_design_study_valid_calls_unchanged():
    t = design_study("small_drive", G, _ok, workers=1)
    assert t.columns == ["table.m", "m"] and t["m"].tolist() == [400.0, 500.0]
    m = design_study("small_drive", G, workers=1, n_modes=2)
    assert m.columns == ["table.m", "f1", "f2", "zeta1", "zeta2"] and np.all(np.isfinite(m.data))


# ---- 4: CMS reduction ----------------------------------------------------------------------------------------------
def _free_chain(n=6):
    Kc = np.diag([2.0] * n) - np.diag([1.0] * (n - 1), 1) - np.diag([1.0] * (n - 1), -1)
    Kc[0, 0] = Kc[-1, -1] = 1.0
    return np.eye(n), 1e4 * Kc


@pytest.mark.parametrize("kwargs, error, words", [
    ({"rigid_tol": -1}, UsageError, ["rigid_tol", "> 0"]),
    ({"rigid_tol": 1.0}, UsageError, ["rigid_tol", "< 1"]),
    ({"rigid_tol": "1e-8"}, UsageError, ["rigid_tol", "number"]),
    ({"n_modes": None, "f_cut": "10"}, UsageError, ["f_cut", "number"]),
    ({"n_modes": 10}, UsageError, ["10 mode(s) (+1 rigid-body) requested", "5 interior DOF"]),
])
def test_cms_arguments(kwargs, error, words):
    Mc, Kc = _free_chain()
    with pytest.raises(error) as exc:
        cms_reduce(Mc, Kc, [0], **{"n_modes": 1, **kwargs})
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_cms_messages_and_valid_call():
    Mc, Kc = _free_chain()
    with pytest.raises(UsageError, match=r"0 mode\(s\) \(\+1 rigid-body\) requested but only 0 interior DOF"):
        cms_reduce(Mc, Kc, list(range(6)), n_modes=0)
    Kg = Kc.copy()
    Kg[0, 0] += 1e4
    with pytest.raises(ParameterError, match=r"K must be positive semi-definite.*most negative eigenvalue .*-"):
        cms_reduce(Mc, -Kg, [0], n_modes=1)
    with pytest.raises(ParameterError, match="positive semi-definite"):
        cms_reduce(Mc, Kg - 1.5e4 * np.eye(6), [0], n_modes=1)
    red = cms_reduce(Mc, Kc, [0], n_modes=1)
    full = np.sqrt(np.clip(np.linalg.eigvalsh(Kc), 0, None)) / (2 * np.pi)
    f = red.natural_frequencies()
    assert f[0] < 1e-6 and abs(f[1] / full[1] - 1) < 0.05     # the first elastic mode is kept
    with pytest.raises(UsageError, match=r"F \(full load vector\) must have 6 rows"):
        red.force(np.zeros(3))
    with pytest.raises(UsageError, match="row: give DOF indices .* keeps no DOF names"):
        red.port("d0")
    with pytest.raises(UsageError, match="must be finite"):
        red.recover(np.full(red.n_reduced, np.nan))


def test_reduce_second_order_takes_one_name():
    so = second_order("small_drive")
    one, _ = reduce_second_order(so, "rotor.phi", 1)
    listed, _ = reduce_second_order(so, ["rotor.phi"], 1)
    assert one.coordinates == listed.coordinates == ["rotor.phi", "q_rb1", "q1"]


# ---- 5: stepped_sine checks offset before use ---------------------------------------------------------------------
@pytest.mark.parametrize("offset, words", [("1", "number"), (float("nan"), "finite")])
def test_stepped_sine_offset(osc, offset, words):
    with pytest.raises(UsageError, match=f"stepped_sine: offset must be (a )?{words}"):
        stepped_sine(osc, "F.f", "m.s", [10.0], 1.0, offset=offset)
