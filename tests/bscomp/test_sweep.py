"""bscomp.linear.sweeps: modes and FRFs against a swept (position) parameter, serial and on a process pool."""

import json
import math
import textwrap

import numpy as np
import pytest

from bscomp.errors import UnknownNameError
from bscomp.linear.response import frf
from bscomp.linear.sweeps import PositionSweep, build_system, position_sweep
from bscomp.systems import mass_spring_chain

M1, M2, K1 = 2.0, 3.0, 1.0e4

SYSTEM_FILE = textwrap.dedent('''
    from bscomp import System
    from bscomp.components import Fixed, Force, Mass, Spring


    def build():
        s = System("chain_file")
        s.add("wall", Fixed())
        s.add("k1", Spring(c=1.0e4))
        s.add("m1", Mass(m=2.0))
        s.add("k2", Spring(c=2.0e4))
        s.add("m2", Mass(m=3.0))
        s.add("F", Force())
        s.connect("wall.flange", "k1.flange_a")
        s.connect("k1.flange_b", "m1.flange_a")
        s.connect("m1.flange_b", "k2.flange_a")
        s.connect("k2.flange_b", "m2.flange_a")
        s.connect("F.flange", "m2.flange_b")
        s.position_parameter = "k2.c"    # the swept "position" of this test system
        return s
''')


def chain():
    return mass_spring_chain((M1, M2), (K1, 2.0e4))


def analytic(k2):
    a, b, c = M1 * M2, -(M1 * k2 + M2 * (K1 + k2)), K1 * k2
    disc = math.sqrt(b * b - 4 * a * c)
    return np.sort([math.sqrt(x) / (2 * math.pi) for x in ((-b - disc) / (2 * a), (-b + disc) / (2 * a))])


K2 = np.array([5.0e3, 2.0e4, 8.0e4, 3.2e5])


def test_frequencies_follow_analytic_formula():
    sw = position_sweep(chain, K2, "k2.c")
    assert isinstance(sw, PositionSweep) and sw.frequencies.shape == (4, 2)
    np.testing.assert_allclose(sw.frequencies, np.array([analytic(k) for k in K2]), rtol=1e-9)
    assert sw.parameter == "k2.c" and sw.inputs == ["F.f"]
    assert np.all(np.diff(sw.frequencies[:, 1]) > 0)                  # stiffer -> higher


def test_frfs_and_n_modes():
    f = np.logspace(0, 2.5, 30)
    sw = position_sweep(chain, K2[:2], "k2.c", freqs=f, outputs=["m2.s"], n_modes=1)
    assert sw.frequencies.shape == (2, 1) and sw.H.shape == (2, 30, 1, 1)
    ref = frf(build_system(chain, {"k2.c": K2[1]}), "F.f", "m2.s", f).H
    np.testing.assert_allclose(sw.H[1], ref, rtol=1e-12)


def test_process_pool_from_name_and_overrides(tmp_path):
    """(system file, overrides) travels to the workers; same numbers as the serial run."""
    path = tmp_path / "chain_file.py"
    path.write_text(SYSTEM_FILE)
    serial = position_sweep(str(path), K2, overrides={"m1.m": M1})
    parallel = position_sweep(str(path), K2, workers=2)
    assert serial.parameter == "k2.c"                                  # from system.position_parameter
    np.testing.assert_allclose(parallel.frequencies, serial.frequencies, rtol=1e-12)
    np.testing.assert_allclose(serial.frequencies, np.array([analytic(k) for k in K2]), rtol=1e-9)


def test_unpicklable_build_with_workers_and_missing_position_parameter():
    with pytest.raises(TypeError, match="picklable"):
        position_sweep(lambda: chain(), K2, "k2.c", workers=2)
    with pytest.raises(UnknownNameError, match="position_parameter"):
        position_sweep(chain, K2)


def test_outputs(tmp_path):
    sw = position_sweep(chain, K2, "k2.c", freqs=[1.0, 10.0, 100.0])
    sw.to_csv(tmp_path / "s.csv")
    rows = (tmp_path / "s.csv").read_text().splitlines()
    assert rows[0] == "k2.c,f1_hz,f2_hz,zeta1,zeta2" and len(rows) == 5
    d = json.loads(sw.to_json(tmp_path / "s.json"))
    assert d["positions"] == K2.tolist() and len(d["H_re"]) == 4
    sw.plot(tmp_path / "s.png")
    sw.plot(tmp_path / "h.png", kind="frf", output="m1.s")
    assert (tmp_path / "s.png").stat().st_size > 1000 and (tmp_path / "h.png").stat().st_size > 1000
