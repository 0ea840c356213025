"""bscomp.kernel.signal_meta.unit_of: the unit of any named signal of a drive, as shown in messages."""

import pytest

from bscomp.kernel.signal_meta import derivative_unit, unit_of


@pytest.mark.parametrize("name, unit", [
    ("table.s", "m"), ("table.v", "m/s"), ("table.a", "m/s^2"),      # observables (Modelica convention)
    ("rotor.phi", "rad"), ("der(rotor.phi)", "rad/s"),               # a state and its derivative
    ("amp.u", "V"),                                                  # an input
    ("screw.E", "Pa"), ("screw.rho", "kg/m^3"),                      # parameters, declared 'kg/m3'
    ("no.such.signal", ""), ("T", ""),
])
def test_unit_of_the_thesis_drive_signals(testbed_at_dae, name, unit):
    assert unit_of(testbed_at_dae, name) == unit


@pytest.mark.parametrize("unit, rate", [("m", "m/s"), ("m/s", "m/s2"), ("rad", "rad/s"), ("N.m", "N.m/s"),
                                        ("", ""), ("furlong", "")])
def test_derivative_unit(unit, rate):
    assert derivative_unit(unit) == rate
