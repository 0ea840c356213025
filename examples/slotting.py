"""Thesis Sec 5.3.3 (Fig 5.16-5.22): a single-axis slotting operation on the axial + torsional test bed
under the three controllers of Chapter 4, each run as a sampled-data controller at T_s = 200 µs.

Run: python examples/slotting.py OUT_DIR [POSITIONS] [FRICTION]
     (default out/slotting, positions "L,C,R,moving", friction "component"; "known" for the older known-force
     run; "moving" is the nut travelling with the table, Sec 5.2.2.3)

Model (section: model)
    ``testbed_axial_torsional`` with the bellows coupling (the notch and the RST of Sec 4.4-4.5 were
    designed on the Table 4.2 bellows plant, and Sec 5.3.3 names its 560 Hz torsional mode), the modal
    damping of the toml ``[damping]`` group and B = 0.0321 kg m^2/s on the motor. The analog PI velocity
    loop (PIController, Tachometer, CurrentAmplifier, K_t) is part of the DAE; the digital blocks
    (DigitalPController, NotchFilter, RSTController) run every T_s through ``simulate(controllers=...)``.
    The table position ``table.s`` is the measured position (linear scale). The guideway's Coulomb
    friction of Table 5.2 (Eq 5.7, F_c+ = 2066 N) is a ``CoulombFriction`` component on the table.
Solve
    ``simulate(..., method="split")`` on a 25 µs grid (24 points per tooth period): the linear closed loop
    stepped by exact zero-order hold, re-linearized per friction regime (stick / slide), the friction
    force implicit (bscomp.simulation.split). IDAS on the same model took 37 s for 20 ms of motion here
    (per-sample restarts), i.e. ~35 min per controller for this 1.2 s operation. Limits:

    * **Nut frozen or moving.** ``L``, ``C``, ``R`` fix the nut at one position per run (toml
      ``table.nut_position_*``) and run the move on each frozen model, which brackets the position-dependent
      dynamics of Sec 5.2.2.3. ``moving`` runs the thesis's own model: the screw-nut joint
      (:class:`MovingScrewNut`) at the nut's current position, the nut travelling with the table from x = R
      to x = L, by ``simulate(method="modal", jit=True)`` (the joint's position-dependent part a low-rank
      correction of an exact modal linear part; bscomp/simulation/modal.py), a few seconds per case.
    * With ``FRICTION=known`` the friction is the known force ``-F_c sign(v_ref(t))`` on the linear model
      (``method="lti"``): exact while the table slides forward, wrong at stand-still (the table is pushed
      back before the drive force exceeds F_c). The viscous part B is the motor's B (applied once).

Trajectory (Table 5.4, Sec 5.3.3): trapezoidal velocity, 1.5 G acceleration and deceleration; 40 m/min
over the first 100 mm from L (ending at 25 m/min), the slot at 25 m/min, then 40 m/min to R and stop.
Cutting force (Table 5.5): see :func:`feed_force_waveform`.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bscomp import flatten
from bscomp.components import (
    CoulombFriction,
    DigitalPController,
    Fixed,
    NotchFilter,
    PIController,
    Tachometer,
)
from bscomp.control.design import ppc_polynomials, rst_design, split_polynomial
from bscomp.simulation.dispatch import simulate
from bscomp.simulation.sampled import sampled_controller
from bscomp.systems.parameters import get_value, load_parameters
from bscomp.systems.testbed import testbed_axial_torsional

CONTROLLERS = ("P-PI", "P-PI + notch", "RST (Table 4.6)", "RST (redesigned)")
#: CHOICE: slot length. Sec 5.3.3 gives it only in Fig 5.16 (missing); 200 mm leaves a 259 mm final rapid.
SLOT_LENGTH = 0.200
#: The first 10 ms are reported apart: with known-force friction it acts there on a table still at rest.
T_START = 0.010
DT = 25e-6  # output grid [s]: 24 points per tooth-passing period (600 µs)
#: Where the moving nut is during the L -> R move (the table axis is the screw's -z): it starts at R.
MOVING_PATH = ("R", "C", "L")
THESIS = {  # Sec 5.3.3 text; the figures themselves are missing from the extracted thesis
    "P-PI": "max 5.6 mm in the rapids (Fig 5.19(e))",
    "P-PI + notch": "max 5.6 mm in the rapids (Fig 5.20(e))",
    "RST (Table 4.6)": "max < 4 mm (Fig 5.21(e))",
    "RST (redesigned)": "max < 4 mm (Fig 5.21(e))",
}


# ---------------------------------------------------------------------------------------------------
# trajectory and cutting force
@dataclass
class Trapezoid:
    """Piecewise-constant acceleration profile: knot times ``tk`` and the acceleration after each knot.

    Attributes
    ----------
    tk, ak : ndarray
        Knot times [s] and accelerations [m/s^2] on ``[tk[i], tk[i+1])``; zero after the last knot.
    phases : dict
        Named time windows ``(t0, t1)``: ``"rapid_1"``, ``"cut"``, ``"rapid_2"``.
    """

    tk: np.ndarray
    ak: np.ndarray
    phases: dict

    def __post_init__(self):
        dt = np.diff(self.tk)
        self._v = np.concatenate([[0.0], np.cumsum(self.ak[:-1] * dt)])
        self._s = np.concatenate([[0.0], np.cumsum(self._v[:-1] * dt + 0.5 * self.ak[:-1] * dt**2)])

    def _seg(self, t):
        t = np.asarray(t, float)
        i = np.clip(np.searchsorted(self.tk, t, side="right") - 1, 0, len(self.tk) - 1)
        tau = np.clip(t - self.tk[i], 0.0, None)
        return i, tau

    def acceleration(self, t):
        i, _ = self._seg(t)
        return np.where(np.asarray(t) < self.tk[-1], self.ak[i], 0.0)

    def velocity(self, t):
        i, tau = self._seg(t)
        return self._v[i] + self.ak[i] * tau

    def position(self, t):
        i, tau = self._seg(t)
        return self._s[i] + self._v[i] * tau + 0.5 * self.ak[i] * tau**2

    @property
    def duration(self) -> float:
        return float(self.tk[-1])


def slotting_trajectory(p, rapid_distance=None, slot_length=SLOT_LENGTH, travel=None) -> Trapezoid:
    """Reference of Sec 5.3.3 / Table 5.4 from the toml ``trajectory.*`` keys.

    ``rapid_feed`` 40 m/min from rest over ``rapid_distance`` (toml ``trajectory.rapid_distance``, 100 mm,
    ending at the slot feed), ``slot_feed`` 25 m/min over ``slot_length`` (CHOICE), then ``rapid_feed``
    again to the end of ``travel`` (default R - L, toml ``table.nut_position_L/R``) where it stops; all
    speed changes at ``trajectory.acceleration_limit`` / ``deceleration_limit`` (1.5 G).
    """
    v_r, v_s = get_value(p, "trajectory.rapid_feed"), get_value(p, "trajectory.slot_feed")
    a_up, a_dn = get_value(p, "trajectory.acceleration_limit"), get_value(p, "trajectory.deceleration_limit")
    d1 = get_value(p, "trajectory.rapid_distance") if rapid_distance is None else rapid_distance
    if travel is None:
        travel = get_value(p, "table.nut_position_R") - get_value(p, "table.nut_position_L")
    d3 = travel - d1 - slot_length
    # segment list: (acceleration, duration)
    t_a0, t_d1 = v_r / a_up, (v_r - v_s) / a_dn
    cruise1 = (d1 - v_r**2 / (2 * a_up) - (v_r**2 - v_s**2) / (2 * a_dn)) / v_r
    t_a2, t_d3 = (v_r - v_s) / a_up, v_r / a_dn
    cruise3 = (d3 - (v_r**2 - v_s**2) / (2 * a_up) - v_r**2 / (2 * a_dn)) / v_r
    if min(cruise1, cruise3) < 0:
        raise ValueError(f"distances too short for the feeds: cruise times {cruise1:.3g}, {cruise3:.3g} s")
    segs = [(a_up, t_a0), (0.0, cruise1), (-a_dn, t_d1), (0.0, slot_length / v_s), (a_up, t_a2), (0.0, cruise3),
            (-a_dn, t_d3)]
    tk = np.concatenate([[0.0], np.cumsum([d for _, d in segs])])
    ak = np.array([a for a, _ in segs] + [0.0])
    t_cut0, t_cut1 = tk[3], tk[4]
    return Trapezoid(tk, ak, {"rapid_1": (0.0, t_cut0), "cut": (t_cut0, t_cut1), "rapid_2": (t_cut1, tk[-1])})


def feed_force_waveform(p, mean=-350.0, n_angle=720, n_slices=50):
    """Feed-direction cutting force over one spindle revolution (Table 5.5, Fig 5.18) for a full slot.

    Mechanistic milling model (linear edge-force law, chip ``h = c sin(phi)``, Altintas's formulation):
    for a flute at immersion ``phi`` in ``(0, pi)`` a disk ``dz`` of the helical edge carries
    ``dF_t = (K_tc h + K_te) dz`` and ``dF_r = (K_rc h + K_re) dz``; its feed component on the tool is
    ``dF_x = -dF_t cos(phi) - dF_r sin(phi)``, summed over the 4 flutes and the 5 mm depth with the
    helix lag ``phi(z) = phi_0 - 2 z tan(30 deg)/D``. Feed per tooth ``c = v_slot / (N n)`` = 0.25 mm.

    CHOICE: the thesis gives neither its in-house software's coefficients nor Fig 5.18; representative
    Al 7075 ratios ``K_tc : K_rc = 796 : 168`` N/mm^2 and edge ``K_te : K_re = 27.7 : 30.8`` N/mm fix the
    *shape*; the waveform is then scaled so its mean is the thesis's -350 N (Sec 5.3.3). On the table
    (which carries the workpiece) the force has the same sign along the table's motion: it opposes it.

    Returns
    -------
    theta, F : ndarray
        Spindle angle [rad] on ``[0, 2 pi)`` and feed force [N]; ``scale``, the factor applied.
    """
    N = int(get_value(p, "cutting.n_flutes"))
    D = get_value(p, "cutting.tool_diameter")
    beta = get_value(p, "cutting.helix_angle")
    a = get_value(p, "cutting.depth_of_cut")
    n_rev = get_value(p, "cutting.spindle_speed") / (2 * np.pi)
    c = get_value(p, "trajectory.slot_feed") / (N * n_rev)
    K_tc, K_rc, K_te, K_re = 796e6, 168e6, 27.7e3, 30.8e3  # N/m^2, N/m (shape only, see CHOICE)
    theta = np.linspace(0.0, 2 * np.pi, n_angle, endpoint=False)
    dz = a / n_slices
    z = (np.arange(n_slices) + 0.5) * dz
    F = np.zeros_like(theta)
    for j in range(N):
        phi = (theta[:, None] + 2 * np.pi * j / N - 2 * z[None, :] * np.tan(beta) / D) % (2 * np.pi)
        cut = phi < np.pi  # full slot: immersion 0 .. 180 deg
        h = c * np.sin(phi)
        dFt = (K_tc * h + K_te) * dz
        dFr = (K_rc * h + K_re) * dz
        F += np.sum(np.where(cut, -dFt * np.cos(phi) - dFr * np.sin(phi), 0.0), axis=1)
    scale = mean / F.mean()
    return theta, F * scale, scale


def cutting_force(p, window, mean=-350.0):
    """``f(t)``: the periodic feed force of :func:`feed_force_waveform` while ``window[0] <= t < window[1]``
    (tool entry and exit transients not modelled: CHOICE), else 0. Spindle at ``cutting.spindle_speed``."""
    theta, F, _ = feed_force_waveform(p, mean)
    omega = get_value(p, "cutting.spindle_speed")
    t0, t1 = window

    def f(t):
        if not t0 <= t < t1:
            return 0.0
        ang = (omega * (t - t0)) % (2 * np.pi)
        return float(np.interp(ang, np.r_[theta, 2 * np.pi], np.r_[F, F[0]]))

    return f


# ---------------------------------------------------------------------------------------------------
# model
def closed_loop_plant(p, kind: str, nut_position="C", coupling="bellows", friction: bool = False,
                      nut_joint: str = "point"):
    """The test bed with the analog part of the controller: ``"P-PI"`` adds the PI velocity loop of
    Fig 4.3 (input ``pi.u_s`` [V]), ``"RST"`` only the amplifier (input ``amp.u`` [V], Fig 4.19).
    ``friction=True`` adds the guideway's Coulomb friction of Table 5.2 as a component (Eq 5.7 with the
    +/- levels, regularised over v_reg = 0.1 mm/s as in examples/nonlinear_scenarios.py). ``nut_joint="moving"``:
    the screw-nut joint at the nut's current position (Sec 5.2.2.3), ``nut_position`` where it starts."""
    s = testbed_axial_torsional(nut_position=nut_position, coupling=coupling, nut_joint=nut_joint)
    if friction:
        fb = p["friction_backlash"]
        s.add("guide_ground", Fixed())
        s.add("friction", CoulombFriction(F_c_pos=fb["F_coul_pos"]["value"], F_c_neg=abs(fb["F_coul_neg"]["value"]),
                                          v_reg=1e-4))
        s.connect("friction.flange_a", "guide_ground.flange")
        s.connect("friction.flange_b", "table.flange_b")
    if kind == "P-PI":
        s.add("pi", PIController(K_v=get_value(p, "control.K_v"), K_i=get_value(p, "control.K_i")))
        s.add("tacho", Tachometer(H_g=get_value(p, "electrical.H_g")))
        s.connect("pi.y", "amp.u")
        s.connect("tacho.flange", "rotor.flange_a")
        s.connect("tacho.v", "pi.u_m")
    return flatten(s)       # the test bed's modal damping (toml [damping]) with the PI's state held


def rst_thesis(p):
    """RST of Sec 4.5 from the thesis's Table 4.4 plant (reproduces Table 4.6; Eq 4.24-4.38)."""
    Ts = get_value(p, "control.T_s")
    A = [1.0] + list(get_value(p, "control.ppc_A"))
    B = get_value(p, "control.ppc_B")
    B_plus, _ = split_polynomial(B, near=[get_value(p, "control.ppc_cancelled_zero")])
    pp = ppc_polynomials(get_value(p, "control.ppc_zeta_c"), get_value(p, "control.ppc_omega_c"),
                         get_value(p, "control.ppc_alpha"), get_value(p, "control.ppc_zeta_o"),
                         get_value(p, "control.ppc_omega_o"), Ts, B_plus=B_plus)
    return rst_design(A, B, pp.A_c, pp.A_o, B_plus=B_plus, R_d=[1, -1], S_d=[1, 1], Ts=Ts)


def rst_redesigned(p, position="C"):
    """The same pole-placement design (Eq 4.24-4.38, Table 4.5 design values) on *this* model's plant:
    rigid body + first mode of the axial + torsional bellows test bed at ``position`` (the procedure of
    Table 4.4, with bscomp's modal parameters instead of the thesis's measured-model ones)."""
    import control

    from bscomp.control.closed_loop import modal_plant
    from bscomp.control.design import zoh_polynomials
    from bscomp.systems.testbed_analysis import drive_parameters

    Ts = get_value(p, "control.T_s")
    d = drive_parameters(variant="axial_torsional", nut_position=position, coupling="bellows")
    K_e = get_value(p, "electrical.K_a") * get_value(p, "electrical.K_t")
    Gm = modal_plant(d["J"], d["B"], d["r_g"], [(d["f1"], d["zeta1"], d["Rw1"], d["Rm1"])]).sys[1, 0] * K_e
    A, B = zoh_polynomials(control.ss(Gm), Ts)
    B_plus, _ = split_polynomial(B, near=[get_value(p, "control.ppc_cancelled_zero")])
    pp = ppc_polynomials(get_value(p, "control.ppc_zeta_c"), get_value(p, "control.ppc_omega_c"),
                         get_value(p, "control.ppc_alpha"), get_value(p, "control.ppc_zeta_o"),
                         get_value(p, "control.ppc_omega_o"), Ts, B_plus=B_plus)
    return rst_design(A, B, pp.A_c, pp.A_o, B_plus=B_plus, R_d=[1, -1], S_d=[1, 1], Ts=Ts)


def controller_blocks(p, name):
    """Sampled blocks of a controller, the input they drive and the plant kind."""
    Ts = get_value(p, "control.T_s")
    if name == "P-PI":
        return [DigitalPController(get_value(p, "control.K_p"), Ts)], "pi.u_s", "P-PI"
    if name == "P-PI + notch":
        n1, n2, d1, d2, K_N = get_value(p, "control.notch_coefficients")
        return ([DigitalPController(get_value(p, "control.K_p_notch"), Ts), NotchFilter(n1, n2, d1, d2, K_N, Ts)],
                "pi.u_s", "P-PI")
    if name == "RST (Table 4.6)":
        return [rst_thesis(p).controller()], "amp.u", "RST"
    if name == "RST (redesigned)":
        return [rst_redesigned(p).controller()], "amp.u", "RST"
    raise ValueError(f"controller {name!r}: use one of {CONTROLLERS}")


def spectral_radius(dae, blocks, actuate, measure="table.s", gain=1.0):
    """Largest |z| of the sampled closed loop (plant ZOH-discretised at T_s, linearized): < 1 is stable."""
    import control

    from bscomp import linearize

    Ts = blocks[0].T_s
    lin = linearize(dae, inputs=[actuate], outputs=[measure])
    Pz = control.c2d(control.ss(lin.A, lin.B, gain * lin.C, gain * lin.D), Ts, "zoh")
    K = blocks[0].ss()
    K = control.ss(K.A, K.B[:, -1:], K.C, K.D[:, -1:], Ts)   # from y (the feedback input)
    for b in blocks[1:]:
        K = control.series(K, b.ss())
    sign = 1.0 if len(blocks[0].inputs) == 2 else -1.0          # (r, y) blocks already carry -S / -K_p on y
    L = control.series(Pz, K)
    cl = control.feedback(L, control.ss([], [], [], [[1.0]], Ts), sign=sign)
    return float(np.max(np.abs(np.linalg.eigvals(cl.A))))


def controller(p, name, reference):
    """Sampled controller and the plant kind it acts on. A positive command moves the table forward
    (``table.v = r_g rotor.w``, systems/testbed.py sign convention), so the controllers work on ``table.s``."""
    blocks, act, kind = controller_blocks(p, name)
    return sampled_controller(blocks, "table.s", act, reference), kind


# ---------------------------------------------------------------------------------------------------
# solve and post-process
def run_case(p, name, traj, position, friction="component", t_end=None, cut_window=None, dt=DT, plants=None):
    """Simulate one controller with the nut frozen at ``position`` or, for ``position="moving"``, travelling
    with the table (it starts at R: the table axis is the screw's -z, so the L -> R move runs the nut from
    x = R to x = L); returns a dict of signals.

    ``friction``: ``"component"`` (default) -- the Table 5.2 Coulomb friction as a component in the
    model, run by ``simulate(method="split")`` (exact ZOH of the linear part per friction regime, so the
    table sticks at rest and slides under load); ``"known"`` -- friction as the known force
    ``-F_c sign(v_ref(t))`` on the linear model (``method="lti"``, exact while the table slides forward);
    ``False`` -- none.
    """
    if friction not in ("component", "known", False, None):
        raise ValueError(f"run_case: friction must be 'component', 'known' or False, got {friction!r}")
    real = friction == "component"
    moving = position == "moving"
    joint, position = ("moving", "R") if moving else ("point", position)
    t_end = traj.duration + 0.1 if t_end is None else t_end
    t = dt * np.arange(int(round(t_end / dt)) + 1)
    ctrl, kind = controller(p, name, lambda tt: float(traj.position(tt)))
    key = (kind, position, real, joint)
    if plants is None or key not in plants:
        dae = closed_loop_plant(p, kind, position, friction=real, nut_joint=joint)
        if plants is not None:
            plants[key] = dae
    else:
        dae = plants[key]
    f_cut = cutting_force(p, traj.phases["cut"] if cut_window is None else cut_window)
    F_c = abs(get_value(p, "friction_backlash.F_coul_pos")) if friction == "known" else 0.0

    def f_table(tt):
        return f_cut(tt) - F_c * np.sign(traj.velocity(tt))

    act = ctrl.actuate[0]
    method = "modal" if moving else ("split" if real else "lti")
    res = simulate(dae, t, inputs={"Fd.f": f_table}, controllers=[ctrl], method=method, jit=moving,
                   outputs=["table.s", "table.v", "table.a", "amp.u"] + (["sn.z"] if moving else []))
    r = traj.position(t)
    return {"t": t, "ref": r, "v_ref": traj.velocity(t), "a_ref": traj.acceleration(t), "x": res["table.s"],
            "v": res["table.v"], "a": res["table.a"], "e": r - res["table.s"], "u": res["amp.u"],
            "u_ctrl": res[act], "F_d": res["Fd.f"], "wall_s": res.stats["wall_s"], "friction": friction,
            "z_nut": res["sn.z"] if moving else None}


def amplitude_at(t, y, f):
    """Amplitude of the ``f`` [Hz] component of ``y(t)`` (least-squares sine + cosine + mean + trend)."""
    w = 2 * np.pi * f
    X = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t), t - t.mean()])
    c, *_ = np.linalg.lstsq(X, y, rcond=None)
    return float(np.hypot(c[0], c[1]))


#: Bands of Sec 5.3.3's vibrations: the screw's axial mode (112-140 Hz by position, "about 120 Hz" in the cut)
#: and the intermittent "about 333 Hz" of Fig 5.22 [Hz].
AXIAL_BAND = (90.0, 170.0)
BAND_333 = (290.0, 380.0)
#: The cut's vibrations are taken from this long after the slot starts [s] (the axial mode's ringing from the
#: change to 25 m/min, 6 % damping at ~120 Hz: time constant 22 ms, has decayed below 1e-3 by then) to as long
#: before it ends (the zero-phase filter's backward pass brings the next rapid's start 0.45 G into the last 50 ms).
CUT_SETTLE = 0.15


def band_peak(t, y, band, window):
    """Largest ``|y|`` inside ``window = (t0, t1)`` after a zero-phase band-pass (4th-order Butterworth, run
    forward and backward over the whole record so that the window has no filter edge): the amplitude of the
    vibration in ``band`` [Hz]."""
    from scipy.signal import butter, sosfiltfilt

    sos = butter(4, band, btype="bandpass", fs=1.0 / (t[1] - t[0]), output="sos")
    yb = sosfiltfilt(sos, y)
    m = (t >= window[0]) & (t < window[1])
    return float(np.max(np.abs(yb[m])))


def metrics(res, traj, f_tooth):
    t, e = res["t"], res["e"]
    out = {}
    g = 9.80665
    vib = res["a"] - res["a_ref"]           # the vibration: the commanded 1.5 G steps taken out
    r1, r2 = traj.phases["rapid_1"], traj.phases["rapid_2"]
    out["axial_rapid_1_G"] = band_peak(t, vib, AXIAL_BAND, r1) / g
    out["axial_rapid_2_G"] = band_peak(t, vib, AXIAL_BAND, (r2[0], min(r2[1] + 0.05, t[-1]))) / g
    steady = (traj.phases["cut"][0] + CUT_SETTLE, traj.phases["cut"][1] - CUT_SETTLE)
    out["cut_axial_G"] = band_peak(t, vib, AXIAL_BAND, steady) / g
    out["cut_333_G"] = band_peak(t, vib, BAND_333, steady) / g
    for ph in ("rapid_1", "cut", "rapid_2"):
        t0, t1 = traj.phases[ph]
        m = (t >= t0) & (t < t1)
        out[f"{ph}_max_mm"] = 1e3 * float(np.max(np.abs(e[m])))
        out[f"{ph}_rms_mm"] = 1e3 * float(np.sqrt(np.mean(e[m] ** 2)))
    t0, t1 = traj.phases["cut"]
    m = (t >= t0 + 0.05) & (t < t1)  # steady cut (after the 25 m/min transient)
    out["cut_e_tooth_nm"] = 1e9 * amplitude_at(t[m], e[m], f_tooth)
    out["cut_a_tooth_G"] = amplitude_at(t[m], res["a"][m], f_tooth) / 9.80665
    mv = (t > T_START) & (t < traj.duration - T_START)
    out["min_v_during_move"] = float(np.min(res["v"][mv]))
    out["min_v_after_end"] = float(np.min(res["v"][t >= traj.duration]))
    out["start_backslide_um"] = -1e6 * float(min(0.0, np.min(res["x"][t < T_START])))
    late = t >= T_START
    out["u_peak_V"] = float(np.max(np.abs(res["u"][late])))
    out["u_peak_start_V"] = float(np.max(np.abs(res["u"][~late])))
    return out


def plot_case(results, traj, name, path):
    from bscomp.plotting.base import _plt

    plt = _plt()
    fig, ax = plt.subplots(4, 1, sharex=True, figsize=(9, 10))
    for pos, r in results.items():
        label = "nut moving R -> L" if pos == "moving" else f"nut frozen at {pos}"
        ax[0].plot(r["t"], r["v"] * 60, lw=0.8, label=label)
        ax[1].plot(r["t"], 1e3 * r["e"], lw=0.8, label=pos)
        ax[2].plot(r["t"], r["a"] / 9.80665, lw=0.5, label=pos)
        ax[3].plot(r["t"], r["u"], lw=0.6, label=pos)
    r0 = next(iter(results.values()))
    ax[0].plot(r0["t"], r0["v_ref"] * 60, "k--", lw=0.8, label="reference")
    for a_ in ax:
        for ph in ("cut",):
            a_.axvspan(*traj.phases[ph], color="0.9", zorder=0)
    ax[0].set_ylabel("table velocity [m/min]")
    ax[1].set_ylabel("tracking error [mm]")
    ax[2].set_ylabel("table acceleration [G]")
    ax[3].set_ylabel("amplifier command [V]\n(+ drives the table forward)")
    ax[3].set_xlabel("time [s] (grey: slot cut)")
    ax[0].legend(fontsize=7, loc="lower center")
    ax[0].set_title(f"Slotting, {name} (cf. Fig 5.19-5.21)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_cut_zoom(all_res, traj, position, path):
    """Fig 5.22: table acceleration during the cut, one panel per controller (20 ms window)."""
    from bscomp.plotting.base import _plt

    plt = _plt()
    t0 = traj.phases["cut"][0] + 0.1
    fig, ax = plt.subplots(len(all_res), 1, sharex=True, figsize=(9, 7))
    for a_, (name, by_pos) in zip(np.atleast_1d(ax), all_res.items()):
        r = by_pos[position]
        m = (r["t"] >= t0) & (r["t"] < t0 + 0.02)
        a_.plot(1e3 * (r["t"][m] - t0), r["a"][m] / 9.80665, lw=0.8)
        a_.set_ylabel(f"{name}\n[G]")
    np.atleast_1d(ax)[-1].set_xlabel(f"time [ms] after t = {t0:.3f} s (steady slot, nut at {position})")
    np.atleast_1d(ax)[0].set_title("Table acceleration during the cut (cf. Fig 5.22)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(out_dir="out/slotting", positions="L,C,R,moving", friction="component"):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    p = load_parameters()
    positions = [s.strip() for s in positions.split(",") if s.strip()]
    traj = slotting_trajectory(p)
    f_tooth = get_value(p, "cutting.n_flutes") * get_value(p, "cutting.spindle_speed") / (2 * np.pi)
    _, F, scale = feed_force_waveform(p)
    print(f"trajectory: {traj.duration:.4f} s, cut {traj.phases['cut'][0]:.4f}-{traj.phases['cut'][1]:.4f} s; "
          f"feed force mean {F.mean():.1f} N, range {F.min():.1f}..{F.max():.1f} N (scale {scale:.3f}), "
          f"tooth passing {f_tooth:.1f} Hz")
    t_wall = time.perf_counter()
    all_res, rows = {}, []
    plants = {}
    for name in CONTROLLERS:
        all_res[name] = {}
        for pos in positions:
            blocks, act, kind = controller_blocks(p, name)
            rho = 0.0
            for at in (MOVING_PATH if pos == "moving" else (pos,)):     # the moving nut passes R, C, L
                if (kind, at, False) not in plants:                   # stability: the linear plant
                    plants[(kind, at, False)] = closed_loop_plant(p, kind, at)
                rho = max(rho, spectral_radius(plants[(kind, at, False)], blocks, act))
                if pos == "moving" and rho >= 1.0:
                    break                                              # unstable where it starts or passes
            if rho >= 1.0:
                rows.append((name, pos, rho, None))
                print(f"  {name:<17} nut at {pos}: closed loop UNSTABLE (max |z| = {rho:.4f}), not simulated")
                continue
            r = run_case(p, name, traj, pos, friction=friction, plants=plants)
            all_res[name][pos] = r
            rows.append((name, pos, rho, metrics(r, traj, f_tooth)))
            print(f"  {name:<17} nut at {pos}: max |z| = {rho:.4f}, {r['wall_s']:5.1f} s wall")
        if all_res[name]:
            fname = name.replace(" + ", "_").replace("-", "").replace(" (", "_").replace(")", "").replace(" ", "_")
            plot_case(all_res[name], traj, name, out / f"slotting_{fname}.png")
    zoom = {k: v for k, v in all_res.items() if ("C" if "C" in positions else positions[0]) in v}
    plot_cut_zoom(zoom, traj, "C" if "C" in positions else positions[0], out / "slotting_cut_acceleration.png")
    head = ("| controller | nut | max abs z | rapid max [mm] | rapid RMS [mm] | cut max [mm] | cut RMS [mm] | "
            "e at 1667 Hz [nm] | a at 1667 Hz [G] | peak u [V] | peak u, first 10 ms [V] | min v [m/s] | thesis |")
    lines = [head, "|" + "---|" * 13]
    for name, pos, rho, m in rows:
        if m is None:
            lines.append(f"| {name} | {pos} | {rho:.4f} | unstable | | | | | | | | | {THESIS[name]} |")
            continue
        rmax = max(m["rapid_1_max_mm"], m["rapid_2_max_mm"])
        rrms = np.sqrt(0.5 * (m["rapid_1_rms_mm"] ** 2 + m["rapid_2_rms_mm"] ** 2))
        lines.append(f"| {name} | {pos} | {rho:.4f} | {rmax:.3f} | {rrms:.3f} | {m['cut_max_mm']:.3f} | "
                     f"{m['cut_rms_mm']:.3f} | {m['cut_e_tooth_nm']:.2f} | {m['cut_a_tooth_G']:.4f} | "
                     f"{m['u_peak_V']:.1f} | {m['u_peak_start_V']:.1f} | {m['min_v_during_move']:.4f} | "
                     f"{THESIS[name]} |")
        print(f"    {name}, {pos}: start back-slide {m['start_backslide_um']:.2f} µm, min v after the end "
              f"{m['min_v_after_end']:.2e} m/s")
    lines += ["", "Vibrations (table acceleration minus the commanded one, band-passed, peak [G]; Fig 5.19(c)-5.22): "
              f"{AXIAL_BAND[0]:g}-{AXIAL_BAND[1]:g} Hz (the screw's axial mode) in the first rapid, in the second "
              f"rapid with its stop, and in the cut from {1e3 * CUT_SETTLE:g} ms after its start to as long "
              "before its end; "
              f"{BAND_333[0]:g}-{BAND_333[1]:g} Hz there",
              "", "| controller | nut | axial mode, rapid 1 [G] | axial mode, rapid 2 + stop [G] | "
              "axial mode, cut [G] | ~333 Hz, cut [G] |", "|" + "---|" * 6]
    for name, pos, _, m in rows:
        if m is not None:
            lines.append(f"| {name} | {pos} | {m['axial_rapid_1_G']:.4f} | {m['axial_rapid_2_G']:.4f} | "
                         f"{m['cut_axial_G']:.1e} | {m['cut_333_G']:.1e} |")
    text = "\n".join(lines)
    (out / "slotting.md").write_text(text + "\n")
    print(text)
    print(f"total wall time {time.perf_counter() - t_wall:.1f} s")
    return all_res, rows


if __name__ == "__main__":
    main(*(sys.argv[1:4] or ["out/slotting"]))
