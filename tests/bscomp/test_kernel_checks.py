"""Kernel checks on how components are written and systems edited: templates shared only when the
equations are the same, der() of what has no derivative, foreign symbols, what equations() returns,
declaration clashes, System editing guards. Each bad input raises its named error naming the part."""

import casadi as ca
import numpy as np
import pytest

from bscomp import Component, Parameter, System, Variable, flatten, modes
from bscomp.components import Fixed, Force, Mass, Spring
from bscomp.errors import (
    ArgumentTypeError,
    DuplicateNameError,
    ModelDefinitionError,
    OverdeterminedError,
    PortConnectionError,
)
from bscomp.kernel.ports import Flange


class Gnd(Component):
    """Spring to ground whose stiffness is a plain instance attribute (not a Parameter)."""

    flange = Flange("to the mass")

    def __init__(self, k=1.0, **kw):
        self.k = k
        super().__init__(**kw)

    def equations(self):
        return [self.flange.f - self.k * self.flange.s]


def _two_masses(k1, k2):
    s = System("two")
    s.add("m1", Mass(m=1.0))
    s.add("m2", Mass(m=1.0))
    s.add("g1", Gnd(k=k1))
    s.add("g2", Gnd(k=k2))
    s.connect("g1.flange", "m1.flange_a")
    s.connect("g2.flange", "m2.flange_a")
    return s


def _osc(extra=None, *conns):
    s = System("osc")
    s.add("wall", Fixed())
    s.add("k", Spring(c=1e4))
    s.add("m", Mass(m=2.0))
    s.add("F", Force())
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("F.flange", "m.flange_b")
    if extra is not None:
        s.add("u", extra)
        for a, b in conns:
            s.connect(a, b)
    return s


# ---- templates: shared only when the equations are the same -------------------------------------
def test_instance_attribute_gives_own_template():
    f = np.sort(modes(_two_masses(100.0, 1e4)).frequencies)
    np.testing.assert_allclose(f, np.sqrt([100.0, 1e4]) / (2 * np.pi), rtol=1e-9)   # 1.59, 15.9 Hz


def test_equal_attributes_share_one_template():
    d = flatten(_two_masses(100.0, 100.0))
    assert d.stats["templates"] == 2            # Mass and Gnd, once each
    d = flatten(_two_masses(100.0, 1e4))
    assert d.stats["templates"] == 3            # Gnd twice: k differs


def test_chain_of_identical_elements_shares_templates():
    s = System("chain")
    s.add("wall", Fixed())
    prev = "wall.flange"
    for i in range(30):
        s.add(f"k{i}", Spring(c=1e4 * (1 + i)))     # other parameter values: same template
        s.add(f"m{i}", Mass(m=1.0 + i))
        s.connect(prev, f"k{i}.flange_a")
        s.connect(f"k{i}.flange_b", f"m{i}.flange_a")
        prev = f"m{i}.flange_b"
    assert flatten(s).stats["templates"] == 3


class RefVar(Component):
    flange = Flange("f")
    x = Variable()

    def __init__(self, other=None, **kw):
        super().__init__(**kw)
        self.other = other

    def equations(self):
        return [self.flange.f - self.x, self.x - (self.other.x if self.other is not None else 0.0)]


def test_equations_reading_another_component_name_both():
    s = _osc()
    a = s.add("a", RefVar())
    s.connect("a.flange", "m.flange_a")
    s.add("b", RefVar(other=a))
    s.connect("b.flange", "m.flange_a")
    with pytest.raises(ModelDefinitionError, match=r"'b' \(RefVar\) read variable 'x' of another component 'a'"):
        flatten(s)


# ---- der() ---------------------------------------------------------------------------------------
class Damp(Component):
    flange = Flange("f")
    d = Parameter(10.0, unit="N.s/m")
    mode = "ok"

    def equations(self):
        f, s = self.flange.f, self.flange.s
        cases = {"ok": lambda: [f - self.d * self.der(s)], "flow": lambda: [f - self.d * self.der(f)],
                 "third": lambda: [f - self.der(self.der(self.der(s)))], "param": lambda: [f - self.der(self.d) * s],
                 "foreign": lambda: [f - self.d * ca.SX.sym("m.flange_a.s")], "none": lambda: None,
                 "tuple": lambda: (f - self.d * self.der(s),), "single": lambda: f - self.d * self.der(s),
                 "str": lambda: ["x"], "nan": lambda: [f - float("nan") * s], "inf": lambda: [f - float("inf") * s]}
        return cases[self.mode]()


def _damped(mode, monkeypatch):
    monkeypatch.setattr(Damp, "mode", mode)
    return _osc(Damp(), ("u.flange", "m.flange_a"))


@pytest.mark.parametrize("mode", ["flow", "third"])
def test_der_of_what_has_no_derivative_is_refused(mode, monkeypatch):
    with pytest.raises(ModelDefinitionError, match=r"der\(\) in component 'u' \(Damp\) cannot differentiate.*"
                                                   r"Declare a Variable"):
        flatten(_damped(mode, monkeypatch))


@pytest.mark.parametrize("mode", ["ok", "tuple", "single"])
def test_damper_damps(mode, monkeypatch):
    zeta = modes(_damped(mode, monkeypatch)).damping[0]
    assert zeta == pytest.approx(10.0 / (2 * np.sqrt(1e4 * 2.0)), rel=1e-9)


def test_der_of_parameter_is_zero(monkeypatch):
    assert modes(_damped("param", monkeypatch)).damping[0] == pytest.approx(0.0, abs=1e-12)


def test_a_template_is_shared_across_flattenings_only_while_what_its_equations_read_is_unchanged(monkeypatch):
    """A second flattening of the same component (same parameter values, the same values of the attributes its
    equations read) reuses the first one's template; a class attribute changed in between (``Damp.mode``) or another
    parameter value gets a new one, with its own equations."""
    from bscomp.kernel import templates

    monkeypatch.setattr(templates, "_SHARED", {})                   # this test's flattenings only

    def damp_keys():
        return [k for k in templates._SHARED if k[0][0] is Damp]

    zeta = modes(_damped("ok", monkeypatch)).damping[0]
    n = len(damp_keys())
    assert n == 1 and modes(_damped("ok", monkeypatch)).damping[0] == zeta       # reused: the same model
    d = flatten(_damped("ok", monkeypatch))
    assert d.stats["templates_built"] == 0 and d.stats["templates"] >= 2          # no symbolic pass at all
    assert len(damp_keys()) == n and len(templates._SHARED[damp_keys()[-1]]) == 1
    assert modes(_damped("param", monkeypatch)).damping[0] == pytest.approx(0.0, abs=1e-12)   # re-built
    assert len(templates._SHARED[damp_keys()[-1]]) == 2
    s = _damped("ok", monkeypatch)
    s.set("u.d", 20.0)
    d = flatten(s)                          # another value of d: the same template (no coefficient judged at d)
    assert d.stats["templates_built"] == 0 and modes(d).damping[0] == pytest.approx(2 * zeta, rel=1e-9)


def test_explicit_solving_says_when_it_judged_a_coefficient_at_the_parameter_values():
    """``k y - x = 0`` is solved for ``y`` only because ``k`` is not 0 at its value: such a template is kept for
    those values only (``shared_template``); ``y - k x = 0`` holds for every ``k``."""
    from bscomp.kernel.templates import eliminate_explicit

    k, x, y = ca.SX.sym("k"), ca.SX.sym("x"), ca.SX.sym("y")
    for eq, read in ((k * y - x, [True]), (y - k * x, [])):
        values_read = []
        solved, _, used = eliminate_explicit([eq], [y], (k, np.array([2.0]), ca.SX(0, 1)), values_read)
        assert list(solved) == [0] and used == {0} and values_read == read
    values_read = []
    solved, _, _ = eliminate_explicit([k * y - x], [y], (k, np.array([0.0]), ca.SX(0, 1)), values_read)
    assert not solved and values_read == [True]                       # k = 0 there: not explicit


# ---- what equations() returns ---------------------------------------------------------------------
@pytest.mark.parametrize("mode, msg", [
    ("foreign", r"'u' \(Damp\) uses symbol\(s\) \['m.flange_a.s'\] that are not its own"),
    ("none", r"equations\(\) of component 'u' \(Damp\) must return a list.*missing 'return'"),
    ("str", r"equation 0 of component 'u' \(Damp\) is str 'x'"),
    ("nan", r"equations of component 'u' \(Damp\) contain the constant nan"),
    ("inf", r"equations of component 'u' \(Damp\) contain the constant inf"),
])
def test_bad_equations_named(mode, msg, monkeypatch):
    with pytest.raises(ModelDefinitionError, match=msg):
        flatten(_damped(mode, monkeypatch))


class Rod(Component):
    flange_a = Flange("a")
    flange_b = Flange("b")
    lam = Variable()

    def equations(self):
        sa, sb, lam = self.flange_a.s, self.flange_b.s, self.lam
        return [self.flange_a.f - lam, self.flange_b.f + lam, (sb - sa) + lam * (sb - sa)]


def test_coefficient_depending_on_potentials_is_no_casadi_error():
    s = _osc(Rod(), ("u.flange_a", "m.flange_b"))
    s.add("m2", Mass(m=1.0))
    s.connect("u.flange_b", "m2.flange_a")
    with pytest.raises(Exception) as info:
        flatten(s)
    assert "free" not in str(info.value) and type(info.value).__module__ == "bscomp.errors"


# ---- declarations -------------------------------------------------------------------------------
def test_portspec_bound_to_two_names():
    with pytest.raises(ModelDefinitionError, match=r"Two: one port object is declared under two names, 'a' and "
                                                   r"'b'.*PortSpec instance can be declared once"):
        class Two(Component):
            a = Flange("a")
            b = a


def test_variable_shadowing_inherited_parameter():
    class A(Component):
        flange = Flange("x")
        c = Parameter(1.0, unit="N/m")

    with pytest.raises(ModelDefinitionError, match=r"B.c is declared as a Variable but A.c is a Parameter"):
        class B(A):
            c = Variable()


def test_add_port_same_spec_twice():
    class Two(Component):
        def __init__(self):
            super().__init__()
            spec = Flange("x")
            self.add_port("x", spec)
            self.add_port("y", spec)

    with pytest.raises(ModelDefinitionError, match=r"already the port 'x'"):
        Two()


# ---- connections and System editing -------------------------------------------------------------
def test_connect_port_to_itself():
    with pytest.raises(PortConnectionError, match=r"'m.flange_a' to itself"):
        _osc().connect("m.flange_a", "m.flange_a")


def test_two_ports_of_one_rigid_component_connected_names_it():
    s = _osc()
    s.connect("m.flange_a", "m.flange_b")
    with pytest.raises(OverdeterminedError, match=r"constraint of 'm' \(Mass\) repeats what the connections"):
        flatten(s)


def test_replace_with_a_member_or_a_number():
    s = _osc()
    with pytest.raises(DuplicateNameError, match=r"already in system 'osc' as 'm'"):
        s.replace("k", s.component("m"))
    with pytest.raises(ArgumentTypeError, match=r"replace\('k', ...\) needs a Component or System, got int"):
        s.replace("k", 5)
    assert s.component("k").get("c") == 1e4


def test_system_cycles_refused():
    s = _osc()
    with pytest.raises(DuplicateNameError, match="cannot contain itself"):
        s.add("self", s)
    outer = System("outer")
    outer.add("inner", s)
    with pytest.raises(DuplicateNameError, match="'outer' already contains 'osc'"):
        s.add("again", outer)


def test_with_parameters_needs_a_mapping():
    with pytest.raises(ArgumentTypeError, match=r"with_parameters\(overrides\) must be a dict"):
        _osc().with_parameters([("m.m", 3.0)])
    assert _osc().with_parameters({"m.m": 3.0}).get("m.m") == 3.0
