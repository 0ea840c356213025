"""Housing: a mass on an axial fastener spring, one free coordinate (the node's w)."""

import math

import numpy as np

from bscomp import System, flatten
from bscomp.components import Bearing, FixedNode, Housing, Mass, NodeToFlange
from bscomp.linear.modal import modes


def test_housing_is_a_mass_on_a_spring_along_the_axis():
    s = System("housing")
    s.add("h", Housing(m=2.0, c=8.0e6, d=0.0))
    s.add("adapter", NodeToFlange())
    s.add("load", Mass(m=3.0))
    s.connect("h.node", "adapter.node")
    s.connect("adapter.flange", "load.flange_a")
    dae = flatten(s)
    assert dae.nx == 2                           # only w moves
    f = modes(dae).frequencies
    assert np.allclose(f, [math.sqrt(8.0e6 / 5.0) / (2 * math.pi)], rtol=1e-9)


def test_housing_behind_a_bearing_is_a_spring_in_series():
    s = System("support")
    s.add("b", Bearing(k_axial=3.0e8, k_radial=1.0e8, grounded=False))
    s.add("h", Housing(m=1.0, c=1.0e8, d=0.0))
    s.add("shaft", NodeToFlange())
    s.add("body", Mass(m=50.0))
    s.add("pin", FixedNode(dofs=("u", "v", "tx", "ty", "tz")))   # the shaft moves along the axis only
    s.connect("b.node_a", "shaft.node")
    s.connect("b.node_a", "pin.node")
    s.connect("shaft.flange", "body.flange_a")
    s.connect("b.node_b", "h.node")
    f = np.sort(modes(flatten(s)).frequencies)
    # two masses on springs: body -(3e8)- housing -(1e8)- ground
    K = np.array([[3e8, -3e8], [-3e8, 4e8]])
    M = np.diag([50.0, 1.0])
    w = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    assert np.allclose(f, w / (2 * math.pi), rtol=1e-6)
