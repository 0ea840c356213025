"""Each class of bad input raises its named error, naming the component/port/parameter."""

import math

import pytest

import bscomp
from bscomp import Component, Parameter, System, Variable, flatten
from bscomp.components import Fixed, Force, Inertia, Mass, Spring, Torque
from bscomp.errors import (
    DuplicateNameError,
    HighIndexError,
    ModelDefinitionError,
    OverdeterminedError,
    ParameterError,
    PortConnectionError,
    UnconnectedPortError,
    UnderdeterminedError,
    UnknownNameError,
)
from bscomp.kernel.ports import Flange


def test_connecting_different_kinds_names_both_ports():
    s = System("bad")
    s.add("m", Mass(m=1.0))
    s.add("J", Inertia(J=1.0))
    with pytest.raises(PortConnectionError, match=r"m\.flange_a.*J\.flange_a"):
        s.connect("m.flange_a", "J.flange_a")


def test_connecting_signals_of_different_units():
    s = System("bad")
    s.add("F", Force())
    s.add("T", Torque())
    s.add("m", Mass(m=1.0))
    s.add("sensor", bscomp.components.PositionSensor())
    with pytest.raises(PortConnectionError, match=r"sensor\.s.*\[m\].*F\.f.*\[N\]"):
        s.connect("sensor.s", "F.f")


def test_two_outputs_on_one_signal():
    s = System("bad")
    s.add("a", bscomp.components.PositionSensor())
    s.add("b", bscomp.components.PositionSensor())
    with pytest.raises(PortConnectionError, match="two outputs"):
        s.connect("a.s", "b.s")


def test_duplicate_and_invalid_names():
    s = System("dup")
    s.add("m", Mass(m=1.0))
    with pytest.raises(DuplicateNameError, match="already has a component named 'm'"):
        s.add("m", Mass(m=2.0))
    with pytest.raises(DuplicateNameError, match="invalid component name"):
        s.add("a.b", Mass(m=2.0))
    m = Mass(m=1.0)
    s.add("m2", m)
    with pytest.raises(DuplicateNameError, match="already in system"):
        System("other").add("x", m)


def test_unknown_names():
    s = System("u")
    s.add("m", Mass(m=1.0))
    with pytest.raises(UnknownNameError, match="no port 'flange_c'"):
        s.connect("m.flange_c", "m.flange_a")
    with pytest.raises(UnknownNameError, match="no parameter 'k'"):
        s.set("m.k", 1.0)
    with pytest.raises(UnknownNameError, match="no component 'n'"):
        s.set("n.m", 1.0)


@pytest.mark.parametrize("value, msg", [(-1.0, "must be > 0"), (0.0, "must be > 0"),
                                        (math.nan, "NaN"), (math.inf, "NaN and inf"), ("abc", "must be a number")])
def test_non_physical_parameters(value, msg):
    with pytest.raises(ParameterError, match=msg):
        Mass(m=value)
    s = System("p")
    s.add("m", Mass(m=1.0))
    with pytest.raises(ParameterError, match=r"m\.m"):
        s.set("m.m", value)


def test_missing_parameter_value():
    s = System("p")
    s.add("wall", Fixed())
    s.add("k", Spring())
    s.add("m", Mass(m=1.0))
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    with pytest.raises(ParameterError, match=r"k\.c .*no value"):
        flatten(s)


def test_unconnected_required_port():
    s = System("open")
    s.add("wall", Fixed())
    s.add("k", Spring(c=1.0))
    s.connect("wall.flange", "k.flange_a")
    with pytest.raises(UnconnectedPortError, match=r"k\.flange_b.*not connected"):
        flatten(s)


def test_point_fixed_twice_is_overdetermined():
    s = System("twice")
    s.add("w1", Fixed())
    s.add("w2", Fixed())
    s.add("m", Mass(m=1.0))
    s.connect("w1.flange", "m.flange_a")
    s.connect("w2.flange", "m.flange_b")
    with pytest.raises(OverdeterminedError, match="redundant constraint"):
        flatten(s)


def test_inconsistent_constraints():
    s = System("contra")
    s.add("w1", Fixed(s0=0.0))
    s.add("w2", Fixed(s0=0.1))
    s.add("m", Mass(m=1.0))
    s.connect("w1.flange", "m.flange_a")
    s.connect("w2.flange", "m.flange_b")
    with pytest.raises(OverdeterminedError, match="inconsistent"):
        flatten(s)


class Dangling(Component):
    """A variable with no equation: under-determined."""

    flange = Flange()
    x = Variable()

    def equations(self):
        return [self.flange.f]


class TwoEquations(Component):
    """Two equations for one variable: over-determined."""

    flange = Flange()
    x = Variable()

    def equations(self):
        return [self.flange.f, self.x - 1.0, self.x - 2.0]


def _attach(comp):
    s = System("custom")
    s.add("wall", Fixed())
    s.add("k", Spring(c=1.0e3))
    s.add("m", Mass(m=1.0))
    s.add("c", comp)
    s.connect("wall.flange", "k.flange_a")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("c.flange", "m.flange_b")
    return s


def test_underdetermined_names_the_variable():
    with pytest.raises(UnderdeterminedError, match=r"c\.x"):
        flatten(_attach(Dangling()))


def test_overdetermined_names_the_component():
    with pytest.raises(OverdeterminedError, match=r"component 'c' \(TwoEquations\)"):
        flatten(_attach(TwoEquations()))


class RigidRodAsEquation(Component):
    """A rigid rod written as a residual with a Lagrange multiplier: index 3 if not declared a constraint."""

    flange_a = Flange()
    flange_b = Flange()
    lam = Variable("N")

    def equations(self):
        return [self.flange_a.f + self.lam, self.flange_b.f - self.lam, self.flange_b.s - self.flange_a.s]


def test_high_index_names_constraint_and_inertias():
    s = System("rod")
    s.add("m1", Mass(m=1.0))
    s.add("m2", Mass(m=2.0))
    s.add("rod", RigidRodAsEquation())
    s.add("F", Force())
    s.connect("m1.flange_b", "rod.flange_a")
    s.connect("rod.flange_b", "m2.flange_a")
    s.connect("F.flange", "m1.flange_a")
    with pytest.raises(HighIndexError, match=r"component 'rod'.*m1\.s.*m2\.s.*constraints\(\)"):
        flatten(s)


class NoFlow(Component):
    """Forgets to define its flow."""

    flange = Flange()
    c = Parameter(1.0, unit="N/m")


def test_undefined_flow_is_a_model_definition_error():
    with pytest.raises(ModelDefinitionError, match=r"'c' \(NoFlow\) does not define the flow of port 'flange'"):
        flatten(_attach(NoFlow()))


def test_free_mass_without_stiffness_is_fine_but_massless_free_node_is_singular():
    # a free mass with a force: rigid-body mode, regular DAE
    s = System("free")
    s.add("m", Mass(m=1.0))
    s.add("F", Force())
    s.connect("F.flange", "m.flange_a")
    assert flatten(s).nx == 2
    # a spring between two massless nodes loaded by forces: the pair floats (quasi-static and singular)
    s = System("floating")
    s.add("k", Spring(c=1.0))
    s.add("F1", Force())
    s.add("F2", Force())
    s.connect("F1.flange", "k.flange_a")
    s.connect("F2.flange", "k.flange_b")
    with pytest.raises(bscomp.SingularSystemError, match=r"singular.*k\.flange"):
        flatten(s)
