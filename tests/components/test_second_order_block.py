"""SecondOrderBlock: a matrix model back in a system; CMS-reduced drive reproduces the full FRF below cut-off."""

import numpy as np

from bscomp import System, second_order
from bscomp.components import Force, Mass, SecondOrderBlock, Spring
from bscomp.linear.reduction import reduce_second_order
from bscomp.simulation.dispatch import simulate


def chain(n=30, m=0.5, k=2.0e8):
    s = System("chain")
    s.add("F", Force())
    prev = None
    for i in range(n):
        s.add(f"m{i}", Mass(m=m))
        if prev:
            s.add(f"k{i}", Spring(c=k))
            s.connect(prev, f"k{i}.flange_a")
            s.connect(f"k{i}.flange_b", f"m{i}.flange_a")
        prev = f"m{i}.flange_b"
    s.connect("F.flange", "m0.flange_a")
    return s


def test_block_reproduces_the_model_it_wraps():
    so = second_order(chain(), inputs=["F.f"], outputs=["m29.s", "m0.a"])
    s = System("wrapped")
    s.add("plant", SecondOrderBlock(so))
    s.add("F", Force())  # unused: the block's input is the system input
    s.remove("F")
    so2 = second_order(s, inputs=["plant.F_f"], outputs=["plant.m29_s", "plant.m0_a"])
    f = np.array([1.0, 50.0, 300.0])
    np.testing.assert_allclose(so2.frf(f), so.frf(f), rtol=1e-9)


def test_reduced_block_matches_full_below_cutoff_and_simulates():
    so = second_order(chain(), inputs=["F.f"], outputs=["m29.s", "m0.s"])
    red, info = reduce_second_order(so, boundary=["m0.s"], f_cut=1500.0)
    assert red.M.shape[0] < 12
    f = np.linspace(1.0, 1200.0, 80)  # first elastic mode ~333 Hz, cut-off 1500 Hz
    H, Hr = so.frf(f), red.frf(f)
    # mode-displacement outputs: error small relative to the response level of each output
    assert np.max(np.abs(Hr - H) / np.max(np.abs(H), axis=0)) < 0.02
    s = System("reduced")
    s.add("plant", SecondOrderBlock(red, expose={"drive": ("m0.s", "Flange")}))
    t = np.linspace(0, 0.02, 201)
    r = simulate(s, t, inputs={"plant.F_f": 1.0}, outputs=["plant.m29_s", "plant.drive.s"])
    # free chain pushed by a constant force: rigid-body acceleration F / (n m)
    acc = 2 * r["plant.m29_s"][-1] / t[-1] ** 2
    assert abs(acc - 1.0 / 15.0) / (1.0 / 15.0) < 0.05
