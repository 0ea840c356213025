"""simulate(method="modal") on drives not built for it, the worst cases of two differential fuzzes against IDAS
(benchmarks/fuzz_modal.py, fuzz_moving_nut.py): a 4-mass chain rattling in a smoothed clearance with Stribeck
friction, and the moving-nut test bed with a clearance and no friction (docs/nonlinear.md, "Accuracy on drives
we did not build" and "Limits")."""

import warnings

import numpy as np
import pytest

from bscomp import System
from bscomp.components import Backlash, Damper, Fixed, Force, Mass, Spring, StribeckFriction
from bscomp.kernel.flattening import flatten
from bscomp.simulation import simulate
from bscomp.systems import testbed

OUTS = ["m3.v", "k3.f"]


def rattling_chain():
    """wall - k0 - m0 - k1 - m1 - k2 - m2 - clearance - m3 <- F, Stribeck friction on m3, 2 % damping per link.

    The clearance (9.3 um, contact 7.3e8 N/m, parabolic corners 1.9 um wide) carries 1-160 N for long stretches
    inside its corner and 2 kN in the impacts; the friction 88-115 N."""
    s = System("rattling_chain")
    s.add("wall", Fixed())
    prev = "wall.flange"
    for i, (m, k) in enumerate(zip((42.8, 40.7, 13.4, 4.3), (6.1e7, 2.85e6, 1.0e4, 4.4e7), strict=True)):
        s.add(f"m{i}", Mass(m=m))
        s.add(f"k{i}", Backlash(b=9.3e-5, c=7.3e8, eps=1.9e-5) if i == 3 else Spring(c=k))
        s.add(f"d{i}", Damper(d=0.04 * np.sqrt(k * m)))
        for a, b in ((prev, f"k{i}.flange_a"), (f"k{i}.flange_b", f"m{i}.flange_a"), (prev, f"d{i}.flange_a"),
                     (f"d{i}.flange_b", f"m{i}.flange_a")):
            s.connect(a, b)
        prev = f"m{i}.flange_b"
    s.add("ground", Fixed())
    s.add("fr", StribeckFriction(F_s_pos=115.0, F_s_neg=115.0, F_c_pos=88.0, F_c_neg=88.0))
    s.connect("ground.flange", "fr.flange_a")
    s.connect("fr.flange_b", "m3.flange_a")
    s.add("F", Force())
    s.connect("F.flange", prev)
    return s


def _force(t):
    return 170.0 * np.sign(np.sin(2 * np.pi * 33.5 * t) + 1e-12)


def _nrmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.ptp(b))


@pytest.fixture(scope="module")
def rattling():
    dae = flatten(rattling_chain())
    t = np.linspace(0.0, 0.05, 501)
    ref = simulate(dae, t, inputs={"F.f": _force}, outputs=OUTS, rtol=1e-10, atol=1e-13, max_num_steps=10**7)
    return dae, t, ref


def _modal(dae, t, tol):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")       # the model's own warnings (a stiff contact) are not under test
        return simulate(dae, t, inputs={"F.f": _force}, outputs=OUTS, method="modal", modal_options={"tol": tol})


def test_small_forces_beside_large_impacts_need_a_tighter_tolerance(rattling):
    """The step's force error is judged against the run's largest force (the impacts' 2.2 kN): the long stretches
    of 1-160 N in the contact's corner each take up to 2.2 N of error of one sign, and at the default ``tol``
    m3's velocity drifts to NRMSE 4.3e-3 (IDAS at its default rtol 1e-6: 1.9e-4). ``tol`` 1e-4, the advice for
    such drives (docs/nonlinear.md): 5.3e-4 (k3.f 7.1e-4)."""
    dae, t, ref = rattling
    r = _modal(dae, t, 1e-4)
    for o in OUTS:
        assert _nrmse(r[o], ref[o]) < 1e-3, o


def test_the_error_falls_with_the_tolerance(rattling):
    """Convergence: a 10x tighter ``tol`` gives a >= 3x smaller error against IDAS at rtol 1e-10 (measured 8x:
    4.3e-3 -> 5.3e-4 on m3.v)."""
    dae, t, ref = rattling
    coarse, fine = (_modal(dae, t, tol) for tol in (1e-3, 1e-4))
    for o in OUTS:
        assert _nrmse(fine[o], ref[o]) < _nrmse(coarse[o], ref[o]) / 3, o


def _clearance_bed():
    """The moving-nut test bed (8 screw elements, nut at 0.486 m) with a 1.87 um nut-table clearance, no guideway
    friction: the table is free whenever the clearance is open (seed 0 of benchmarks/fuzz_moving_nut.py)."""
    return _fuzz_clearance_bed(8, 0.48592701410419925, 1.874024340935909e-06, 1142998595.469288, 0.0, 1.0, eps=1e-7)[0]


def test_a_free_table_in_a_clearance_converges_with_the_tolerance():
    """The open clearance leaves the table free (a Jordan block the linear part gets a small spring for, carried
    back by the correction). With that spring at 1e-6 of the contact's, the free mode came out nearly critically
    damped (eigenvector condition 2.1e9), each regime switch's projection moved the clearance's s by up to 2e-8 m,
    and the error did not fall with ``tol``: table.a 1.5e-2, 4.9e-2, 1.7e-2 at 1e-3, 1e-4, 1e-5 (IDAS rtol 1e-6:
    9.3e-5). At 1e-8:
    9.0e-5 and 7.4e-6 (1e-4: 3.3e-5)."""
    dae = _clearance_bed()
    t = np.arange(0.0, 0.05 + 1e-12, 1e-4)

    def u(tt):
        return 5.550181262834976 if (tt * 5.0726491034663415) % 1.0 < 0.5 else -5.550181262834976

    ref = simulate(dae, t, inputs={"amp.u": u}, outputs=["table.a"], rtol=1e-9, atol=1e-12, max_num_steps=10**7)
    err = {}
    for tol in (1e-3, 1e-5):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = simulate(dae, t, inputs={"amp.u": u}, outputs=["table.a"], method="modal", modal_options={"tol": tol})
        err[tol] = float(np.sqrt(np.mean((r["table.a"] - ref["table.a"]) ** 2) / np.mean(ref["table.a"] ** 2)))
    assert err[1e-3] < 1e-3
    assert err[1e-5] < err[1e-3] / 2


def _contact_on_a_wall():
    """1 kg on a soft spring (1e4 N/m) and a 1e10 N/m contact to a wall, 1 um clearance, pushed by 0.5 N."""
    s = System("contact_on_a_wall")
    s.add("wall", Fixed())
    s.add("m", Mass(m=1.0))
    s.add("k", Spring(c=1e4))
    s.add("gap", Backlash(b=1e-6, c=1e10, eps=0.0))
    s.add("push", Force())
    s.connect("k.flange_a", "wall.flange")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("gap.flange_a", "wall.flange")
    s.connect("gap.flange_b", "m.flange_a")
    s.connect("push.flange", "m.flange_b")
    return flatten(s)


def test_the_default_keeps_an_octave_above_a_stiff_contacts_own_mode():
    """In contact the mass's mode is sqrt((c + k)/m)/2pi = 15.92 kHz and carries ~all of the contact's compliance
    (share c/(c + k)): the default f_keep 30 kHz is raised to twice it, 31.83 kHz (``stats["f_keep_used"]``); a
    given f_keep is kept, with a ModelLimitationWarning naming the element and the band."""
    from bscomp.errors import ModelLimitationWarning

    dae = _contact_on_a_wall()
    t = np.linspace(0.0, 2e-3, 21)
    r = simulate(dae, t, inputs={"push.f": 0.5}, outputs=["m.a"], method="modal")
    f_e = np.sqrt((1e10 + 1e4) / 1.0) / (2 * np.pi)
    assert abs(r.stats["f_keep_used"] / (2 * f_e) - 1) < 1e-9, r.stats["f_keep_used"]
    with pytest.warns(ModelLimitationWarning, match=r"f_keep=30000 Hz makes modes of 'gap'.*1\.592e\+04 Hz"):
        r = simulate(dae, t, inputs={"push.f": 0.5}, outputs=["m.a"], method="modal", modal_options={"f_keep": 3e4})
    assert r.stats["f_keep_used"] == 3e4
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelLimitationWarning)       # keeping every mode: nothing to say
        simulate(dae, t, inputs={"push.f": 0.5}, outputs=["m.a"], method="modal", modal_options={"f_keep": None})


def _fuzz_clearance_bed(n_elements, nut_position, b, c, amp, freq, eps=0.0):
    """A bed of benchmarks/fuzz_moving_nut.py with a clearance and no friction, flattened, and its square wave."""
    s = testbed.testbed_axial_torsional(nut_joint="moving", n_elements=n_elements, nut_position=nut_position)
    s.insert("backlash", Backlash(b=b, c=c, eps=eps), between=("table_joint.flange", "table.flange_a"))

    def u(tt):
        return amp if (tt * freq) % 1.0 < 0.5 else -amp

    return flatten(s), u


def test_a_stiff_contacts_modes_are_kept_dynamic():
    """Seed 97 of benchmarks/fuzz_moving_nut.py: the moving-nut bed (14 elements, nut at 0.366 m) with a 3.2 um
    clearance of 3.1e10 N/m (its contact modes at 23.5 and 24.6 kHz, 17x Table 5.2's), no friction, a 5.5 V
    square wave at 18.7 Hz. With every mode above 30 kHz static, each impact rang modes the static part drops:
    table.a NRMSE 4.0e-3 against IDAS over 0.05 s at any ``tol`` (1e-3..1e-5). The default now keeps the modes
    to 49.1 kHz: over 0.02 s 2.7e-4 against IDAS rtol 1e-9, against 2.4e-3 with f_keep held at 30 kHz."""
    dae, u = _fuzz_clearance_bed(14, 0.3662941413512001, 3.2097779271554304e-06, 31374007295.583412, 5.484418906960989,
                                 18.74679008983348)
    t = np.arange(0.0, 0.02 + 1e-12, 1e-4)
    ref = simulate(dae, t, inputs={"amp.u": u}, outputs=["table.a"], rtol=1e-9, atol=1e-12, max_num_steps=10**7)
    err = {}
    for fk in (None, 3e4):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opts = {"window": 1} if fk is None else {"window": 1, "f_keep": fk}
            r = simulate(dae, t, inputs={"amp.u": u}, outputs=["table.a"], method="modal", modal_options=opts)
        err[fk] = float(np.sqrt(np.mean((r["table.a"] - ref["table.a"]) ** 2) / np.mean(ref["table.a"] ** 2)))
        if fk is None:
            assert 4.5e4 < r.stats["f_keep_used"] < 5.5e4, r.stats["f_keep_used"]
    assert err[None] < 6e-4 and err[3e4] > 4 * err[None], err


def test_a_bounce_between_the_check_points_is_seen(monkeypatch):
    """Seed 143 of benchmarks/fuzz_moving_nut.py: the moving-nut bed (11 elements, nut at 0.673 m) with a 19.5 um
    clearance of 1.15e10 N/m and no friction, a 2.0 V square wave at 43.4 Hz. At 49.1 ms the table bounces in the
    contact: separations of 17-25 us between contacts of ~50 us. A step whose check points (a quarter step apart,
    25 us on the 0.1 ms grid) all fall in contact passed with the contact kept closed through a separation, and the
    impacts after it went wrong: table.a NRMSE 4.1e-2 over 0.05 s at tol 1e-3 and 1e-4 (IDAS rtol 1e-6: 1.6e-3).
    The displacement's extremum between check points (cubic Hermite of s and v) is now checked too: 9.0e-5."""
    import bscomp.simulation.modal_kernels as mk

    dae, u = _fuzz_clearance_bed(11, 0.6732667738405385, 1.9485467261522464e-05, 11462632456.757195, 2.025349329193674,
                                 43.39005481755329)
    t = np.arange(0.0, 0.05 + 1e-12, 1e-4)
    ref = simulate(dae, t, inputs={"amp.u": u}, outputs=["table.a"], rtol=1e-8, atol=1e-11, max_num_steps=10**7)

    def err():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = simulate(dae, t, inputs={"amp.u": u}, outputs=["table.a"], method="modal", modal_options={"window": 0})
        return float(np.sqrt(np.mean((r["table.a"] - ref["table.a"]) ** 2) / np.mean(ref["table.a"] ** 2)))

    checked = err()
    init = mk.Kernel.__init__
    monkeypatch.setattr(mk.Kernel, "__init__", lambda self, *a, **k: init(self, *a, **{**k, "extrema": ()}))
    dae._cache.clear()
    unchecked = err()
    assert checked < 5e-4 and unchecked > 1e-2, (checked, unchecked)
