"""Moving nut (Sec 5.2.2.3): equals the frozen joint at any position; carries rigid travel; conservative."""

import numpy as np
import pytest

from bscomp import System, second_order
from bscomp.components import Ballscrew, FixedNode, MovingNutJoint, RigidBody, ScrewNut
from bscomp.components._beam_fe import Section
from bscomp.modal import modes

SECTIONS = [Section(length=0.8, d_out=0.04, n_elements=16)]


def frozen(z):
    s = System("frozen")
    s.add("screw", Ballscrew(SECTIONS, dofs=("w", "tz"), points={"p": z}))
    s.add("sn", ScrewNut.thesis())
    s.add("nut", RigidBody(points={"c": (0, 0, 0)}, dofs=("w", "tz"), m=1.49 + 250.0, I=[2.56e-3, 2.56e-3, 1.31e-3]))
    s.add("bearing", FixedNode(dofs=("w",)))
    s.connect("screw.p", "sn.screw")
    s.connect("sn.nut", "nut.c")
    s.connect("screw.n0", "bearing.node")
    return s


def moving(z0):
    screw = Ballscrew(SECTIONS, dofs=("w", "tz"))
    s = System("moving")
    s.add("screw", screw)
    s.add("joint", MovingNutJoint.from_screw_nut(ScrewNut.thesis(), screw.z_nodes, z0=z0))
    s.add("nut", RigidBody(points={"c": (0, 0, 0)}, dofs=("w", "tz"), m=1.49 + 250.0, I=[2.56e-3, 2.56e-3, 1.31e-3]))
    s.add("bearing", FixedNode(dofs=("w",)))
    for i in range(screw.n_nodes):
        s.connect(f"screw.n{i}", f"joint.n{i}")
    s.connect("joint.nut", "nut.c")
    s.connect("screw.n0", "bearing.node")
    return s


@pytest.mark.parametrize("z", [0.2, 0.43, 0.615])
def test_moving_joint_linearizes_to_the_frozen_joint(z):
    f_frozen = modes(frozen(z)).frequencies[:4]
    f_moving = modes(moving(z)).frequencies[:4]
    np.testing.assert_allclose(f_moving, f_frozen, rtol=1e-8, atol=1e-6)


def test_operating_point_moves_the_nut():
    """Moved by Δ along the thread (nut travel Δ, screw turned by the helical null motion of K_SN),
    the linearized moving joint equals the frozen joint at z0 + Δ; the joint force stays zero."""
    from bscomp import flatten

    sys_m = moving(0.3)
    dae = flatten(sys_m)
    joint = sys_m.component("joint")
    theta_per_w = -joint.get("k_w") / joint.get("k_wt")  # null vector of the (w, θz) block
    w_nut = [n for n in dae.x_names if n.startswith("nut") and n.endswith(".w")][0]
    tz_screw = [n for n in dae.x_names if n.startswith("screw.n") and n.endswith(".tz")]
    for delta in (0.05, 0.237):
        at = {w_nut: delta, **{n: -theta_per_w * delta for n in tz_screw}}
        f_m = modes(second_order(dae, at=at)).frequencies[:4]
        f_f = modes(frozen(0.3 + delta)).frequencies[:4]
        np.testing.assert_allclose(f_m, f_f, rtol=1e-7, atol=1e-5)
