"""Closed-loop analysis of the feed-drive controllers of thesis Chapter 4 (python-control).

Plants (:class:`DrivePlant`, continuous, inputs ``tau`` [N m] and optionally ``F_d`` [N], outputs ``w``
[rad/s] and ``x`` [m]):

* :func:`rigid_plant` -- rigid-body model, Eq (4.2);
* :func:`modal_plant` -- rigid body plus normal modes, Eq (4.3)-(4.7); the thesis plants of Tables 4.1
  and 4.2 (L/C/R positions) are :func:`bscomp.systems.thesis_plants.thesis_modal_plant`;
* :func:`plant_from_system` -- any bscomp model, through :func:`bscomp.linearize` (e.g. ``small_drive``).

Loops (each returns a :class:`~bscomp.control.loop_analysis.LoopAnalysis`):

* :func:`velocity_loop` -- analog PI velocity loop (Fig 4.3, Eq 4.10), open loop broken at the
  tachometer feedback: ``L(s) = C(s) K_a K_t G_w(s) H_g``;
* :func:`p_pi_loop` -- digital P position loop around the closed velocity loop, with an optional notch
  (Fig 4.3, 4.14): ``L(z) = G_N(z) K_p Z{ZOH G_v(s) G_x(s)}`` (Eq 4.17), broken at the position error
  (equivalently at the measured position);
* :func:`rst_loop` -- pole-placement controller on ``B(z)/A(z) = Z{ZOH G_e G_m}`` (Fig 4.19-4.20),
  ``L(z) = B S / (A R)`` broken at the plant input.

Sign convention of the disturbance: ``F_d`` acts on the table in ``+x`` (``G_d^r = r_g/(J s + B)``, Eq
4.2). The thesis's "sensitivity" plots of Figs 4.5, 4.8, 4.11, 4.18 and 4.24 show the disturbance response
(``w/F_d`` or ``x/F_d``; its -172 dB peak is in m/N), not ``1/(1 + L)``: a ``LoopAnalysis`` reports
both (``S_peak_db`` and ``D_peak_db``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bscomp.components import RSTController
from bscomp.control._checks import polynomial, real
from bscomp.control.design import NotchCoefficients, RSTDesign
from bscomp.control.loop_analysis import LoopAnalysis, freqresp, loop_metrics, margins
from bscomp.errors import ArgumentTypeError, ParameterError, UnknownNameError, UsageError
from bscomp.kernel.sampled import SampledBlock
from bscomp.linear.linearization import control_labels, linearize

__all__ = [
    "DrivePlant", "rigid_plant", "modal_plant", "plant_from_system", "velocity_loop", "p_pi_loop", "rst_loop",
    # the result and its metrics, defined in bscomp.control.loop_analysis
    "LoopAnalysis", "loop_metrics", "margins", "freqresp",
]


# ---------------------------------------------------------------------------------------------------
# plants
@dataclass
class DrivePlant:
    """Continuous feed-drive plant: inputs ``tau`` (motor torque) and optionally ``F_d`` (table force),
    outputs ``w`` (motor speed) and ``x`` (table position).

    Attributes
    ----------
    sys : control.StateSpace
        With ``input_labels`` ``['tau']`` or ``['tau', 'F_d']`` and ``output_labels`` ``['w', 'x']``.
    name : str
    """

    sys: Any
    name: str = "plant"

    @property
    def has_disturbance(self) -> bool:
        return "F_d" in self.sys.input_labels


def _plant_ss(A, B, C, D, inputs, name):
    import control

    return DrivePlant(control.ss(A, B, C, D, inputs=inputs, outputs=["w", "x"],
                                 name=name.replace(".", "_")), name)


def rigid_plant(J: float, B: float, r_g: float, name: str = "rigid") -> DrivePlant:
    """Rigid-body drive, Eq (4.2): ``G_w = 1/(J s + B)``, ``G_x = r_g/s``, ``G_d = r_g/(J s + B)``.

    States: motor speed ``w`` [rad/s] and table position ``x`` [m].
    """
    return modal_plant(J, B, r_g, [], name=name)


def modal_plant(J: float, B: float, r_g: float, modes, name: str = "modal") -> DrivePlant:
    """Rigid body plus normal modes, Eq (4.3)-(4.7).

    Parameters
    ----------
    J, B, r_g : float
        Inertia [kg m^2] and damping [kg m^2/s] at the motor, lead ratio [m/rad] (Sec 4.2.1).
    modes : sequence of (f_n [Hz], zeta, R_w, R_m)
        Natural frequency, damping ratio and residues of ``G_w`` (Eq 4.5) and ``G_m`` (Eq 4.7), as in
        Tables 4.1/4.2.

    Returns
    -------
    DrivePlant
        ``G_w = 1/(Js+B) + sum R_w,k s/(s^2 + 2 zeta_k w_k s + w_k^2)`` and
        ``G_m = r_g/(Js^2+Bs) + sum R_m,k/(...)`` from ``tau``; from ``F_d`` the same modes with the
        residues of a consistent modal model: ``R_d = R_m`` to ``w`` (Table 4.1 prints ``R_d = R_m``) and
        ``R_m^2/R_w`` to ``x`` (mode-shape entries ``P_mot = sqrt(R_w)``, ``P_tab = R_m/sqrt(R_w)``,
        Eq 4.4). The thesis forms ``G_d^x = G_d G_m / G_w`` instead (Eq 4.30), equal for the rigid part.
    """
    J = real("modal_plant", "J", J, positive=True, unit="kg m^2")
    r_g = real("modal_plant", "r_g", r_g, positive=True, unit="m/rad")
    B = real("modal_plant", "B", B, nonnegative=True, unit="kg m^2/s")
    modes = _modes(modes)
    n = 2 + 2 * len(modes)
    A = np.zeros((n, n))
    Bm = np.zeros((n, 2))
    C = np.zeros((2, n))
    A[0, 0] = -B / J
    A[1, 0] = r_g
    Bm[0, 0], Bm[0, 1] = 1 / J, r_g / J
    C[0, 0] = C[1, 1] = 1.0
    for k, (f_n, zeta, R_w, R_m) in enumerate(modes):
        if not (f_n > 0 and zeta >= 0 and R_w > 0):
            raise ParameterError(f"modal_plant: mode {k + 1}: need f_n > 0, zeta >= 0 and R_w > 0, "
                                 f"got {(f_n, zeta, R_w, R_m)}")
        w = 2 * math.pi * f_n
        i = 2 + 2 * k
        A[i, i + 1] = 1.0
        A[i + 1, i], A[i + 1, i + 1] = -w * w, -2 * zeta * w
        p_mot, p_tab = math.sqrt(R_w), R_m / math.sqrt(R_w)
        Bm[i + 1, 0], Bm[i + 1, 1] = p_mot, p_tab
        C[0, i + 1], C[1, i] = p_mot, p_tab
    return _plant_ss(A, Bm, C, np.zeros((2, 2)), ["tau", "F_d"], name)


_MODE_FORM = ("a sequence of modes, each (f_n [Hz], zeta, R_w, R_m), e.g. [(120.0, 0.05, 0.8, 0.01)] "
              "(Tables 4.1/4.2); [] for the rigid body alone")


def _modes(modes) -> list[tuple[float, float, float, float]]:
    """``modes`` of :func:`modal_plant` as a list of 4 floats each, else a :class:`UsageError` giving the form."""
    if isinstance(modes, (str, bytes, dict)) or not hasattr(modes, "__iter__"):
        raise ArgumentTypeError(f"modal_plant: modes must be {_MODE_FORM}, got {type(modes).__name__} "
                                f"{modes!r}"[:300])
    out = []
    for k, m in enumerate(modes):
        try:
            row = np.asarray(m, dtype=float)
        except (TypeError, ValueError):
            row = None
        if row is None or row.shape != (4,):
            raise UsageError(f"modal_plant: mode {k + 1} = {m!r} is not (f_n [Hz], zeta, R_w, R_m); modes must "
                             f"be {_MODE_FORM}"[:400])
        if not np.all(np.isfinite(row)):
            raise ParameterError(f"modal_plant: mode {k + 1} = {tuple(row.tolist())} is not finite")
        out.append(tuple(float(v) for v in row))
    return out


def plant_from_system(model, tau: str = "motor.tau", w: str = "rotor.w", x: str = "table.s",
                      F_d: str | None = None, name: str | None = None) -> DrivePlant:
    """A :class:`DrivePlant` from a bscomp System/Dae (linearized) or a python-control StateSpace.

    Parameters
    ----------
    model : System, Dae or control.StateSpace
        A StateSpace must carry the labels (bscomp's ``'.'`` appear as ``'/'``, see
        :func:`bscomp.linear.control_labels`).
    tau, w, x : str
        Names of the motor-torque input, motor-speed output and table-position output.
    F_d : str, optional
        Name of a table-force input (e.g. a :class:`~bscomp.components.Force` on the table).
    """
    import control

    inputs = [tau] + ([F_d] if F_d else [])
    if not isinstance(model, control.StateSpace):
        model = linearize(model, inputs=inputs, outputs=[w, x])
    labels_in, labels_out = list(model.input_labels), list(model.output_labels)
    try:
        iu = [labels_in.index(n) for n in control_labels(inputs)]
        iy = [labels_out.index(n) for n in control_labels([w, x])]
    except ValueError as exc:
        raise UnknownNameError(f"plant signals {inputs} -> {[w, x]} not found among inputs {labels_in} and "
                               f"outputs {labels_out}") from exc
    return _plant_ss(model.A, model.B[:, iu], model.C[iy, :], model.D[np.ix_(iy, iu)],
                     ["tau"] + (["F_d"] if F_d else []), name or getattr(model, "name", "plant"))


# ---------------------------------------------------------------------------------------------------
# loops
def _sub(sys, outputs, inputs):
    """Sub-system by signal names (python-control 0.10 indexes by integer or single name only)."""
    import control

    outputs = [outputs] if isinstance(outputs, str) else list(outputs)
    inputs = [inputs] if isinstance(inputs, str) else list(inputs)
    try:
        io = [list(sys.output_labels).index(n) for n in outputs]
        ii = [list(sys.input_labels).index(n) for n in inputs]
    except ValueError as exc:
        raise UnknownNameError(f"signals {outputs} <- {inputs} not in {sys.output_labels} <- "
                               f"{sys.input_labels}") from exc
    return control.ss(sys.A, sys.B[:, ii], sys.C[io, :], sys.D[np.ix_(io, ii)], sys.dt, inputs=inputs,
                      outputs=outputs)


def _gain(k, inp, out, dt=None):
    import control

    return control.ss([], [], [], [[k]], dt, inputs=[inp], outputs=[out]) if dt else \
        control.ss([], [], [], [[k]], inputs=[inp], outputs=[out])


def _velocity_closed(plant: DrivePlant, K_a, K_t, H_g, K_v, K_i, inner_notch=None):
    """Continuous velocity loop closed: inputs ``u_v`` [V] (and ``F_d``), outputs ``w``, ``x``, ``u``."""
    import control

    pi = control.ss(0.0, 1.0, K_i, K_v, inputs=["e"], outputs=["u"], name="pi")
    sm = control.summing_junction(inputs=["u_v", "-w_m"], output="e", name="sum")
    parts = [plant.sys, pi, sm, _gain(H_g, "w", "w_m"), _gain(K_a * K_t, "u", "tau")]
    inputs = ["u_v"] + (["F_d"] if plant.has_disturbance else [])
    return control.interconnect(parts, inplist=inputs, outlist=["w", "x", "u"], inputs=inputs,
                                outputs=["w", "x", "u"], name="velocity_loop")


def velocity_loop(plant: DrivePlant, K_a: float, K_t: float, H_g: float, K_v: float, K_i: float,
                  t_final: float = 0.05) -> LoopAnalysis:
    """Analog PI velocity loop (Sec 4.3.1).

    ``L(s) = (K_v + K_i/s) K_a K_t G_w(s) H_g`` (broken at the tachometer feedback);
    ``T = H_g w/u_v`` (unit DC gain; Eq 4.10 times H_g); ``D = w/F_d``.
    """
    import control

    f = "velocity_loop"
    plant = _drive_plant(f, plant)
    K_a, K_t, H_g, K_v, K_i = _gains(f, K_a=K_a, K_t=K_t, H_g=H_g, K_v=K_v, K_i=K_i)
    t_final = real(f, "t_final", t_final, positive=True, unit="s")
    Gw = _sub(plant.sys, ["w"], ["tau"])
    pi = control.ss(0.0, 1.0, K_i, K_v)
    L = control.series(pi, _gain(K_a * K_t, "u", "tau"), Gw, _gain(H_g, "w", "w_m"))
    S = control.feedback(control.ss([], [], [], [[1.0]]), L)
    cl = _velocity_closed(plant, K_a, K_t, H_g, K_v, K_i)
    T = H_g * _sub(cl, ["w"], ["u_v"])
    D = _sub(cl, ["w"], ["F_d"]) if plant.has_disturbance else None
    res = LoopAnalysis(f"PI velocity loop on {plant.name}", L, S, T, D, t_final=t_final,
                       info=dict(loop="velocity", K_a=K_a, K_t=K_t, H_g=H_g, K_v=K_v, K_i=K_i,
                                 plant=plant.name))
    loop_metrics(res)
    return res


def p_pi_loop(plant: DrivePlant, K_a: float, K_t: float, H_g: float, K_v: float, K_i: float, K_p: float,
              Ts: float, notch=None, t_final: float = 0.1) -> LoopAnalysis:
    """Digital P position loop (ZOH, period ``Ts``) around the analog PI velocity loop (Sec 4.3.2, 4.4.2).

    Parameters
    ----------
    plant : DrivePlant
    K_a, K_t, H_g, K_v, K_i : float
        Velocity loop (Eq 4.1, 4.14).
    K_p : float
        Position gain [V/m] (7000; 5000 with the notch).
    Ts : float
        Sampling period [s] (200e-6).
    notch : NotchFilter, NotchCoefficients or control.LTI, optional
        Digital filter after the P controller (Fig 4.14).

    Returns
    -------
    LoopAnalysis
        ``L(z) = G_N(z) K_p Z{ZOH G_v G_x}`` (Eq 4.17), ``T = x/x_r``, ``D = x/F_d`` (F_d sampled and held,
        as the thesis assumes in Sec 4.5).
    """
    import control

    f = "p_pi_loop"
    plant = _drive_plant(f, plant)
    K_a, K_t, H_g, K_v, K_i = _gains(f, K_a=K_a, K_t=K_t, H_g=H_g, K_v=K_v, K_i=K_i)
    K_p = real(f, "K_p", K_p, positive=True, unit="V/m")
    Ts = real(f, "Ts", Ts, positive=True, unit="s")
    t_final = _t_final(f, t_final, Ts)
    cl = _velocity_closed(plant, K_a, K_t, H_g, K_v, K_i)
    outs = ["x"]
    ins = ["u_v"] + (["F_d"] if plant.has_disturbance else [])
    Pz = control.c2d(_sub(cl, outs, ins), Ts, "zoh")
    Pz = control.ss(Pz.A, Pz.B, Pz.C, Pz.D, Ts, inputs=ins, outputs=["x"], name="plant_z")
    K = _gain(K_p, "e", "u_p", Ts)
    if notch is not None:
        N = _as_discrete(notch, Ts, f)
        N = control.ss(N.A, N.B, N.C, N.D, Ts, inputs=["u_p"], outputs=["u_v"], name="notch")
    else:
        N = _gain(1.0, "u_p", "u_v", Ts)
    sm = control.summing_junction(inputs=["x_r", "-x"], output="e", name="sum", dt=Ts)
    L = control.series(K, N, _sub(Pz, ["x"], ["u_v"]))
    one = control.ss([], [], [], [[1.0]], Ts)
    S = control.feedback(one, L)
    ext = ["x_r"] + ins[1:]
    full = control.interconnect([Pz, K, N, sm], inplist=ext, outlist=["x"], inputs=ext, outputs=["x"], dt=Ts)
    T = _sub(full, ["x"], ["x_r"])
    D = _sub(full, ["x"], ["F_d"]) if plant.has_disturbance else None
    label = f"P-PI{' + notch' if notch is not None else ''} (K_p = {K_p:g} V/m) on {plant.name}"
    res = LoopAnalysis(label, L, S, T, D, t_final=t_final,
                       info=dict(loop="position (P-PI)", K_a=K_a, K_t=K_t, H_g=H_g, K_v=K_v, K_i=K_i, K_p=K_p,
                                 Ts=Ts, notch=notch is not None, plant=plant.name))
    loop_metrics(res)
    return res


def _as_discrete(block, Ts, func="p_pi_loop"):
    import control

    if isinstance(block, SampledBlock):
        sys = block.ss()
    elif isinstance(block, NotchCoefficients):
        sys = block.filter().ss()
    elif isinstance(block, control.LTI):
        sys = control.ss(block)
    else:
        raise ArgumentTypeError(f"{func}: notch must be a NotchFilter, the NotchCoefficients of "
                                f"bscomp.control.notch(...) or a discrete python-control LTI system, got "
                                f"{type(block).__name__} {block!r}"[:300])
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise UsageError(f"{func}: notch must be SISO, got {sys.noutputs} outputs x {sys.ninputs} inputs")
    if not sys.dt or abs(sys.dt - Ts) > 1e-15 * max(1.0, Ts):
        raise ParameterError(f"{func}: discrete block has dt = {sys.dt!r}, loop runs at Ts = {Ts!r}")
    return sys


def _drive_plant(func, plant):
    if not isinstance(plant, DrivePlant):
        raise ArgumentTypeError(f"{func}: plant must be a DrivePlant (from rigid_plant, modal_plant, "
                                f"plant_from_system or thesis_modal_plant), got {type(plant).__name__} "
                                f"{plant!r}"[:300],
                                hint="for a model name use plant_from_system(bscomp.systems.get(name))")
    return plant


def _gains(func, **kw):
    """The loop gains of ``kw`` as finite floats (a sign is the user's choice, as in the thesis)."""
    return [real(func, k, v) for k, v in kw.items()]


def _t_final(func, t_final, Ts):
    """``t_final`` of a sampled loop: > 0 and at least two sampling periods (the step response)."""
    t_final = real(func, "t_final", t_final, positive=True, unit="s")
    if t_final < 2 * Ts:
        raise UsageError(f"{func}: t_final = {t_final:g} s is shorter than 2 sampling periods Ts = {Ts:g} s: "
                         "the step response would have fewer than 2 samples; raise t_final or shorten Ts")
    return t_final


def rst_loop(plant, design, K_a: float = 1.0, K_t: float = 1.0, t_final: float = 0.1) -> LoopAnalysis:
    """Pole-placement (RST) loop, Fig 4.19 and Eq (4.22).

    Parameters
    ----------
    plant : DrivePlant or (A, B)
        A DrivePlant is discretised as ``Z{ZOH K_a K_t G_m}`` (amplifier command [V] to table position,
        Sec 4.5, Fig 4.20) and, with ``F_d``, ``Z{ZOH G_d^x}``; a pair of polynomials ``(A, B)`` in z (e.g.
        Table 4.4) is used as given (no disturbance response then).
    design : RSTDesign or RSTController
    K_a, K_t : float
        Amplifier and torque constant (used with a DrivePlant).

    Returns
    -------
    LoopAnalysis
        ``L = B S/(A R)`` (broken at the plant input), ``T = B T_pol/(A R + B S)``, ``D = x/F_d``.
    """
    import control

    f = "rst_loop"
    if isinstance(design, RSTDesign):
        ctrl = design.controller()
    elif isinstance(design, RSTController):
        ctrl = design
    else:
        raise ArgumentTypeError(f"rst_loop: design must be an RSTDesign (from rst_design) or an "
                                f"RSTController, got {type(design).__name__} {design!r}"[:300])
    Ts = ctrl.T_s
    K_a, K_t = _gains(f, K_a=K_a, K_t=K_t)
    t_final = _t_final(f, t_final, Ts)
    if not isinstance(plant, DrivePlant):
        if isinstance(plant, (str, bytes)) or not hasattr(plant, "__len__") or len(plant) != 2:
            raise ArgumentTypeError(f"rst_loop: plant must be a DrivePlant or a pair of polynomials (A, B) "
                                    f"in z, got {type(plant).__name__} {plant!r}"[:300])
        plant = (polynomial(f, "plant A", plant[0], min_degree=1), polynomial(f, "plant B", plant[1]))
    if isinstance(plant, DrivePlant):
        ins = ["tau"] + (["F_d"] if plant.has_disturbance else [])
        P = _sub(plant.sys, ["x"], ins)
        scale = np.r_[K_a * K_t, np.ones(len(ins) - 1)]  # amplifier command [V] -> torque; F_d as is
        P = control.ss(P.A, P.B * scale, P.C, P.D * scale)
        Pz = control.c2d(P, Ts, "zoh")
        Pz = control.ss(Pz.A, Pz.B, Pz.C, Pz.D, Ts, inputs=["u"] + ins[1:], outputs=["x"], name="plant_z")
        pname = plant.name
    else:
        A, B = plant
        Pz = control.ss(control.tf(list(B), list(A), Ts))
        Pz = control.ss(Pz.A, Pz.B, Pz.C, Pz.D, Ts, inputs=["u"], outputs=["x"], name="plant_z")
        pname = "B(z)/A(z) given"
    K = ctrl.ss()
    K = control.ss(K.A, K.B, K.C, K.D, Ts, inputs=["x_r", "x"], outputs=["u"], name="rst")
    # L = (S/R) P, from the plant input around the loop (sign -1 of the feedback removed)
    fb = control.ss(K.A, -K.B[:, 1:2], K.C, -K.D[:, 1:2], Ts)
    L = control.series(_sub(Pz, ["x"], ["u"]), fb)
    one = control.ss([], [], [], [[1.0]], Ts)
    S = control.feedback(one, L)
    ins = ["x_r"] + [n for n in Pz.input_labels if n == "F_d"]
    full = control.interconnect([Pz, K], inplist=ins, outlist=["x"], inputs=ins, outputs=["x"], dt=Ts)
    T = _sub(full, ["x"], ["x_r"])
    D = _sub(full, ["x"], ["F_d"]) if "F_d" in ins else None
    res = LoopAnalysis(f"RST on {pname}", L, S, T, D, t_final=t_final,
                       info=dict(loop="position (RST)", Ts=Ts, R=list(ctrl.R), S=list(ctrl.S), T=list(ctrl.T),
                                 plant=pname))
    loop_metrics(res)
    return res
