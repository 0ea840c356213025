"""Test bed with the moving 6-DOF screw-nut joint (nut_joint="moving"): one flattening, the nut position
as the parameter ``sn.z0``; every linearization equals the point-port model built at that position,
including the drive modal damping re-derived from the modes there (Tables 4.1/4.2 ratios)."""

import numpy as np
import pytest

from bscomp import flatten, second_order
from bscomp.linear.response import frf
from bscomp.linear.sweeps import position_sweep
from bscomp.systems.testbed import nut_positions
from bscomp.systems.testbed import testbed as build

IN, OUT = ["amp.u", "Fd.f"], ["rotor.w", "table.s"]   # amplifier-voltage input (the default build)


@pytest.fixture(scope="module")
def moving():
    s = build("full", nut_joint="moving")
    return s, flatten(s)


def test_position_parameter_is_the_joint_z0(moving):
    assert moving[0].position_parameter == "sn.z0"


@pytest.mark.parametrize("name", ["L", "R"])
def test_linearization_equals_point_model(moving, name):
    x = nut_positions()[name]
    so_m = second_order(moving[1], inputs=IN, outputs=OUT, params={"sn.z0": x})
    so_p = second_order(build("full", nut_position=x), inputs=IN, outputs=OUT)
    for A in ("M", "K", "C", "B", "Cq", "Cv"):
        a, b = getattr(so_m, A).toarray(), getattr(so_p, A).toarray()
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max(), A


def test_tangent_sweep_matches_point_model_frf(moving):
    """Fig 4.2 FRFs at L from the one-flattening sweep = FRF of the point model rebuilt at L."""
    x = nut_positions()["L"]
    f = np.linspace(1.0, 300.0, 200)
    res = position_sweep(lambda: moving[0], [x, 0.5], freqs=f, inputs=IN, outputs=OUT, method="tangent")
    ref = frf(second_order(build("full", nut_position=x), inputs=IN, outputs=OUT), freqs=f).H
    assert np.abs(res.H[0] - ref).max() <= 1e-6 * np.abs(ref).max()
