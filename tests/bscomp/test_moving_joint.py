"""simulate(method="modal"): friction, backlash and the moving screw-nut joint as low-rank corrections of an exact
modal linear part (bscomp/simulation/modal*.py, moving_joints.py). Checked against the model's own residual (the
decomposition is exact), the joint's closed-form port forces, IDAS at rtol 1e-9 on the same equations, the exact
ZOH of a linear model and a sampled controller closing the loop. The creeping-nut limit is
tests/components/test_moving_nut.py."""

import numpy as np
import pytest

from bscomp import System, flatten
from bscomp.components import Backlash, CoulombFriction, Damper, Fixed, Force, Mass
from bscomp.simulation import SampledController, simulate
from bscomp.simulation.modal_channels import Channels, LinearPart, ModalSimulationError
from bscomp.simulation.modal_driver import ModalSimulator
from bscomp.systems import free_chain, testbed

AMP = 2.125                     # Sec 5.3.1: 4.25 V peak-to-peak square wave
F_C, B_GAP = 2066.0, 0.001885 * 0.010 / (2 * np.pi)   # Table 5.2: Coulomb force, backlash L r_g = 3.0 um


def square(t):
    return AMP if (t * 5.0) % 1.0 < 0.5 else -AMP


def drive(nut_joint="moving", n_elements=12, friction=True, backlash=True, **kw):
    """The Ch 5 test bed (coarse screw mesh) with Table 5.2 friction and backlash (examples/nonlinear_scenarios.py).

    With 12 elements (15 with one per short section; section C in 78 mm elements) a node sits at 432.5 mm:
    the nut starts 0.1 mm above it and crosses it once the table moves forward (the nut runs towards -z)."""
    kw.setdefault("nut_position", 0.4326)
    s = testbed.testbed_axial_torsional(nut_joint=nut_joint, n_elements=n_elements, **kw)
    if friction:
        s.add("guide_ground", Fixed())
        s.add("friction", CoulombFriction(F_c=F_C, v_reg=1e-4))
        s.connect("friction.flange_a", "guide_ground.flange")
        s.connect("friction.flange_b", "table.flange_b")
    if backlash:
        s.insert("backlash", Backlash(b=B_GAP, c=1.7e10), between=("table_joint.flange", "table.flange_a"))
    return s


@pytest.fixture(scope="module")
def moving():
    return flatten(drive())


def _nrmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - b) ** 2)) / np.sqrt(np.mean(np.asarray(b) ** 2)))


def test_decomposition_into_linear_part_and_channels_is_exact(moving):
    """F(v) = F_L(v) + sum G g(v) at random states, in two regimes and a shifted joint reference (the method's
    equations are the model's equations; the joint's correction on its active potentials is the closed form)."""
    dae, rng = moving, np.random.default_rng(3)
    ch = Channels(dae, dae.p0)
    assert [e.path for e in ch.elements] == ["friction", "backlash"] and [j.path for j in ch.joints] == ["sn"]
    cands = [ch.candidate_regimes(i) for i in range(2)]
    jt = ch.joints[0]
    for regime, z_ref in (((0, 0), jt.z0), ((1, 1), jt.z0 - 0.004)):
        lin = LinearPart(ch, [cands[i][r] for i, r in enumerate(regime)], (z_ref,))
        A, B, E, c, *_ = lin.explicit()
        dx = rng.normal(size=dae.nx) * 1e-6
        dx[dae.x_names.index("sn.nut.w")] = -2.5e-3             # the nut 2.5 mm from its start: another element
        u = rng.normal(size=dae.nu)
        y0, _, Jx, _, _ = ch.el_rows
        g = np.zeros(lin.ng)
        for i, el in enumerate(ch.elements):
            s, v = y0[2 * i] + Jx[2 * i] @ dx, y0[2 * i + 1] + Jx[2 * i + 1] @ dx
            k, d = lin.regime[i]
            g[i] = float(el.law(s, v, el.pvec)) - k * s - d * v
        d = jt.P @ (ch.Sq_x @ dx)
        off, n = lin.joint_cols[0]
        g[off:off + n] = jt.force(d) - jt.tangent(z_ref)[0] @ d
        assert jt.element_of(jt.position(d[jt.slow])) != jt.element_of(z_ref) or z_ref != jt.z0
        xd = A @ dx + B @ u + E @ g + c
        F = np.asarray(dae.F(xd, ch.x_a + dx, np.zeros(0), u, dae.p0)).ravel()
        scale = np.abs(lin.Jx @ dx).max()
        assert np.abs(F).max() < 1e-9 * scale, (regime, np.abs(F).max(), scale)


def test_compiled_law_equals_the_joint_force(moving):
    """The CasADi correction on a channel set S equals f(d) - K_r d of MovingJoint (Eq 3.35 through N(z))."""
    sim = ModalSimulator(moving, moving.p0)
    jt = sim.ch.joints[0]
    rng = np.random.default_rng(5)
    for dz in (-1e-3, 2.5e-3):
        z = jt.z0 + dz
        z_ref = jt.z0 - 0.01
        cset = sim.channel_set([z], [z_ref])
        S = cset[0][0]
        spec = sim.law(cset)
        mp_regime = (0, 1)
        theta = spec.pack(mp_regime, sim.slopes(mp_regime), [z_ref], cset)
        d = np.zeros(jt.n)
        d[S] = rng.normal(size=S.size) * 1e-6
        d[jt.slow] = dz
        y = np.concatenate([[0.0, 0.0, 0.0, 0.0], d[S]])
        g = np.asarray(spec.f(y, theta)[0]).ravel()[2:]
        ref = jt.force(d) - jt.tangent(z_ref)[0] @ d
        np.testing.assert_allclose(g, ref[S], rtol=1e-9, atol=1e-9 * np.abs(ref).max())
        assert np.abs(np.delete(ref, S)).max() <= 1e-12 * np.abs(ref).max()   # nothing outside S


def test_kernel_skips_the_steps_after_the_first_unacceptable_one(moving):
    """A compiled chunk stops computing after the first step the driver would not accept (tolerance 0: the first
    step) and reports the rest as skipped; the step it computed is the one of an unstopped chunk."""
    from bscomp.simulation.modal_driver import _State
    from bscomp.simulation.modal_kernels import SKIPPED

    sim = ModalSimulator(moving, moving.p0)
    u = np.zeros(moving.nu)
    u[moving.u_names.index("amp.u")] = AMP
    st = _State(sim, moving.x_start, u)
    stp = sim.stepper(st.mp, st.cset)
    _, mats = stp.data(1e-4)
    run = stp.kernel.runner(16, -3)
    x0 = stp.pack_state(st.xi, st.g[stp.gsel])
    X_all, I_all = (a.copy() for a in run(x0, u, mats, stp.theta, np.array([1e300, 1.0, 1e300, 16])))
    aux_all = run.aux.copy()
    X0, I0 = (a.copy() for a in run(x0, u, mats, stp.theta, np.array([0.0, 1.0, 0.0, 16])))
    assert np.all(I0[1:, 0] == SKIPPED) and np.all(X0[1:] == X0[0])       # nothing computed after step 0
    assert run.aux[2] == 1 and run.aux[3] == 1.0                          # one step; the scale before it
    np.testing.assert_array_equal(X0[0], X_all[0])
    computed = np.flatnonzero(I_all[:, 0] < SKIPPED)
    assert computed[0] == 0 and np.array_equal(computed, np.arange(computed.size))
    assert aux_all[2] == computed.size and aux_all[0] == max(1.0, I_all[computed, 1].max())
    if computed.size < 16:                               # an unstopped chunk only stops at a regime change
        assert I_all[computed[-1], 2] < 0.5
    # the steps wanted: a chunk of 16 asked for 5 computes 5, the same ones
    X5, I5 = (a.copy() for a in run(x0, u, mats, stp.theta, np.array([1e300, 1.0, 1e300, 5])))
    n5 = min(5, computed.size)
    assert run.aux[2] == n5 and np.all(I5[n5:, 0] == SKIPPED)
    np.testing.assert_array_equal(X5[:n5], X_all[:n5])


def test_moving_nut_with_friction_and_backlash_matches_idas_at_rtol_1e9(moving):
    """0.03 s from rest: the nut crosses its gap, hits the table (backlash), the table breaks away against
    Table 5.2 friction and the nut leaves its start node. Table acceleration, velocity, motor angle and the
    nut-table (backlash) force against IDAS at rtol 1e-9, atol 1e-12 on the same equations."""
    t = np.arange(0.0, 0.03 + 1e-12, 1e-4)
    outs = ["table.a", "table.v", "rotor.phi", "backlash.f", "sn.z"]
    r = simulate(moving, t, inputs={"amp.u": square}, outputs=outs, method="modal")
    ref = simulate(moving, t, inputs={"amp.u": square}, outputs=outs, rtol=1e-9, atol=1e-12, max_num_steps=10**7)
    assert ref["sn.z"][-1] < 0.4325 - 1e-4                      # the contact point moved into the next element
    assert np.abs(ref["backlash.f"]).max() > 1e3 and np.abs(ref["table.v"]).max() > 1e-2
    errs = {o: _nrmse(r[o], ref[o]) for o in outs}
    assert errs["table.a"] < 1e-3 and errs["backlash.f"] < 1e-3, errs
    assert errs["table.v"] < 1e-4 and errs["rotor.phi"] < 1e-5 and errs["sn.z"] < 1e-8, errs
    assert r.stats["switches"] >= 2                              # gap -> contact, stick -> slide


def test_linear_model_equals_exact_zoh():
    """Without friction, backlash or a moving nut the method is the exact zero-order hold (method='lti')."""
    dae = flatten(drive("point", friction=False, backlash=False))
    t = np.arange(0.0, 0.02 + 1e-12, 1e-4)
    outs = ["table.a", "table.s", "rotor.w"]
    r = simulate(dae, t, inputs={"amp.u": square}, outputs=outs, method="modal", modal_options={"f_keep": None})
    ref = simulate(dae, t, inputs={"amp.u": square}, outputs=outs, method="lti")
    for o in outs:
        assert _nrmse(r[o], ref[o]) < 1e-8, o
    np.testing.assert_allclose(r.x, ref.x, atol=1e-9 * np.abs(ref.x).max())     # states rebuilt on request


@pytest.mark.slow
def test_sampled_position_controller_closes_the_loop(moving):
    """A 5 kHz proportional position loop on the moving-nut drive with friction and backlash: the same
    closed loop as IDAS (the controller is sampled and held identically; IDAS restarts at every sample, ~20 s)."""
    def law(t, y):
        return [min(max(4000.0 * (1e-3 - y[0]), -5.0), 5.0)]

    ctrl = SampledController(law=law, measure=["table.s"], actuate=["amp.u"], Ts=2e-4)
    t = np.arange(0.0, 0.012 + 1e-12, 1e-4)
    r = simulate(moving, t, outputs=["table.s", "table.v"], controllers=[ctrl], method="modal")
    ref = simulate(moving, t, outputs=["table.s", "table.v"], controllers=[ctrl], rtol=1e-8, atol=1e-12,
                   max_num_steps=10**7)
    assert ref["table.s"][-1] > 5e-5 and np.ptp(ref["amp.u"]) > 1.0
    assert _nrmse(r["table.s"], ref["table.s"]) < 1e-4
    assert _nrmse(r["table.v"], ref["table.v"]) < 1e-3


def test_bad_input_raises_named_errors(moving):
    t = np.arange(0.0, 1e-3, 1e-4)
    with pytest.raises(ValueError, match="options"):
        simulate(moving, t, method="modal", modal_options={"tolerance": 1e-3})
    # the drive without viscous damping (a free rigid-body motion) was refused ("not diagonalisable"); it runs
    # now, through a virtual rigid-body damper, and equals the exact ZOH
    dae = flatten(drive("point", friction=False, backlash=False, viscous="none"))
    r = simulate(dae, t, inputs={"amp.u": AMP}, outputs=["rotor.phi", "table.s"], method="modal")
    ref = simulate(dae, t, inputs={"amp.u": AMP}, outputs=["rotor.phi", "table.s"], method="lti")
    assert r.stats["rigid_body_dampers"]
    for o in ("rotor.phi", "table.s"):
        assert np.abs(r[o] - ref[o]).max() < 1e-6 * np.abs(ref[o]).max(), o
    # a nonlinearity the method does not correct (the amplifier's current limit, active at 2.125 V) is refused,
    # not linearized silently
    with pytest.raises(ModalSimulationError, match="amp"):
        simulate(moving, t, inputs={"amp.u": AMP}, params={"amp.i_max": 1.0}, method="modal")
    simulate(moving, t, inputs={"amp.u": AMP}, params={"amp.i_max": 100.0}, method="modal")   # inactive: fine


def test_a_mass_sliding_free_in_an_open_clearance():
    """A pushed mass hits a second one through a clearance; the second slides on under Coulomb friction with the
    clearance open: in that regime (friction sliding, no contact) it is a free mass, a Jordan block of the
    linear part. The driver gives the friction a tiny viscous slope there (the correction carries it back), so
    the run equals IDAS rtol 1e-10 on the same equations."""
    s = System("free_in_gap")
    s.add("wall", Fixed())
    s.add("m1", Mass(m=1.0))
    s.add("m2", Mass(m=1.0))
    s.add("push", Force())
    s.connect("push.flange", "m1.flange_a")
    s.add("d1", Damper(d=20.0))
    s.connect("d1.flange_a", "wall.flange")
    s.connect("d1.flange_b", "m1.flange_a")
    s.add("gap", Backlash(b=1e-3, c=1e7, d=50.0))
    s.connect("gap.flange_a", "m1.flange_b")
    s.connect("gap.flange_b", "m2.flange_a")
    s.add("fr", CoulombFriction(F_c=5.0, v_reg=1e-4))
    s.connect("fr.flange_a", "wall.flange")
    s.connect("fr.flange_b", "m2.flange_b")
    dae = flatten(s)
    t = 1e-4 * np.arange(1001)

    def push(tt):
        return 100.0 if tt < 0.01 else 0.0

    outs = ["m1.s", "m2.s", "m2.v"]
    r = simulate(dae, t, inputs={"push.f": push}, outputs=outs, method="modal")
    ref = simulate(dae, t, inputs={"push.f": push}, outputs=outs, rtol=1e-10, atol=1e-13, max_num_steps=10**7)
    assert ref["m2.v"][-1] > 0.03 and abs(ref["m1.s"][-1] - ref["m2.s"][-1]) < 0.5e-3   # sliding, clearance open
    for o in outs:
        assert _nrmse(r[o], ref[o]) < 1e-3, o


def test_a_new_parameter_value_reuses_the_compiled_laws(moving):
    """The laws' expression holds no parameter value (friction force, contact stiffness and the regime distance's
    scales are packed numbers), so the compiled kernels of another parameter vector are the same library on disk:
    a friction sweep with jit=True compiled anew per value (~3 s each) before."""
    p = moving.p0.copy()
    for name, factor in (("friction.F_c_pos", 1.3), ("friction.F_c_neg", 1.3), ("backlash.c", 0.5)):
        p[moving.p_names.index(name)] *= factor
    sims = [ModalSimulator(moving, moving.p0), ModalSimulator(moving, p)]
    z = [sims[0].ch.joints[0].z0]
    specs = [s.law(s.channel_set(z, z)) for s in sims]
    for a, b in zip(specs[0].functions(), specs[1].functions(), strict=True):
        assert a.serialize() == b.serialize()
    thetas = [spec.pack((0, 1), s.slopes((0, 1)), z, s.channel_set(z, z)) for s, spec in zip(sims, specs, strict=True)]
    assert thetas[0].size == thetas[1].size and not np.allclose(thetas[0], thetas[1])


def _free_chain(backlash=False):
    """:func:`bscomp.systems.free_chain` (3 masses, 2 springs, nothing to ground: a free, undamped rigid-body
    motion -- a Jordan block of the linear part), its second spring a 0.2 mm clearance when ``backlash``."""
    s = free_chain()
    if backlash:
        s.replace("k1", Backlash(b=2e-4, c=3.0e4))
    return flatten(s)


def test_an_undamped_rigid_body_mode_runs_exactly():
    """A free chain pushed by a constant force (no damping, nothing to ground): method='modal' refused it (a
    Jordan block) before; now a virtual damper on the rigid-body mode goes into the linear part and its exact
    negative into a correction channel. Checked against the momentum balance -- the centre of mass moves as
    F t^2 / (2 sum m), whatever the vibration -- and the exact ZOH; and the registered sub-model 1 (a free rotor
    and screw) against IDAS at rtol 1e-10."""
    from bscomp.systems import get

    dae = _free_chain()
    t = 1e-3 * np.arange(1001)
    outs = ["m0.s", "m1.s", "m2.s", "m2.v"]
    r = simulate(dae, t, inputs={"F.f": 2.0}, outputs=outs, method="modal")
    assert r.stats["rigid_body_dampers"] == ["rigid-body damper at m0.s"]
    xcm = (1.0 * r["m0.s"] + 2.0 * r["m1.s"] + 3.0 * r["m2.s"]) / 6.0
    np.testing.assert_allclose(xcm, 2.0 * t ** 2 / 12.0, rtol=0, atol=1e-8 * 2.0 / 12.0)
    ref = simulate(dae, t, inputs={"F.f": 2.0}, outputs=outs, method="lti")
    for o in outs:
        assert np.abs(r[o] - ref[o]).max() < 1e-8 * np.abs(ref[o]).max(), o
    sub = flatten(get("testbed_submodel1"))
    t = 1e-4 * np.arange(3001)
    outs = ["rotor.phi", "screw.n0.tz", "screw.n47.tz"]
    r = simulate(sub, t, inputs={"amp.u": 1.0}, outputs=outs, method="modal")
    ref = simulate(sub, t, inputs={"amp.u": 1.0}, outputs=outs, method="lti")
    assert r.stats["rigid_body_dampers"] == ["rigid-body damper at rotor.phi"]
    for o in outs:
        assert np.abs(r[o] - ref[o]).max() < 1e-6 * np.abs(ref[o]).max(), o


def test_a_free_chain_through_a_clearance_matches_idas():
    """The free chain with its second spring a 0.2 mm clearance: the rest regime (clearance open) leaves the
    whole chain free, and after the first contact two bodies bounce apart again. The virtual rigid-body damper
    and the backlash channel together equal IDAS at rtol 1e-10 on the same equations."""
    dae = _free_chain(backlash=True)
    t = 1e-4 * np.arange(1001)
    outs = ["m0.s", "m2.s", "m2.v"]

    def push(tt):
        return 40.0 if tt < 0.02 else 0.0

    r = simulate(dae, t, inputs={"F.f": push}, outputs=outs, method="modal")
    ref = simulate(dae, t, inputs={"F.f": push}, outputs=outs, rtol=1e-10, atol=1e-13, max_num_steps=10**7)
    assert r.stats["rigid_body_dampers"] and np.abs(ref["m2.v"]).max() > 0.05      # m2 was hit
    for o in outs:
        assert _nrmse(r[o], ref[o]) < 1e-3, (o, _nrmse(r[o], ref[o]))


def _numpy_newton(stp, y_free, H, g, tol, n_iter):
    """The consistent forces' Newton written in numpy (what Kernel.newton_function compiles)."""
    g = np.array(g, float)
    for _ in range(n_iter):
        gl, L = (np.asarray(a) for a in stp.kernel.law_newton(y_free + H @ g, stp.theta))
        dg = np.linalg.solve(np.eye(g.size) - L @ H, gl.ravel() - g)
        g = g + dg
        if np.abs(dg).max() / (1.0 + np.abs(g).max()) < tol:
            break
    return g


@pytest.mark.parametrize("jit", [False, True])
def test_consistent_forces_solve_the_static_feedthrough(moving, jit):
    """``Stepper.consistent`` (one call of the compiled Newton, Kernel.newton_function): the forces it returns
    satisfy ``g = law(y_free + H g)`` and equal a numpy Newton's, in the sticking and the sliding regime of the
    friction and with the backlash closed, from zero forces (the first iteration does most of the work)."""
    from bscomp.simulation.modal_steps import NEWTON_TOL

    sim = ModalSimulator(moving, moving.p0, jit=jit)
    jt = sim.ch.joints[0]
    cset = sim.channel_set([jt.z0], [jt.z0])
    rng = np.random.default_rng(11)
    for regime in ((0, 0), (1, 1)):
        mp = sim.part(regime, [jt.z0])
        stp = sim.stepper(mp, cset)
        xi = (rng.normal(size=mp.lam.size) + 1j * rng.normal(size=mp.lam.size)) * 1e-5
        u = np.zeros(moving.nu)
        u[moving.u_names.index("amp.u")] = AMP
        g, y, upd = stp.consistent(xi, u, np.zeros(stp.r))
        Cxi, Du, Dg, yc = stp.rows
        H = Dg[:, stp.gsel]
        y_free = (Cxi @ xi).real + Du @ u + yc
        np.testing.assert_allclose(y, y_free + H @ g, rtol=0, atol=1e-12 * (1 + np.abs(y).max()))
        gl = np.asarray(stp.kernel.law_newton(y, stp.theta)[0]).ravel()
        assert upd < NEWTON_TOL and np.abs(gl - g).max() < 1e-8 * (1 + np.abs(g).max()), (regime, upd)
        ref = _numpy_newton(stp, y_free, H, np.zeros(stp.r), NEWTON_TOL, 8)
        np.testing.assert_allclose(g, ref, rtol=0, atol=1e-9 * (1 + np.abs(ref).max()))
        # a feedthrough that couples the forces (H ~ 0 at these states): the compiled Newton against numpy's
        Hc = rng.normal(size=H.shape) * 0.1 * np.abs(y_free).max() / max(np.abs(ref).max(), 1e-300)
        # held to a contraction (|L Hc| <= 0.5 at the free state), so the coupled forces have a fixed point the two
        # Newtons both reach; unheld, the draw depends on the eigenvectors' phases (numpy 2.4 / scipy 1.17: |L Hc|
        # 21 in the first regime, where neither Newton converges in 50 iterations)
        L0 = np.asarray(stp.kernel.law_newton(y_free, stp.theta)[1])
        Hc *= min(1.0, 0.5 / max(np.linalg.norm(L0 @ Hc, 2), 1e-300))
        g, y, upd = stp.newton(y_free, Hc, np.zeros(stp.r))
        ref = _numpy_newton(stp, y_free, Hc, np.zeros(stp.r), NEWTON_TOL, 8)
        assert np.abs(Hc @ ref).max() > 1e-6 * np.abs(y_free).max()          # the coupling matters
        np.testing.assert_allclose(g, ref, rtol=0, atol=1e-9 * (1 + np.abs(ref).max()))
        np.testing.assert_allclose(y, y_free + Hc @ g, rtol=0, atol=1e-12 * (1 + np.abs(y).max()))
