"""Bad input to :class:`bscomp.optimal.Ocp` is refused up front with a named error (bscomp.optimal.checks),
and a valid problem still solves to the same optimum."""

import math

import numpy as np
import pytest

from bscomp import System
from bscomp.components import Inertia, Torque
from bscomp.errors import ArgumentTypeError, UnknownNameError, UsageError
from bscomp.optimal import Ocp, OcpError, OcpResult
from bscomp.optimal.checks import MAX_DEGREE

J, TAU, THETA = 8.55e-3, 5.0, 10.0
T_BANG = 2 * math.sqrt(THETA * J / TAU)          # rest-to-rest minimum time of a rigid inertia


def rotor():
    s = System("rotor")
    s.add("motor", Torque())
    s.add("rotor", Inertia(J=J))
    s.connect("motor.flange", "rotor.flange_a")
    return s


@pytest.fixture(scope="module")
def drive():
    return Ocp("small_drive", N=10).dae


def move(N=20, **kw):
    return (Ocp(rotor(), N=N, **kw).bound("motor.tau", -TAU, TAU).initial({"rotor.phi": 0.0})
            .final({"rotor.phi": THETA}))


# ---- 1. parameters and constants are not signals --------------------------------------------------------
@pytest.mark.parametrize("call, what", [
    (lambda o: o.minimize_tracking(T=0.1, output="rotor.J", reference=lambda t: 0.0), "minimize_tracking"),
    (lambda o: o.bound("rotor.J", 1.0, 2.0), "bound"),
    (lambda o: o.bound_rate("rotor.J", 1.0), "bound_rate"),
    (lambda o: o.limit_residual_vibration({"rotor.J": 1e-6}), "limit_residual_vibration"),
    (lambda o: o.minimize_residual_vibration(T=0.1, output="rotor.J", T_settle=0.05), "minimize_residual"),
])
def test_a_parameter_is_not_a_signal(drive, call, what):
    with pytest.raises(UnknownNameError, match=r"'rotor\.J' of 'small_drive' is a parameter, not a signal") as info:
        call(Ocp(drive, N=10))
    msg = str(info.value)
    assert msg.startswith(what) and "outputs of 'rotor': ['rotor.phi'" in msg
    assert "rotor.J'" not in msg.split("outputs of")[1]


def test_a_constant_output_is_not_a_signal(drive):
    with pytest.raises(UnknownNameError, match=r"'ground\.flange\.s' of 'small_drive' is a constant, not a signal"):
        Ocp(drive, N=10).bound("ground.flange.s", -1, 1)
    Ocp(drive, N=10).bound("table.v", -1, 1).bound("motor.tau", -8, 8)     # real signals still accepted


# ---- 2. bound pairs that admit no value -----------------------------------------------------------------
@pytest.mark.parametrize("name, lo, hi", [("motor.tau", np.inf, np.inf), ("table.v", -np.inf, -np.inf),
                                          ("table.s", np.inf, np.inf)])
def test_bound_pair_without_a_finite_value_is_refused(drive, name, lo, hi):
    with pytest.raises(UsageError, match=rf"bound on '{name}': lo={lo}, hi={hi} admits no finite value"):
        Ocp(drive, N=10).bound(name, lo, hi)


def test_one_sided_bounds_are_kept(drive):
    o = Ocp(drive, N=10).bound("table.v", -np.inf, 1.0).bound("motor.tau", -8.0, np.inf)
    assert o.bounds == {"table.v": (-np.inf, 1.0), "motor.tau": (-8.0, np.inf)}


# ---- 3. collocation degree, 9. N and degree as bools ----------------------------------------------------
def test_degree_range(drive):
    with pytest.raises(UsageError, match=rf"degree must be <= {MAX_DEGREE} .* got 12"):
        Ocp(drive, degree=12)
    assert Ocp(drive, degree=MAX_DEGREE).d == MAX_DEGREE


@pytest.mark.parametrize("kw, name", [({"N": True}, "N"), ({"degree": True}, "degree"), ({"N": np.bool_(1)}, "N")])
def test_bools_are_not_counts(drive, kw, name):
    with pytest.raises(UsageError, match=rf"{name} must be a number, got (np\.)?True"):
        Ocp(drive, **kw)


# ---- 4. solver options ----------------------------------------------------------------------------------
@pytest.mark.parametrize("options, error, pattern", [
    ([1], ArgumentTypeError, r"solver_options must be a dict of Ipopt options.*got list"),
    ({"bad_opt": 1}, UsageError, r"solver_options: Ipopt does not accept option 'bad_opt' = 1 \(No such IPOPT option"),
    ({"max_iter": -5}, UsageError, r"solver_options\['max_iter'\] must be >= 0, got -5"),
    ({"max_iter": 2.5}, UsageError, r"solver_options\['max_iter'\] must be an integer"),
    ({"mu_strategy": "fast"}, UsageError,
     r"option 'mu_strategy' = 'fast' .*valid settings: \['monotone', 'adaptive'\]"),
    ({"tol": "small"}, UsageError, r"option 'tol' = 'small'"),
    ({3: 1}, ArgumentTypeError, r"option names must be str, got 3"),
])
def test_solver_options_are_checked_before_solving(options, error, pattern):
    ocp = move().minimize_effort(T=0.1)
    with pytest.raises(error, match=pattern):
        ocp.solve(options)


def test_bad_default_ipopt_option_names_its_source():
    ocp = move().minimize_effort(T=0.1)
    ocp.ipopt_options["mumps_pivtoll"] = 1e-2
    with pytest.raises(UsageError, match=r"^Ocp\.ipopt_options: .* 'mumps_pivtoll'"):
        ocp.solve()


# ---- 5. residual-vibration limits must be numbers -------------------------------------------------------
@pytest.mark.parametrize("value, pattern", [("1e-6", r"must be a number, got '1e-6'"),
                                            (None, r"must be a number, got None"),
                                            (0.0, r"must be > 0"), (np.nan, r"must be finite")])
def test_residual_vibration_limit_must_be_a_positive_number(drive, value, pattern):
    with pytest.raises(UsageError, match=r"residual-vibration limit on 'table\.s' " + pattern):
        Ocp(drive, N=10).limit_residual_vibration({"table.s": value})


# ---- 6. tracking references are evaluated up front ------------------------------------------------------
def test_reference_that_raises_is_named():
    with pytest.raises(UsageError, match=r"reference .*'rotor\.phi'.* raised ZeroDivisionError: .* at t = ") as info:
        move().minimize_tracking(T=0.1, output="rotor.phi", reference=lambda t: 1 / 0)
    assert isinstance(info.value.__cause__, ZeroDivisionError)


@pytest.mark.parametrize("ref, error, pattern", [
    (lambda t: "a", ArgumentTypeError, r"must return one real number, got str 'a'"),
    (lambda t: np.array([0.0, 1.0]), ArgumentTypeError, r"must return one real number, got ndarray"),
    (lambda t: None, ArgumentTypeError, r"must return one real number, got NoneType"),
    (lambda t: np.nan if t > 0.05 else 0.0, UsageError, r"returned nan at t = 0\.05\d* s; it must be finite"),
])
def test_reference_must_give_finite_scalars(ref, error, pattern):
    with pytest.raises(error, match=r"^reference \(the wanted 'rotor\.phi' as a function of t\) " + pattern):
        move().minimize_tracking(T=0.1, output="rotor.phi", reference=ref)


def test_tracking_with_numpy_scalar_reference_solves():
    """A reference returning 0-d arrays is fine; tracking a reachable ramp-and-hold ends near it."""
    ref = lambda t: np.asarray(min(t / 0.1, 1.0) * 1.0)   # noqa: E731
    r = (Ocp(rotor(), N=20).bound("motor.tau", -TAU, TAU).initial({"rotor.phi": 0.0})
         .minimize_tracking(T=0.2, output="rotor.phi", reference=ref).solve())
    assert r.stats["return_status"] == "Solve_Succeeded"
    assert r["rotor.phi"][-1] == pytest.approx(1.0, abs=0.05)


# ---- 7. boundary values outside their own path bounds ---------------------------------------------------
def test_initial_state_outside_its_bound():
    ocp = move().bound("rotor.phi", 1.0, 20.0).minimize_effort(T=0.1)
    with pytest.raises(OcpError, match=r"initial value of 'rotor\.phi' = 0 rad is outside its path bound \[1, 20\] rad "
                                       r"\(the lower bound 1 rad\)") as info:
        ocp.solve()
    assert info.value.infeasibility["worst"]["variable"] == "rotor.phi"


def test_final_target_outside_its_bound():
    with pytest.raises(OcpError, match=r"final value of 'rotor\.phi' = 10 rad is outside .*upper bound 5 rad"):
        move().bound("rotor.phi", -1.0, 5.0).minimize_effort(T=0.1).solve()
    with pytest.raises(OcpError, match=r"final value of 'der\(rotor\.phi\)' = 0 rad/s .*lower bound 1 rad/s.*rest"):
        move().initial({"der(rotor.phi)": 2.0}).bound("der(rotor.phi)", 1.0, 100.0).minimize_effort(T=0.1).solve()


# ---- 8. warm starts from another model ------------------------------------------------------------------
def test_warm_start_from_another_model_is_refused(drive):
    other = OcpResult(T=0.1, t=np.linspace(0, 0.1, 3), x=np.zeros((3, 2)), u=np.zeros((2, 1)), outputs={},
                      x_names=["rotor.phi", "der(rotor.phi)"], u_names=["motor.tau"], active={})
    with pytest.raises(UsageError, match=r"warm_start: the result is of 'another model', not of 'small_drive'"):
        Ocp(drive, N=10).warm_start(other)


# ---- a valid problem still solves to the same optimum ---------------------------------------------------
def test_valid_problem_still_solves_to_the_bang_bang_time():
    ocp = move(N=40).minimize_time(T_guess=0.5)
    r = ocp.solve({"max_iter": 500})
    assert r.T == pytest.approx(T_BANG, rel=1e-3)
    r2 = move(N=40).minimize_time(T_guess=0.5).warm_start(r).solve()     # same model: accepted
    assert r2.T == pytest.approx(r.T, rel=1e-6)
