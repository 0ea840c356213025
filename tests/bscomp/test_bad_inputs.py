"""Library-level bad inputs (issue 15): each raises a named ``BscompError`` whose message names the offending thing.

One row per case: what is called, the error class expected and a regex the message must match (the name of
the argument, parameter, port or file at fault). Analyses use the small lumped ``small_drive`` (4 DOF) so the
whole table runs in seconds. ``docs/errors.md`` quotes some of these messages.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import bscomp
from bscomp import Component, System, Variable, flatten
from bscomp.components import Fixed, Gain, Inertia, Mass, Spring, StructuralBlock
from bscomp.errors import (
    ArgumentTypeError,
    BscompError,
    DuplicateNameError,
    ModelDefinitionError,
    OutputFileError,
    OverdeterminedError,
    ParameterError,
    ParameterFileError,
    PortConnectionError,
    SolverError,
    UnconnectedPortError,
    UnderdeterminedError,
    UnknownNameError,
    UsageError,
)
from bscomp.kernel.ports import Flange
from bscomp.model import as_dae, as_system
from bscomp.optimal import Ocp
from bscomp.optimal.problem import OcpError
from bscomp.simulation.result import SimulationError
from bscomp.systems import small_drive
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.testbed import testbed as make_testbed
from bscomp.validate import MeasurementFileError, load

T = np.linspace(0.0, 0.01, 11)
F = [5.0, 10.0]
NAN = math.nan


def sd():
    return small_drive()


class Dangling(Component):
    """A component with a variable no equation determines."""

    flange = Flange()
    x = Variable()

    def equations(self):
        return [self.flange.f]


def _underdetermined():
    s = System("custom")
    s.add("wall", Fixed())
    s.add("k", Spring(c=1.0e3))
    s.add("m", Mass(m=1.0))
    s.add("c", Dangling())
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("c.flange", "m.flange_b")
    return flatten(s)


def _overdetermined():
    s = System("o")
    s.add("g1", Fixed())
    s.add("g2", Fixed())
    s.add("m", Mass(m=1.0))
    s.connect("g1.flange", "m.flange_a")
    s.connect("g2.flange", "m.flange_a")
    s.connect("m.flange_b", "g1.flange")
    return flatten(s)


def _unconnected():
    s = System("s")
    s.add("m", Mass(m=1.0))
    s.add("k", Spring(c=1.0))
    return flatten(s)


def _two_sources():
    s = System("sig")
    for n in "abc":
        s.add(n, Gain(k=1.0))
    s.connect("a.y", "c.u")
    s.connect("b.y", "c.u")
    return flatten(s)


def _different_kinds():
    s = System("bad")
    s.add("m", Mass(m=1.0))
    s.add("J", Inertia(J=1.0))
    s.connect("m.flange_a", "J.flange_a")


def _frf_file(tmp):
    p = tmp / "h.csv"
    bscomp.frf(sd(), "motor.tau", "table.s", [10.0, 50.0, 100.0]).to_csv(p)
    return p


def _measurement(tmp, name, text, encoding="utf-8"):
    p = tmp / name
    p.write_bytes(text.encode(encoding))
    return p


PAIR = "f,re(table.s/motor.tau),im(table.s/motor.tau)"
UNIT = "# unit table.s/motor.tau: m/(N.m)\n"

CASES = [
    # ---- components and parameters -------------------------------------------------------------------
    ("mass_negative", lambda tmp: Mass(m=-1), ParameterError, r"Mass\.m = -1 kg must be > 0"),
    ("mass_nan", lambda tmp: Mass(m=NAN), ParameterError, r"Mass\.m \[kg\] is nan"),
    ("mass_inf", lambda tmp: Mass(m=math.inf), ParameterError, r"Mass\.m \[kg\] is inf"),
    ("mass_text", lambda tmp: Mass(m="abc"), ParameterError, r"Mass\.m \[kg\] must be a number.*'abc'"),
    ("mass_wrong_unit", lambda tmp: Mass(m="3 m"), ParameterError, r"Mass\.m: '3 m'.*'kg'"),
    ("mass_none", lambda tmp: Mass(m=None), ParameterError, r"Mass\.m \[kg\] has no value"),
    ("mass_bool", lambda tmp: Mass(m=True), ParameterError, r"Mass\.m \[kg\] must be a number, got True"),
    ("mass_unknown_keyword", lambda tmp: Mass(mass=1.0), UnknownNameError, r"Mass has no parameter.*'mass'"),
    ("spring_zero", lambda tmp: Spring(c=0.0), ParameterError, r"Spring\.c = 0\.0 N/m must be > 0"),
    ("inertia_negative", lambda tmp: Inertia(J=-1e-3), ParameterError, r"Inertia\.J = -0\.001"),
    ("mass_list", lambda tmp: Mass(m=[1, 2]), ParameterError, r"Mass\.m \[kg\] takes one real number, got \[1, 2\]"),
    ("mass_array", lambda tmp: Mass(m=np.array([3.0])), ParameterError, r"Mass\.m .*takes one real number"),
    ("mass_complex", lambda tmp: Mass(m=1 + 2j), ParameterError, r"Mass\.m \[kg\] must be a number, got \(1\+2j\)"),
    ("mass_numpy_complex", lambda tmp: Mass(m=np.complex128(2.0)), ParameterError, r"Mass\.m .*complex"),
    ("mass_bytes", lambda tmp: Mass(m=b"3"), ParameterError, r"Mass\.m .*b'3'"),
    ("mass_dict", lambda tmp: Mass(m={}), ParameterError, r"Mass\.m .*must be a number"),
    ("mass_overflowing_text", lambda tmp: Mass(m="1e400"), ParameterError, r"Mass\.m \[kg\] is inf"),
    ("spring_list", lambda tmp: Spring(c=(1e6, 2e6)), ParameterError, r"Spring\.c .*takes one real number"),
    ("set_list", lambda tmp: sd().set("table.m", [1.0, 2.0]), ParameterError,
     r"table\.m \(Mass\) \[kg\] takes one real number"),
    ("set_complex", lambda tmp: sd().set("table.m", 250j), ParameterError, r"table\.m \(Mass\).*250j"),
    ("set_negative_text", lambda tmp: sd().set("table.m", "-3 kg"), ParameterError, r"table\.m = -3\.0 kg"),
    ("set_not_a_name", lambda tmp: sd().set(3, 1.0), ArgumentTypeError, r"system\.set\(\).*got int 3"),
    ("set_unknown_parameter", lambda tmp: sd().set("table.mm", 1.0), UnknownNameError, r"table.*no parameter 'mm'"),
    ("set_unknown_component", lambda tmp: sd().set("tabel.m", 1.0), UnknownNameError, r"no component 'tabel'"),
    ("set_nan", lambda tmp: sd().set("table.m", NAN), ParameterError, r"table\.m \[kg\] is nan"),
    ("with_parameters_negative", lambda tmp: sd().with_parameters({"table.m": -3}), ParameterError,
     r"table\.m = -3 kg"),
    # ---- building a System -----------------------------------------------------------------------------
    ("connect_unknown_port", lambda tmp: sd().connect("table.flange_c", "ground.flange"), UnknownNameError,
     r"'table' \(Mass\) has no port 'flange_c'"),
    ("connect_unknown_component", lambda tmp: sd().connect("tabel.flange_a", "ground.flange"), UnknownNameError,
     r"no component 'tabel'"),
    ("connect_not_a_port", lambda tmp: sd().connect("table", "ground.flange"), UnknownNameError,
     r"'table' is not a port name"),
    ("connect_a_number", lambda tmp: sd().connect(3, "ground.flange"), ArgumentTypeError, r"got 3"),
    ("connect_to_itself", lambda tmp: sd().connect("table.flange_a", "table.flange_a"), PortConnectionError,
     r"'table\.flange_a' to itself"),
    ("connect_different_kinds", lambda tmp: _different_kinds(), PortConnectionError, r"m\.flange_a.*J\.flange_a"),
    ("connect_two_sources", lambda tmp: _two_sources(), PortConnectionError, r"'a\.y' and 'b\.y'.*c\.u"),
    ("add_duplicate_name", lambda tmp: sd().add("table", Mass(m=1.0)), DuplicateNameError,
     r"already has a component named 'table'"),
    ("add_dotted_name", lambda tmp: System("x").add("a.b", Mass(m=1.0)), DuplicateNameError,
     r"invalid component name 'a\.b'"),
    ("add_not_a_component", lambda tmp: System("x").add("m", 42), ArgumentTypeError, r"add\('m'.*got int"),
    ("remove_unknown", lambda tmp: sd().remove("nope"), UnknownNameError, r"no component 'nope'"),
    # ---- flattening ------------------------------------------------------------------------------------
    ("underdetermined", lambda tmp: _underdetermined(), UnderdeterminedError, r"c\.x"),
    ("overdetermined", lambda tmp: _overdetermined(), OverdeterminedError, r"'g2' \(Fixed\).*'g1'"),
    ("unconnected_port", lambda tmp: _unconnected(), UnconnectedPortError, r"'k\.flange_a'"),
    # ---- modes -----------------------------------------------------------------------------------------
    ("modes_n_zero", lambda tmp: bscomp.modes(sd(), n=0), UsageError, r"n must be >= 1, got 0"),
    ("modes_n_negative", lambda tmp: bscomp.modes(sd(), n=-1), UsageError, r"n must be >= 1, got -1"),
    ("modes_n_fraction", lambda tmp: bscomp.modes(sd(), n=1.5), UsageError, r"n must be an integer"),
    ("modes_fmax_negative", lambda tmp: bscomp.modes(sd(), fmax=-1), UsageError, r"fmax must be > 0"),
    ("modes_damping_method", lambda tmp: bscomp.modes(sd(), damping="foo"), UsageError, r"damping.*'foo'"),
    ("modes_unknown_input", lambda tmp: bscomp.modes(sd(), inputs=["motor.tauu"]), UnknownNameError,
     r"'motor\.tauu' is not an input"),
    ("modes_unknown_output", lambda tmp: bscomp.modes(sd(), outputs=["table.ss"]), UnknownNameError,
     r"'table\.ss'"),
    ("modes_unknown_operating_point", lambda tmp: bscomp.modes(sd(), at={"table.mm": 1}), UnknownNameError,
     r"'table\.mm'"),
    # ---- frf -------------------------------------------------------------------------------------------
    ("frf_zero_frequency", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", [0.0, 1.0]), UsageError,
     r"freqs.*positive.*got 0\.0"),
    ("frf_negative_frequency", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", [-1.0, 1.0]), UsageError,
     r"freqs.*got -1\.0"),
    ("frf_nan_frequency", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", [NAN, 1.0]), UsageError,
     r"freqs.*finite.*got nan"),
    ("frf_no_frequencies", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", []), UsageError,
     r"freqs must be a non-empty"),
    ("frf_text_frequencies", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", "abc"), UsageError,
     r"freqs.*'abc'"),
    ("frf_fmin_zero", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", fmin=0), UsageError, r"fmin must be > 0"),
    ("frf_fmin_above_fmax", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", fmin=100, fmax=10), UsageError,
     r"fmin=100\.0, fmax=10\.0"),
    ("frf_n_zero", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", n=0), UsageError, r"n must be >= 1"),
    ("frf_unknown_input", lambda tmp: bscomp.frf(sd(), "motor.tauu", "table.s", F), UnknownNameError,
     r"'motor\.tauu' is not an input"),
    ("frf_unknown_output", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.ss", F), UnknownNameError,
     r"'table\.ss'"),
    ("frf_csv_unit_not_si", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", F).to_csv(
        tmp / "x.csv", units={"table.s": "mm"}), UsageError, r"unit 'mm' of 'table\.s' is not SI"),
    ("frf_plot_unknown_extension", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", F).plot(tmp / "x.xyz"),
     OutputFileError, r"x\.xyz.*'\.xyz'"),
    # ---- simulate --------------------------------------------------------------------------------------
    ("simulate_nan_time", lambda tmp: bscomp.simulate(sd(), [0, NAN, 0.01]), UsageError,
     r"t holds a non-finite time at index 1"),
    ("simulate_decreasing_time", lambda tmp: bscomp.simulate(sd(), [0, 0.02, 0.01]), UsageError,
     r"t must be strictly increasing: t\[2\]"),
    ("simulate_one_time", lambda tmp: bscomp.simulate(sd(), [0.0]), UsageError, r"t must be .* at least two"),
    ("simulate_unknown_method", lambda tmp: bscomp.simulate(sd(), T, method="rk4"), UsageError,
     r"method must be one of .*'rk4'"),
    ("simulate_rtol_zero", lambda tmp: bscomp.simulate(sd(), T, rtol=0), UsageError, r"rtol must be > 0"),
    # an input beyond 1e100 is refused by every method before it runs (IDACalcIC did not return in 120 s on 1e150;
    # modal and fixed returned numbers of 1e150)
    ("simulate_idas_input_1e150", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": 1e150}),
     UsageError, r"input 'motor\.tau' = 1e\+150 on the interval starting at t = 0 s is beyond 1e\+100"),
    ("simulate_modal_input_1e150", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": 1e150},
                                                               method="modal"), UsageError, r"'motor\.tau' = 1e\+150"),
    ("simulate_fixed_input_1e150", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": -1e150},
                                                               method="fixed"), UsageError, r"'motor\.tau' = -1e\+150"),
    # within the input limit but the states run beyond it: IDAS before its first step, the others after the run
    ("simulate_idas_rate_beyond", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": 1e100}),
     SimulationError, r"the rate of state 'der\(rotor.phi\)' = 1.59e\+102, beyond 1e\+100 -- an input in the wrong"),
    ("simulate_fixed_states_beyond", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": 1e100},
                                                                 method="fixed"), SolverError,
     r"method='fixed'\) on 'small_drive': the states overflowed \(not finite or beyond 1e\+100\) with inputs "
     r"\|motor\.tau\| up to 1e\+100"),
    ("simulate_rtol_nan", lambda tmp: bscomp.simulate(sd(), T, rtol=NAN), UsageError, r"rtol must be finite"),
    ("simulate_atol_negative", lambda tmp: bscomp.simulate(sd(), T, atol=-1), UsageError, r"atol must be > 0"),
    ("simulate_substeps_zero", lambda tmp: bscomp.simulate(sd(), T, method="fixed", substeps=0), UsageError,
     r"substeps"),
    ("simulate_unknown_input", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tauu": 1.0}), UnknownNameError,
     r"'motor\.tauu' is not an input"),
    ("simulate_nan_input", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": NAN}), UsageError,
     r"input 'motor\.tau' is not finite"),
    ("simulate_input_length", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": np.ones(5)}), UsageError,
     r"input 'motor\.tau' has shape \(5,\)"),
    ("simulate_text_input", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": "abc"}), UsageError,
     r"input 'motor\.tau' must be a number.*'abc'"),
    ("simulate_unknown_output", lambda tmp: bscomp.simulate(sd(), T, outputs=["table.ss"]), UnknownNameError,
     r"'table\.ss'"),
    ("simulate_unknown_x0", lambda tmp: bscomp.simulate(sd(), T, x0={"table.ss": 1.0}), UnknownNameError,
     r"x0 names 'table\.ss'"),
    ("simulate_nan_x0", lambda tmp: bscomp.simulate(sd(), T, x0={"table.s": NAN}), UsageError,
     r"x0\['table\.s'\] must be finite"),
    ("simulate_unknown_parameter", lambda tmp: bscomp.simulate(sd(), T, params={"table.mm": 1.0}), UnknownNameError,
     r"no parameter 'mm'"),
    # ---- Ocp -------------------------------------------------------------------------------------------
    ("ocp_T_zero", lambda tmp: Ocp(sd()).minimize_effort(T=0), UsageError, r"T must be > 0, got 0"),
    ("ocp_T_negative", lambda tmp: Ocp(sd()).minimize_effort(T=-1), UsageError, r"T must be > 0, got -1"),
    ("ocp_T_nan", lambda tmp: Ocp(sd()).minimize_effort(T=NAN), UsageError, r"T must be finite"),
    ("ocp_T_guess_negative", lambda tmp: Ocp(sd()).minimize_time(T_guess=-1), UsageError, r"T_guess must be > 0"),
    ("ocp_bound_nan", lambda tmp: Ocp(sd()).bound("motor.tau", NAN, 1.0), UsageError,
     r"bound on 'motor\.tau': a bound is NaN"),
    ("ocp_bound_reversed", lambda tmp: Ocp(sd()).bound("motor.tau", 2.0, 1.0), UsageError,
     r"'motor\.tau': lower 2\.0 > upper 1\.0"),
    ("ocp_bound_unknown", lambda tmp: Ocp(sd()).bound("motor.tauu", -1, 1), UnknownNameError, r"'motor\.tauu'"),
    ("ocp_N_zero", lambda tmp: Ocp(sd(), N=0), UsageError, r"N must be >= 1, got 0"),
    ("ocp_degree_zero", lambda tmp: Ocp(sd(), degree=0), UsageError, r"degree must be >= 1"),
    ("ocp_coordinates", lambda tmp: Ocp(sd(), coordinates="polar"), UsageError, r"coordinates.*'polar'"),
    ("ocp_rate_negative", lambda tmp: Ocp(sd()).bound_rate("motor.tau", -1), UsageError,
     r"rate limit on 'motor\.tau' must be > 0"),
    ("ocp_final_nan", lambda tmp: Ocp(sd()).final({"table.s": NAN}), UsageError,
     r"final value of 'table\.s' must be finite"),
    ("ocp_initial_not_a_state", lambda tmp: Ocp(sd()).initial({"motor.tau": 0.0}), UnknownNameError,
     r"initial value for 'motor\.tau'"),
    ("ocp_no_objective", lambda tmp: Ocp(sd()).solve(), OcpError, r"no objective"),
    # ---- measurement files -----------------------------------------------------------------------------
    ("measurement_missing", lambda tmp: load(tmp / "missing.csv"), MeasurementFileError,
     r"missing\.csv: no such file"),
    ("measurement_empty", lambda tmp: load(_measurement(tmp, "e.csv", "")), MeasurementFileError,
     r"e\.csv, line 1.*empty file"),
    ("measurement_text_cell", lambda tmp: load(_measurement(tmp, "t.csv", f"# kind: frf\n{PAIR}\n1,2,3\n2,abc,4\n")),
     MeasurementFileError, r"t\.csv, line 4, column 2.*'abc' is not a number"),
    ("measurement_frequency_order", lambda tmp: load(_measurement(
        tmp, "o.csv", f"# kind: frf\n{PAIR}\n2,2,3\n1,1,4\n")),
     MeasurementFileError, r"o\.csv, line 4.*not strictly increasing"),
    ("measurement_unknown_unit", lambda tmp: load(_measurement(
        tmp, "u.csv", f"# kind: frf\n# unit table.s/motor.tau: furlong\n{PAIR}\n1,2,3\n2,1,4\n")),
     MeasurementFileError, r"u\.csv, line 2.*unknown unit 'furlong'"),
    ("measurement_condition_names_a_file", lambda tmp: load(_measurement(
        tmp, "c.csv", f"# kind: frf\n# condition params: ../../etc/passwd\n{PAIR}\n1,2,3\n2,1,4\n")),
     MeasurementFileError, r"c\.csv, line 2.*condition 'params' is not allowed"),
    ("measurement_latin1", lambda tmp: load(_measurement(
        tmp, "l.csv", f"# kind: frf\n# source: m\xe9sure\n{PAIR}\n1,2,3\n2,1,4\n", "latin-1")),
     MeasurementFileError, r"l\.csv, line 2: not a UTF-8"),
    ("measurement_ragged_row", lambda tmp: load(_measurement(tmp, "r.csv", f"# kind: frf\n{PAIR}\n1,2,3\n2,1\n")),
     MeasurementFileError, r"r\.csv, line 4.*row has 2 fields, the header has 3"),
    ("measurement_nan_value", lambda tmp: load(_measurement(
        tmp, "n.csv", "# kind: time\n# input motor.tau: N m\n# output table.s: m\nt,motor.tau,table.s\n"
        "0,1,nan\n0.1,1,2\n")), MeasurementFileError, r"n\.csv, line 5, column 3 \('table\.s'\).*not finite"),
    ("measurement_zero_response_row", lambda tmp: load(_measurement(
        tmp, "z.csv", f"# kind: frf\n{UNIT}{PAIR}\n1,2,3\n2,0,0\n3,1,4\n")),
     MeasurementFileError, r"z\.csv, line 5, column 2.*table\.s/motor\.tau is exactly 0 at f = 2 Hz"),
    ("measurement_zero_response_everywhere", lambda tmp: load(_measurement(
        tmp, "z0.csv", f"# kind: frf\n{UNIT}f,mag(table.s/motor.tau),phase_deg(table.s/motor.tau)\n1,0,0\n2,0,0\n")),
     MeasurementFileError, r"z0\.csv, line 4.*exactly 0 at every frequency"),
    ("measurement_mag_db_underflows", lambda tmp: load(_measurement(
        tmp, "u0.csv", f"# kind: frf\n{UNIT}f,mag_db(table.s/motor.tau),phase_deg(table.s/motor.tau)\n"
        "1,-20,0\n2,-9000,0\n")),
     MeasurementFileError, r"u0\.csv, line 5.*exactly 0"),
    # ---- parameter files (TOML) ------------------------------------------------------------------------
    ("parameter_file_missing", lambda tmp: load_parameters(tmp / "none.toml"), ParameterFileError,
     r"parameter file not found: .*none\.toml"),
    ("parameter_file_directory", lambda tmp: load_parameters(str(tmp) + "/"), ParameterFileError,
     r"is a directory"),
    ("parameter_file_not_toml", lambda tmp: load_parameters(_measurement(tmp, "b.toml", "x = = 1\n")),
     ParameterFileError, r"b\.toml: invalid TOML"),
    ("parameter_file_latin1", lambda tmp: load_parameters(_measurement(
        tmp, "l.toml", "[a]\nvalue = 1\nunit = 'm'\nsource = 'm\xe9sure'\n", "latin-1")), ParameterFileError,
     r"l\.toml: not UTF-8"),
    ("parameter_file_missing_source", lambda tmp: load_parameters(_measurement(
        tmp, "s.toml", "[g.k]\nvalue = 1\nunit = 'N/m'\n")), ParameterFileError,
     r"s\.toml: entry 'g\.k' lacks.*source"),
    ("parameter_file_nan_value", lambda tmp: load_parameters(_measurement(
        tmp, "n.toml", "[g.k]\nvalue = nan\nunit = 'N/m'\nsource = 'x'\n")), ParameterFileError,
     r"n\.toml: entry 'g\.k' has the value nan"),
    ("parameter_file_bool_value", lambda tmp: load_parameters(_measurement(
        tmp, "t.toml", "[g.k]\nvalue = true\nunit = 'N/m'\nsource = 'x'\n")), ParameterFileError,
     r"t\.toml: entry 'g\.k' has value True"),
    ("parameter_file_bare_value", lambda tmp: load_parameters(_measurement(tmp, "v.toml", "[g]\nk = 1\n")),
     ParameterFileError, r"v\.toml: key 'g\.k' is a bare value"),
    ("parameter_file_not_a_name", lambda tmp: load_parameters(3), ParameterFileError, r"got int 3"),
    ("parameter_entry_unknown", lambda tmp: get_value(load_parameters(), "screw.lenght"), UnknownNameError,
     r"no parameter entry 'screw\.lenght'"),
    # ---- a careless user across the public API (issue 15 review) ----------------------------------------
    ("modes_at_text", lambda tmp: bscomp.modes(sd(), at={"table.s": "abc"}), UsageError,
     r"at\['table\.s'\] must be a number"),
    ("modes_at_list", lambda tmp: bscomp.modes(sd(), at=[1, 2]), ArgumentTypeError, r"at must be a dict"),
    ("modes_params_list", lambda tmp: bscomp.modes("small_drive", params=[1, 2]), ArgumentTypeError,
     r"params must be a dict"),
    ("frf_input_a_number", lambda tmp: bscomp.frf(sd(), 3, "table.s", F), ArgumentTypeError,
     r"input must be a name.*3"),
    ("frf_output_a_list_of_numbers", lambda tmp: bscomp.frf(sd(), "motor.tau", [1, 2], F), ArgumentTypeError,
     r"output must be a name"),
    ("frf_csv_to_a_directory", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", F).to_csv(tmp), OutputFileError,
     r"is a directory"),
    ("frf_json_missing_folder", lambda tmp: bscomp.frf(sd(), "motor.tau", "table.s", F).to_json(tmp / "no" / "x.json"),
     OutputFileError, r"folder .*no' does not exist"),
    ("transfer_function_list", lambda tmp: bscomp.transfer_function(sd(), ["motor.tau"], "table.s"), ArgumentTypeError,
     r"SISO.*\['motor\.tau'\]"),
    ("transfer_function_modes_negative", lambda tmp: bscomp.transfer_function(sd(), "motor.tau", "table.s", modes=-1),
     UsageError, r"modes must be >= 0, got -1"),
    ("transfer_function_fmax_negative", lambda tmp: bscomp.transfer_function(sd(), "motor.tau", "table.s", fmax=-1),
     UsageError, r"fmax must be > 0"),
    ("simulate_inputs_list", lambda tmp: bscomp.simulate(sd(), T, inputs=[1.0]), ArgumentTypeError,
     r"inputs must be a dict"),
    ("simulate_input_function_raises", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": lambda t: 1 / 0}),
     UsageError, r"input 'motor\.tau': its function raised ZeroDivisionError at t = 0\.0005 s"),
    ("simulate_input_function_text", lambda tmp: bscomp.simulate(sd(), T, inputs={"motor.tau": lambda t: "x"}),
     UsageError, r"input 'motor\.tau': its function returned 'x'"),
    ("simulate_x0_list", lambda tmp: bscomp.simulate(sd(), T, x0=[1, 2]), ArgumentTypeError, r"x0 must be a dict"),
    ("simulate_x0_text", lambda tmp: bscomp.simulate(sd(), T, x0={"table.s": "abc"}), UsageError,
     r"x0\['table\.s'\] must be a number"),
    ("simulate_output_a_number", lambda tmp: bscomp.simulate(sd(), T, outputs=[1]), ArgumentTypeError,
     r"outputs must be names"),
    ("simulate_csv_to_a_directory", lambda tmp: bscomp.simulate(sd(), T).to_csv(tmp), OutputFileError,
     r"is a directory"),
    ("ocp_bound_text", lambda tmp: Ocp(sd()).bound("motor.tau", "a", 1), UsageError,
     r"bound on 'motor\.tau': the lower bound must be a number.*'a'"),
    ("ocp_bound_none", lambda tmp: Ocp(sd()).bound("motor.tau", -1, None), UsageError,
     r"'motor\.tau': the upper bound must be a number.*None"),
    ("ocp_scale_zero", lambda tmp: Ocp(sd()).bound("motor.tau", -1, 1, scale=0), UsageError,
     r"scale of 'motor\.tau' must be > 0"),
    ("ocp_scale_nan", lambda tmp: Ocp(sd()).bound("motor.tau", -1, 1, scale=NAN), UsageError,
     r"scale of 'motor\.tau' must be finite"),
    ("ocp_rate_text", lambda tmp: Ocp(sd()).bound_rate("motor.tau", "a"), UsageError,
     r"rate limit on 'motor\.tau' must be a number"),
    ("ocp_rate_nan", lambda tmp: Ocp(sd()).bound_rate("motor.tau", NAN), UsageError, r"rate limit on 'motor\.tau'"),
    ("ocp_final_list", lambda tmp: Ocp(sd()).final(["table.s"]), ArgumentTypeError, r"final\(values\) must be a dict"),
    ("ocp_final_text", lambda tmp: Ocp(sd()).final({"table.s": "a"}), UsageError,
     r"final value of 'table\.s' must be a number"),
    ("ocp_rest_below_negative", lambda tmp: Ocp(sd()).final({"table.s": 0.1}, rest_below_hz=-5), UsageError,
     r"rest_below_hz must be > 0"),
    ("ocp_T_text", lambda tmp: Ocp(sd()).minimize_effort(T="a"), UsageError, r"T must be a number, got 'a'"),
    ("ocp_weight_nan", lambda tmp: Ocp(sd()).minimize_effort(T=0.1, weights={"motor.tau": NAN}), UsageError,
     r"weight of 'motor\.tau' must be finite"),
    ("ocp_weight_unknown_input", lambda tmp: Ocp(sd()).minimize_effort(T=0.1, weights={"motor.tauu": 1.0}),
     UnknownNameError, r"weight for 'motor\.tauu'"),
    ("ocp_reference_not_callable", lambda tmp: Ocp(sd()).minimize_tracking(0.1, "table.s", 3.0), ArgumentTypeError,
     r"reference must be a function of t.*'table\.s'"),
    ("ocp_effort_weight_nan", lambda tmp: Ocp(sd()).minimize_tracking(0.1, "table.s", lambda t: 0.0,
                                                                      effort_weight=NAN), UsageError,
     r"effort_weight must be finite"),
    ("ocp_settle_negative", lambda tmp: Ocp(sd()).minimize_residual_vibration(0.1, "table.s", T_settle=-1), UsageError,
     r"T_settle must be > 0"),
    ("ocp_settle_longer_than_T", lambda tmp: Ocp(sd()).minimize_residual_vibration(0.1, "table.s", T_settle=5),
     UsageError, r"T_settle = 5\.0 s is longer than the horizon T = 0\.1 s"),
    ("ocp_limit_nan", lambda tmp: Ocp(sd()).limit_residual_vibration({"table.s": NAN}), UsageError,
     r"residual-vibration limit on 'table\.s'"),
    ("ocp_hold_nan", lambda tmp: Ocp(sd()).limit_residual_vibration({"table.s": 1e-6}, hold={"motor.tau": NAN}),
     UsageError, r"hold value of 'motor\.tau' must be finite"),
    ("ocp_warm_start_junk", lambda tmp: Ocp(sd()).warm_start(42), ArgumentTypeError,
     r"warm_start takes an OcpResult or a SimulationResult, got int"),
    ("ocp_N_text", lambda tmp: Ocp(sd(), N="a"), UsageError, r"N must be a number"),
    ("ocp_initial_nan", lambda tmp: Ocp(sd()).initial({"table.s": NAN}), UsageError,
     r"initial value of 'table\.s' must be finite"),
    ("compare_model_a_number", lambda tmp: bscomp.compare(42, _frf_file(tmp)), UnknownNameError,
     r"cannot use int as a model"),
    ("compare_data_a_number", lambda tmp: bscomp.compare(sd(), 42), ArgumentTypeError,
     r"measurements are a file path.*got int 42"),
    ("diagnose_data_a_number", lambda tmp: bscomp.diagnose(sd(), 42), ArgumentTypeError,
     r"measurements are a file path.*got int 42"),
    ("calibrate_nothing", lambda tmp: bscomp.calibrate(sd(), _frf_file(tmp), []), UsageError,
     r"uncertain is empty"),
    ("calibrate_spread_nan", lambda tmp: bscomp.calibrate(sd(), _frf_file(tmp), {"table.m": NAN}), UsageError,
     r"spread of 'table\.m' must be finite"),
    ("sweep_positions_text", lambda tmp: bscomp.position_sweep("small_drive", "nope"), UsageError,
     r"positions must be numbers.*'nope'"),
    ("sweep_positions_nan", lambda tmp: bscomp.position_sweep("small_drive", [0.1, NAN]), UsageError,
     r"positions must be a non-empty 1-D array of finite"),
    ("sweep_positions_empty", lambda tmp: bscomp.position_sweep("small_drive", []), UsageError,
     r"positions must be a non-empty"),
    ("sweep_method_unknown", lambda tmp: bscomp.position_sweep("small_drive", [0.1], method="fast"), UsageError,
     r"method must be 'auto', 'tangent' or 'rebuild', got 'fast'"),
    ("load_a_number", lambda tmp: load(42), MeasurementFileError, r"42: a measurement file is given by its path"),
    ("load_a_directory", lambda tmp: load(tmp), MeasurementFileError, r"no such file"),
    ("load_binary", lambda tmp: load(_measurement(tmp, "b.csv", "\x00\x01\x02", "latin-1")), MeasurementFileError,
     r"b\.csv"),
    ("second_order_model_with_params", lambda tmp: bscomp.modes(bscomp.second_order(sd()), params={"table.m": 1.0}),
     UsageError, r"'at' and 'params' cannot be applied to a SecondOrderModel"),
    # ---- model resolution ------------------------------------------------------------------------------
    ("model_a_number", lambda tmp: as_system(42), UnknownNameError, r"cannot use int as a model"),
    ("model_none", lambda tmp: as_dae(None), UnknownNameError, r"cannot use NoneType as a model"),
    ("model_unknown_name", lambda tmp: as_system("no_such_drive"), UnknownNameError,
     r"unknown system 'no_such_drive'.*small_drive"),
    ("model_missing_file", lambda tmp: as_system(str(tmp / "nope.py")), UnknownNameError,
     r"nope\.py' does not exist"),
    ("model_file_syntax_error", lambda tmp: as_system(str(_measurement(tmp, "broken.py", "def build(:\n"))),
     ModelDefinitionError, r"broken\.py, line 1: invalid syntax"),
    ("model_file_without_build", lambda tmp: as_system(str(_measurement(tmp, "nobuild.py", "x = 1\n"))),
     UnknownNameError, r"nobuild\.py must define build\(\)"),
    ("model_file_build_raises", lambda tmp: as_system(str(_measurement(
        tmp, "raises.py", "def build():\n    raise RuntimeError('oops')\n"))), ModelDefinitionError,
     r"raises\.py, line 2: RuntimeError in its build\(\): oops"),
    ("model_unknown_build_keyword", lambda tmp: as_system("small_drive", {"k_axiall": 1.0}), UnknownNameError,
     r"'k_axiall' is neither a parameter.*k_axial"),
    ("model_build_keyword_nan", lambda tmp: as_system("small_drive", {"k_axial": NAN}), ParameterError,
     r"Spring\.c \[N/m\] is nan"),
    ("model_build_returns_not_a_system", lambda tmp: as_system(lambda: 42), UnknownNameError,
     r"'<lambda>' returned int"),
    ("model_build_keyword_for_a_system", lambda tmp: as_system(sd(), {"k_axial": 1.0}), UnknownNameError,
     r"\['k_axial'\] are build keywords"),
    # ---- the CMS-reduced test bed (Sec 5.2.3) and the Ch 5 effects --------------------------------------------
    ("reduce_point_joint", lambda tmp: _reduce(make_testbed("axial_torsional")), ModelDefinitionError,
     r"moving screw-nut joint 'sn'.*nut_joint='moving'"),
    ("reduce_6dof_bed", lambda tmp: _reduce(make_testbed("full", nut_joint="moving")), ModelDefinitionError,
     r"axial \+ torsional test bed.*got variant 'full'"),
    ("reduce_negative_modes", lambda tmp: _reduce(make_testbed("axial_torsional", nut_joint="moving"), -1), UsageError,
     r"n_modes must be a non-negative integer, got -1"),
    ("reduce_too_many_modes", lambda tmp: _reduce(make_testbed("axial_torsional", nut_joint="moving"), 200), UsageError,
     r"200 mode\(s\) \(\+1 rigid-body\) requested but only 95 interior DOF"),
    ("reduce_unknown_anchor", lambda tmp: _reduce(make_testbed("axial_torsional", nut_joint="moving"),
                                                  anchor="screw.n99.tz"), UsageError,
     r"anchor 'screw.n99.tz' is neither 'centre' nor a DOF of sub-model 1 \(closest: \['screw.n9.tz'"),
    ("reduce_anchor_typo", lambda tmp: bscomp.systems.get("testbed_reduced", {"anchor": "centr"}), UsageError,
     r"anchor 'centr' is neither 'centre' nor a DOF"),
    ("effects_on_a_drive_without_table_joint", lambda tmp: _effects(sd()), ModelDefinitionError,
     r"'small_drive' needs the test bed's \['table', 'table_joint'\]"),
    ("structural_block_bad_kind", lambda tmp: StructuralBlock({"a": "Spring"}, ["a.s"], K=[[1.0]]),
     ModelDefinitionError, r"port 'a' has kind 'Spring'"),
    ("build_argument_out_of_bounds", lambda tmp: bscomp.modes("small_drive", params={"k_axial": -1.0}), ParameterError,
     r"system 'small_drive' built with k_axial=-1.0: parameter Spring.c"),
    ("component_positional_parameter", lambda tmp: Spring(1.0), ArgumentTypeError,
     r"Spring takes its parameters by name, e.g. Spring\(c=1.0\)"),
    ("output_of_no_component", lambda tmp: bscomp.linearize("small_drive", outputs=["x.y"]), UnknownNameError,
     r"no output named 'x.y' in 'small_drive'; no component 'x' has outputs; components: \['axial'"),
    ("output_typo_closest", lambda tmp: bscomp.linearize("small_drive", outputs=["tabel.s"]), UnknownNameError,
     r"closest: \['table.s'"),
    ("stepped_sine_offset_nan", lambda tmp: bscomp.stepped_sine(sd(), "motor.tau", "table.s", F, 1.0, offset=NAN),
     UsageError, r"offset must be finite"),
    ("stepped_sine_max_settle_below_settle", lambda tmp: bscomp.stepped_sine(sd(), "motor.tau", "table.s", F, 1.0,
                                                                              settle=10, max_settle=5),
     UsageError, r"max_settle = 5 periods is less than settle = 10"),
    ("simulate_bool_as_number", lambda tmp: bscomp.simulate(sd(), T, max_order=True), UsageError,
     r"max_order must be a number, got True \(bool\)"),
    ("inputs_not_names", lambda tmp: bscomp.linearize("small_drive", inputs=3), ArgumentTypeError,
     r"inputs must be a name or a list of names"),
    ("outputs_not_names", lambda tmp: bscomp.modes("small_drive", outputs=[1, 2]), ArgumentTypeError,
     r"outputs must be a name or a list of names"),
]


def _reduce(full, n_modes=3, **kw):
    from bscomp.systems.reduced_testbed import reduce_testbed

    return reduce_testbed(full, n_modes, **kw)


def _effects(system):
    from bscomp.systems.thesis_effects import with_friction_backlash

    return with_friction_backlash(system)


@pytest.mark.parametrize("call, error, message", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_raises_a_named_error(tmp_path, call, error, message):
    assert issubclass(error, BscompError)
    with pytest.raises(error, match=message) as info:
        call(tmp_path)
    assert isinstance(info.value, BscompError)


def test_the_table_is_large_and_ids_are_unique():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids)) and len(ids) >= 40


def test_one_name_is_one_name_not_its_characters():
    """``inputs="motor.tau"`` is the input motor.tau (it was split into 'm', 'o', ...)."""
    one = bscomp.linearize("small_drive", inputs="motor.tau", outputs="table.s")
    listed = bscomp.linearize("small_drive", inputs=["motor.tau"], outputs=["table.s"])
    assert one.ninputs == 1 and one.noutputs == 1
    np.testing.assert_allclose(one.C @ np.linalg.solve(-one.A + 1e-9 * np.eye(one.nstates), one.B),
                               listed.C @ np.linalg.solve(-listed.A + 1e-9 * np.eye(listed.nstates), listed.B))


def test_python_bases_are_kept():
    """Named errors keep the built-in base a Python caller might catch."""
    assert issubclass(UsageError, ValueError) and issubclass(ParameterError, ValueError)
    assert issubclass(ArgumentTypeError, TypeError) and issubclass(UnknownNameError, KeyError)
    assert issubclass(OutputFileError, OSError) and issubclass(MeasurementFileError, ValueError)
