"""Closed-loop analysis of the feed-drive controllers of thesis Chapter 4 (python-control).

Plants (:class:`DrivePlant`, continuous, inputs ``tau`` [N m] and optionally ``F_d`` [N], outputs ``w``
[rad/s] and ``x`` [m]):

* :func:`rigid_plant` -- rigid-body model, Eq (4.2);
* :func:`modal_plant` -- rigid body plus normal modes, Eq (4.3)-(4.7); :func:`thesis_modal_plant` builds it
  from the modal parameters of Table 4.1 or 4.2 (L/C/R positions);
* :func:`plant_from_system` -- any bscomp model, through :func:`bscomp.linearize` (e.g. ``small_drive``).

Loops (each returns a :class:`LoopAnalysis`):

* :func:`velocity_loop` -- analog PI velocity loop (Fig 4.3, Eq 4.10), open loop broken at the
  tachometer feedback: ``L(s) = C(s) K_a K_t G_w(s) H_g``;
* :func:`p_pi_loop` -- digital P position loop around the closed velocity loop, with an optional notch
  (Fig 4.3, 4.14): ``L(z) = G_N(z) K_p Z{ZOH G_v(s) G_x(s)}`` (Eq 4.17), broken at the position error
  (equivalently at the measured position);
* :func:`rst_loop` -- pole-placement controller on ``B(z)/A(z) = Z{ZOH G_e G_m}`` (Fig 4.19-4.20),
  ``L(z) = B S / (A R)`` broken at the plant input.

Sign convention of the disturbance: ``F_d`` acts on the table in ``+x`` (``G_d^r = r_g/(J s + B)``, Eq
4.2). The thesis's "sensitivity" plots of Figs 4.5, 4.8, 4.11, 4.18 and 4.24 show the disturbance response
(``w/F_d`` or ``x/F_d``; its -172 dB peak is in m/N), not ``1/(1 + L)``: a :class:`LoopAnalysis` reports
both (``S_peak_db`` and ``D_peak_db``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bscomp.errors import ParameterError, UnknownNameError

__all__ = [
    "DrivePlant", "rigid_plant", "modal_plant", "thesis_modal_plant", "plant_from_system", "LoopAnalysis",
    "velocity_loop", "p_pi_loop", "rst_loop", "loop_metrics", "margins", "freqresp",
]

_POSITIONS = {"L": 0, "C": 1, "R": 2}


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
    for k, v in dict(J=J, r_g=r_g).items():
        if not v > 0:
            raise ParameterError(f"{k} = {v!r} must be > 0")
    if B < 0:
        raise ParameterError(f"B = {B!r} must be >= 0")
    modes = [tuple(map(float, m)) for m in modes]
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
            raise ParameterError(f"mode {k + 1}: need f_n > 0, zeta >= 0 and R_w > 0, "
                                 f"got {(f_n, zeta, R_w, R_m)}")
        w = 2 * math.pi * f_n
        i = 2 + 2 * k
        A[i, i + 1] = 1.0
        A[i + 1, i], A[i + 1, i + 1] = -w * w, -2 * zeta * w
        p_mot, p_tab = math.sqrt(R_w), R_m / math.sqrt(R_w)
        Bm[i + 1, 0], Bm[i + 1, 1] = p_mot, p_tab
        C[0, i + 1], C[1, i] = p_mot, p_tab
    return _plant_ss(A, Bm, C, np.zeros((2, 2)), ["tau", "F_d"], name)


def thesis_modal_plant(table: str = "4.1", position: str = "C", n_modes: int = 2) -> DrivePlant:
    """Modal plant of Eq (4.5)-(4.7) with the parameters of Table 4.1 (jaw coupling) or 4.2 (bellows).

    J, B, r_g come from ``systems/data/fadal_vmc2216_x.toml`` (``control`` group, Sec 4.2.1).
    """
    from bscomp.systems._params import get_value, load_parameters

    if table not in ("4.1", "4.2"):
        raise UnknownNameError(f"table '{table}': use '4.1' (jaw coupling) or '4.2' (bellows coupling)")
    if position not in _POSITIONS:
        raise UnknownNameError(f"position '{position}': use one of {sorted(_POSITIONS)}")
    p = load_parameters()
    t = "table41" if table == "4.1" else "table42"
    i = _POSITIONS[position]
    zetas = (get_value(p, "damping.zeta_mode1"), get_value(p, "damping.zeta_mode2"))
    modes = []
    ref = p["reference_results"]
    for k in (1, 2)[:n_modes]:
        modes.append((ref[f"{t}_fn{k}"]["value"][i], zetas[k - 1], ref[f"{t}_Rw{k}"]["value"][i],
                      ref[f"{t}_Rm{k}"]["value"][i]))
    J, B, r_g = (get_value(p, f"control.{k}") for k in ("J", "B", "r_g"))
    return modal_plant(J, B, r_g, modes, name=f"Table {table} {position}-position, {n_modes} mode(s)")


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

    from bscomp.linear.linearize import control_labels

    inputs = [tau] + ([F_d] if F_d else [])
    if not isinstance(model, control.StateSpace):
        from bscomp.linear.linearize import linearize

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
# result
@dataclass
class LoopAnalysis:
    """Frequency- and time-domain figures of one loop.

    Attributes
    ----------
    name : str
    L, S, T : control.LTI
        Open loop, sensitivity ``1/(1+L)`` and complementary sensitivity ``L/(1+L)`` (Eq 4.15);
        ``T`` is also the reference-to-output transfer (normalised to unit DC gain for the velocity loop).
    D : control.LTI or None
        Disturbance response (``F_d`` to the controlled output, loop closed).
    metrics : dict
        ``gm_db``, ``pm_deg``, ``f_pc_hz`` (phase crossover), ``f_gc_hz`` (gain crossover),
        ``bandwidth_hz`` (T -3 dB), ``S_peak_db``/``f_S_peak_hz``, ``T_peak_db``/``f_T_peak_hz``,
        ``D_peak_db``/``f_D_peak_hz``, ``rise_time_s`` (10-90 %), ``settling_time_s`` (2 %),
        ``overshoot_pct``, ``dist_peak``, ``dist_settling_time_s``.
    info : dict
        Controller and plant description.
    """

    name: str
    L: Any
    S: Any
    T: Any
    D: Any = None
    metrics: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    t_final: float = 0.1

    def to_dict(self) -> dict:
        return {"name": self.name, "info": self.info, "metrics": self.metrics}

    def to_json(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=2, default=_json_default))
        return path

    def table(self) -> str:
        """Plain-text table of the metrics."""
        rows = [f"{self.name}"]
        for k, v in self.metrics.items():
            rows.append(f"  {k:<22} {v:12.5g}" if isinstance(v, (int, float)) else f"  {k:<22} {v}")
        return "\n".join(rows)

    def step(self, t=None):
        """Unit step response of ``T`` (reference to output): ``(t, y)``."""
        import control

        t = self._time(t)
        r = control.step_response(self.T, T=t)
        return r.time, np.squeeze(r.outputs)

    def disturbance_step(self, t=None):
        """Response to a unit step of ``F_d`` [N]: ``(t, y)`` (y in m or rad/s)."""
        import control

        if self.D is None:
            raise UnknownNameError(f"'{self.name}': the plant has no disturbance input F_d")
        t = self._time(t)
        r = control.step_response(self.D, T=t)
        return r.time, np.squeeze(r.outputs)

    def _time(self, t):
        if t is not None:
            return t
        dt = self.T.dt if self.T.dt else self.t_final / 4000
        return np.arange(0.0, self.t_final + dt / 2, dt)

    def frequencies(self, n: int = 4000) -> np.ndarray:
        """Frequency grid [rad/s]: 0.1 Hz to the Nyquist frequency (discrete) or 10 kHz (continuous)."""
        top = math.pi / self.L.dt * (1 - 1e-9) if self.L.dt else 2 * math.pi * 1e4
        return np.logspace(math.log10(2 * math.pi * 0.1), math.log10(top), n)

    def plot(self, path=None):
        """Bode of L, |S|, |T|, |D| and the step responses (matplotlib, imported lazily)."""
        from bscomp.plotting.control import plot_loop

        return plot_loop(self, path)


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


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


def freqresp(sys, w) -> np.ndarray:
    """Complex SISO response of a state-space system at ``w`` [rad/s] (``z = exp(j w dt)`` if discrete),
    one batched solve instead of python-control's per-frequency loop."""
    import control

    sys = control.ss(sys)
    w = np.asarray(w, float)
    s = np.exp(1j * w * sys.dt) if sys.dt else 1j * w
    n = sys.A.shape[0]
    D = complex(sys.D[0, 0])
    if n == 0:
        return np.full(w.shape, D)
    M = s[:, None, None] * np.eye(n) - sys.A[None, :, :]
    X = np.linalg.solve(M, np.broadcast_to(sys.B[:, :1], (w.size, n, 1)))
    return (sys.C[:1, :] @ X)[:, 0, 0] + D


def _mag(sys, w):
    return np.abs(freqresp(sys, w))


def margins(L, w) -> tuple[float, float, float, float]:
    """Gain margin [dB], phase margin [deg] and their crossover frequencies [rad/s] from a dense grid.

    Crossings are located by linear interpolation in ``log w``; when there are several, the margin
    closest to instability (smallest magnitude) is returned, as python-control's ``stability_margins``.
    """
    H = freqresp(L, w)
    lw = np.log10(w)
    mag_db = 20 * np.log10(np.abs(H))
    ph = np.degrees(np.unwrap(np.angle(H)))
    gm, wpc = float("inf"), float("nan")
    pm, wgc = float("inf"), float("nan")
    k = np.nonzero(np.diff(np.sign(mag_db)) != 0)[0]
    for i in k:
        f = mag_db[i] / (mag_db[i] - mag_db[i + 1])
        p = ph[i] + f * (ph[i + 1] - ph[i])
        m = (p + 180.0) % 360.0
        m = m - 360.0 if m > 180.0 else m
        if abs(m) < abs(pm):
            pm, wgc = m, 10 ** (lw[i] + f * (lw[i + 1] - lw[i]))
    shifted = (ph + 180.0) / 360.0  # integer crossings = phase -180 + k 360
    k = np.nonzero(np.floor(shifted[:-1]) != np.floor(shifted[1:]))[0]
    for i in k:
        target = np.floor(max(shifted[i], shifted[i + 1]))
        f = (target - shifted[i]) / (shifted[i + 1] - shifted[i])
        g = -(mag_db[i] + f * (mag_db[i + 1] - mag_db[i]))
        if abs(g) < abs(gm):
            gm, wpc = g, 10 ** (lw[i] + f * (lw[i + 1] - lw[i]))
    return gm, pm, wpc, wgc


def _peak(sys, w):
    m = _mag(sys, w)
    k = int(np.argmax(m))
    return 20 * math.log10(m[k]), w[k] / (2 * math.pi)


def _bandwidth(T, w):
    """First frequency [Hz] where |T| falls 3 dB below its low-frequency value (log interpolation)."""
    m = 20 * np.log10(_mag(T, w))
    ref = m[0] - 3.0103
    below = np.nonzero(m < ref)[0]
    if below.size == 0:
        return float("nan")
    k = below[0]
    if k == 0:
        return w[0] / (2 * math.pi)
    lw = np.interp(ref, [m[k], m[k - 1]], [math.log10(w[k]), math.log10(w[k - 1])])
    return 10**lw / (2 * math.pi)


def _settling(t, y, band=0.02):
    """Last time |y - y_final| leaves ``band * max|y - y(0)|`` (works for responses returning to 0)."""
    yf = y[-1]
    scale = max(abs(yf - y[0]), np.max(np.abs(y - y[0])))
    out = np.nonzero(np.abs(y - yf) > band * scale)[0]
    return float(t[out[-1] + 1]) if out.size and out[-1] + 1 < t.size else (float(t[-1]) if out.size else 0.0)


def loop_metrics(res: LoopAnalysis) -> dict:
    """Fill ``res.metrics`` (see :class:`LoopAnalysis`) and return it."""
    import control

    w = res.frequencies()
    gm, pm, wpc, wgc = margins(res.L, w)
    m = {
        "gm_db": float(gm),
        "pm_deg": float(pm),
        "f_pc_hz": float(wpc) / (2 * math.pi),
        "f_gc_hz": float(wgc) / (2 * math.pi),
        "bandwidth_hz": _bandwidth(res.T, w),
    }
    m["S_peak_db"], m["f_S_peak_hz"] = _peak(res.S, w)
    m["T_peak_db"], m["f_T_peak_hz"] = _peak(res.T, w)
    t, y = res.step()
    info = control.step_info(y, t, yfinal=y[-1])
    m["rise_time_s"] = float(info["RiseTime"])
    m["settling_time_s"] = float(info["SettlingTime"])
    m["overshoot_pct"] = float(info["Overshoot"])
    if res.D is not None:
        m["D_peak_db"], m["f_D_peak_hz"] = _peak(res.D, w)
        td, yd = res.disturbance_step()
        k = int(np.argmax(np.abs(yd)))
        m["dist_peak"] = float(yd[k])
        m["dist_settling_time_s"] = _settling(td, yd)
    res.metrics = m
    return m


# ---------------------------------------------------------------------------------------------------
# loops
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

    if not (Ts > 0 and K_p > 0):
        raise ParameterError(f"need Ts > 0 and K_p > 0, got Ts = {Ts!r}, K_p = {K_p!r}")
    cl = _velocity_closed(plant, K_a, K_t, H_g, K_v, K_i)
    outs = ["x"]
    ins = ["u_v"] + (["F_d"] if plant.has_disturbance else [])
    Pz = control.c2d(_sub(cl, outs, ins), Ts, "zoh")
    Pz = control.ss(Pz.A, Pz.B, Pz.C, Pz.D, Ts, inputs=ins, outputs=["x"], name="plant_z")
    K = _gain(K_p, "e", "u_p", Ts)
    if notch is not None:
        N = _as_discrete(notch, Ts)
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


def _as_discrete(block, Ts):
    import control

    if hasattr(block, "ss") and callable(block.ss):
        sys = block.ss()
    elif hasattr(block, "filter"):
        sys = block.filter().ss()
    else:
        sys = control.ss(block)
    if not sys.dt or abs(sys.dt - Ts) > 1e-15 * max(1.0, Ts):
        raise ParameterError(f"discrete block has dt = {sys.dt!r}, loop runs at Ts = {Ts!r}")
    return sys


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

    ctrl = design.controller() if hasattr(design, "controller") else design
    Ts = ctrl.T_s
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
