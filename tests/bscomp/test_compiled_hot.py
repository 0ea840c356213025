"""The time series' sample compiled to C once hot (bscomp.simulation.compiled_hot): the same numbers to the bit as
CasADi's virtual machine, loaded from the on-disk cache by a later model, and the virtual machine kept where nothing
can be compiled."""

import shutil

import numpy as np
import pytest

from bscomp.components.backlash import Backlash
from bscomp.components.coulomb_friction import CoulombFriction
from bscomp.errors import BscompError
from bscomp.simulation import compiled_hot
from bscomp.simulation.compiled import CompiledModel
from bscomp.systems import get

OUTS = ["rotor.phi", "rotor.w", "table.s", "table.a"]
needs_cc = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc")), reason="needs a C compiler")


def _drive():
    """The validation drive with guideway friction and a screw-nut clearance (two elements, a 4-sub-step sample)."""
    s = get("validation_drive")
    s.add("friction", CoulombFriction(F_c=1500.0, v_reg=5e-4))
    s.connect("friction.flange_a", "ground.flange")
    s.connect("friction.flange_b", "table.flange_b")
    c, d = s.get("axial.c"), s.get("axial_loss.d")
    s.remove("axial")
    s.remove("axial_loss")
    s.add("axial", Backlash(b=2e-5, c=c, d=d, s_rel0=-1e-5, eps=4e-6))
    s.connect("lead.flange_b", "axial.flange_a")
    s.connect("axial.flange_b", "nut.flange_a")
    return s


def _run(cm, F_c=1500.0):
    t = np.arange(0, 0.4, 2e-4)                 # 1,999 steps: every block length (256, 64, 16, 4, 1) is used
    u = 2.125 * np.sign(np.sin(2 * np.pi * 5 * t) + 1e-12)
    y = cm.simulate({"friction.F_c_pos": F_c, "friction.F_c_neg": F_c}, t, {"amp.u": u})
    return y, cm.stats["native_steps"]


@needs_cc
def test_a_hot_sample_runs_compiled_with_the_numbers_of_the_virtual_machine(tmp_path, monkeypatch):
    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 1.0)          # hot after one run
    s = _drive()
    monkeypatch.setenv("BSCOMP_NATIVE_STEPS", "0")
    vm = CompiledModel(s, ["amp.u"], OUTS)
    ref = [_run(vm, F) for F in (1500.0, 1200.0, 1500.0)]
    assert [n for _, n in ref] == [False] * 3                   # switched off: always the virtual machine
    monkeypatch.delenv("BSCOMP_NATIVE_STEPS")
    cm = CompiledModel(s, ["amp.u"], OUTS)
    got = [_run(cm, F) for F in (1500.0, 1200.0, 1500.0)]
    assert [n for _, n in got] == [False, True, True]           # counted once, then compiled
    for (y0, _), (y1, _) in zip(ref, got, strict=True):
        for o in OUTS:
            assert np.array_equal(y0[o], y1[o]), o             # to the bit
    assert np.max(np.abs(ref[1][0]["table.a"] - ref[0][0]["table.a"])) > 0.01   # the parameter did change the run
    later = CompiledModel(s, ["amp.u"], OUTS)   # another model (a later process): from disk
    y, native = _run(later, 1200.0)
    assert native and all(np.array_equal(y[o], ref[1][0][o]) for o in OUTS)
    assert list(tmp_path.glob("jit/sample_x256_k*.so"))


def test_where_nothing_compiles_the_virtual_machine_goes_on(tmp_path, monkeypatch):
    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 0.0)

    def no_compiler(*args, **kwargs):
        raise BscompError("jit=True needs a C compiler (cc or gcc on PATH, or $CC)")

    monkeypatch.setattr(compiled_hot, "native_functions", no_compiler)
    s = _drive()
    cm = CompiledModel(s, ["amp.u"], OUTS)
    (y1, n1), (y2, n2) = _run(cm), _run(cm)
    assert not n1 and not n2
    assert all(np.array_equal(y1[o], y2[o]) for o in OUTS) and np.all(np.isfinite(y1["table.a"]))
    assert not list(tmp_path.glob("jit/sample_*"))


def test_the_skipping_newton_is_the_full_newton_to_the_bit():
    """compiled_hot.skipping_newton (the compiled sample's Newton: an iteration skipped once one returned its start)
    against CompiledModel._newton (every iteration), at 300 random element coordinates through and around the
    clearance and the friction's regularised band, started as in a run from the forces of a sub-step before (the
    coordinates 1e-8 m and 1e-4 m/s away) and from far off: equal to the bit, and from the sub-step before most
    reach the fixed point before the eighth iteration (so the skip saves work)."""
    cm = CompiledModel(_drive(), ["amp.u"], OUTS)
    full = cm._newton(8)
    step, residual = cm._newton_parts()
    skip = compiled_hot.skipping_newton(step, residual, 8)
    pl = cm.law_values(cm._split({})[1])
    rng = np.random.default_rng(7)
    Gs, Gv = np.array([[-2e-9, 1e-10], [1e-10, -3e-9]]), np.array([[-1e-6, 0.0], [0.0, -2e-6]])
    first_fixed = []
    for _ in range(300):
        a_s, a_v = rng.uniform(-4e-5, 4e-5, 2), rng.uniform(-2e-3, 2e-3, 2)
        far = rng.uniform(-2e3, 2e3, 2)
        w0 = np.asarray(full(a_s - 1e-8, a_v - 1e-4, Gs, Gv, far, pl)[0]).ravel()     # the sub-step before's
        for start in (w0, far):
            ref, got = full(a_s, a_v, Gs, Gv, start, pl), skip(a_s, a_v, Gs, Gv, start, pl)
            assert np.array_equal(np.asarray(ref[0]), np.asarray(got[0])) and float(ref[1]) == float(got[1])
        w, k = w0, 0
        while k < 8:
            wn = np.asarray(step(a_s, a_v, Gs, Gv, w, pl)[0]).ravel()
            k += 1
            if np.array_equal(wn, w):
                break
            w = wn
        first_fixed.append(k)
    assert np.median(first_fixed) < 8, np.bincount(first_fixed)


def test_a_cache_folder_that_cannot_be_written_leaves_the_virtual_machine(tmp_path, monkeypatch):
    """BSCOMP_CACHE_DIR naming a file (a read-only or mistyped folder): the run is not refused, it stays in the
    virtual machine with the same numbers."""
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    monkeypatch.setenv("BSCOMP_CACHE_DIR", str(blocker))
    monkeypatch.setattr(compiled_hot, "HOT_WORK", 0.0)
    cm = CompiledModel(_drive(), ["amp.u"], OUTS)
    (y1, n1), (y2, n2) = _run(cm), _run(cm)
    assert not n1 and not n2 and all(np.array_equal(y1[o], y2[o]) for o in OUTS)
