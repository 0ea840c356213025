"""The result of a closed-loop analysis and its figures of merit (thesis Ch 4, python-control).

* :class:`LoopAnalysis` -- open loop ``L``, sensitivity ``S = 1/(1 + L)``, complementary sensitivity
  ``T = L/(1 + L)`` (Eq 4.15) and disturbance response ``D`` of one loop, with its metrics;
* :func:`loop_metrics` -- margins, bandwidth, peaks, step-response figures;
* :func:`freqresp`, :func:`margins` -- batched frequency response and margins from a dense grid;
* :class:`LoopCurves` -- the numbers a figure shows (:meth:`LoopAnalysis.curves`), the only thing
  :mod:`bscomp.plotting.control` receives;
* :func:`plot_bode_comparison`, :func:`plot_step_comparison`, :func:`plot_sensitivity_comparison`,
  :func:`plot_disturbance_comparison` -- several loops on one figure: the curves of each loop computed
  here, then drawn by :mod:`bscomp.plotting.control` (matplotlib imported only when drawing).

The loops themselves (:func:`~bscomp.control.closed_loop.velocity_loop`, ``p_pi_loop``, ``rst_loop``)
are built in :mod:`bscomp.control.closed_loop`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bscomp.control._checks import lti
from bscomp.errors import ArgumentTypeError, ParameterError, SingularSystemError, UnknownNameError, UsageError
from bscomp.files import atomic_write
from bscomp.plotting.control import (
    bode_comparison_plot,
    disturbance_comparison_plot,
    loop_plot,
    sensitivity_comparison_plot,
    step_comparison_plot,
)

__all__ = [
    "LoopAnalysis", "LoopCurves", "loop_metrics", "margins", "freqresp", "plot_bode_comparison",
    "plot_step_comparison", "plot_sensitivity_comparison", "plot_disturbance_comparison", "CURVE_PARTS",
]

CURVE_PARTS = ("L", "S", "T", "D", "step", "disturbance_step")
"""What :meth:`LoopAnalysis.curves` can compute: the four responses on the frequency grid, the step and
the disturbance-step responses."""


@dataclass(frozen=True)
class LoopCurves:
    """Frequency and step responses of one loop, as numbers (what the loop figures draw).

    Attributes
    ----------
    name : str
    metrics : dict
        The loop's :attr:`LoopAnalysis.metrics` (margins and settling times go into the legends).
    f_hz : numpy.ndarray
        Frequency grid [Hz].
    L, S, T : numpy.ndarray
        Complex responses of the open loop, ``1/(1 + L)`` and ``L/(1 + L)`` on ``f_hz``.
    D : numpy.ndarray or None
        Complex disturbance response (``F_d`` to the controlled output); ``None`` without ``F_d``.
    t, y : numpy.ndarray
        Unit step response of ``T`` (time [s], output per unit reference).
    t_d, y_d : numpy.ndarray or None
        Response to a unit step of ``F_d`` [N]; ``None`` without ``F_d``.

    A field is ``None`` when :meth:`LoopAnalysis.curves` was not asked for it (``parts``).
    """

    name: str
    metrics: dict
    f_hz: np.ndarray | None
    L: np.ndarray | None
    S: np.ndarray | None
    T: np.ndarray | None
    D: np.ndarray | None
    t: np.ndarray | None
    y: np.ndarray | None
    t_d: np.ndarray | None = None
    y_d: np.ndarray | None = None


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
    t_final : float
        End of the step responses [s].
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
        text = json.dumps(self.to_dict(), indent=2, default=_json_default)
        with atomic_write(path, what="LoopAnalysis.to_json: path", suffixes=(".json",)) as fh:
            fh.write(text)
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
        if not (isinstance(self.t_final, (int, float, np.integer, np.floating)) and 0 < self.t_final < math.inf):
            raise UsageError(f"LoopAnalysis '{self.name}': t_final = {self.t_final!r} must be a finite time > 0 [s]")
        dt = self.T.dt if self.T.dt else self.t_final / 4000
        return np.arange(0.0, self.t_final + dt / 2, dt)

    def frequencies(self, n: int = 4000) -> np.ndarray:
        """Frequency grid [rad/s]: 0.1 Hz to the Nyquist frequency (discrete) or 10 kHz (continuous)."""
        top = math.pi / self.L.dt * (1 - 1e-9) if self.L.dt else 2 * math.pi * 1e4
        return np.logspace(math.log10(2 * math.pi * 0.1), math.log10(top), n)

    def curves(self, n: int = 1500, parts=CURVE_PARTS) -> LoopCurves:
        """The responses the figures show, as numbers.

        Parameters
        ----------
        n : int
            Number of frequencies of :meth:`frequencies`.
        parts : sequence of str
            What to compute, among :data:`CURVE_PARTS`: ``"L"``, ``"S"``, ``"T"``, ``"D"`` (complex
            responses on the grid), ``"step"``, ``"disturbance_step"``; the fields of the others are ``None``.
        """
        unknown = sorted(set(parts) - set(CURVE_PARTS))
        if unknown:
            raise UnknownNameError(f"curve parts {unknown}: use some of {list(CURVE_PARTS)}")
        w = self.frequencies(n) if set(parts) & set("LSTD") else None
        H = [freqresp(sys, w) if k in parts and sys is not None else None
             for k, sys in zip("LSTD", (self.L, self.S, self.T, self.D))]
        t, y = self.step() if "step" in parts else (None, None)
        want_d = "disturbance_step" in parts and self.D is not None
        t_d, y_d = self.disturbance_step() if want_d else (None, None)
        f_hz = None if w is None else w / (2 * math.pi)
        return LoopCurves(self.name, dict(self.metrics), f_hz, *H, t, y, t_d, y_d)

    def plot(self, path=None):
        """Bode of L, |S|, |T|, the step responses (:func:`bscomp.plotting.control.loop_plot`); returns the
        figure, saved to ``path`` if given."""
        return loop_plot(self.curves(), path)


def plot_bode_comparison(loops, path=None, title="Open loop L"):
    """Bode diagram of the open loops ``L`` with the margins in the legend (Fig 4.6, 4.9, 4.16, 4.22)."""
    return bode_comparison_plot([lp.curves(parts=("L",)) for lp in loops], path, title)


def plot_step_comparison(loops, path=None, title="Unit step response"):
    """Reference step responses (Fig 4.4, 4.7, 4.10, 4.17, 4.23)."""
    return step_comparison_plot([lp.curves(parts=("step",)) for lp in loops], path, title)


def plot_sensitivity_comparison(loops, path=None, title="Sensitivity functions"):
    """``|D|`` (the thesis's "sensitivity": disturbance to output), ``|S|``, ``|T|`` (Fig 4.5, 4.8, 4.18)."""
    return sensitivity_comparison_plot([lp.curves(parts=("D", "S", "T")) for lp in loops], path, title)


def plot_disturbance_comparison(loops, path=None, title="Unit step disturbance force"):
    """Responses to a unit step of ``F_d`` [N] (Fig 4.25); loops without ``F_d`` are skipped."""
    return disturbance_comparison_plot([lp.curves(parts=("disturbance_step",)) for lp in loops], path, title)


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def freqresp(sys, w) -> np.ndarray:
    """Complex SISO response of a state-space system at ``w`` [rad/s] (``z = exp(j w dt)`` if discrete),
    one batched solve instead of python-control's per-frequency loop.

    Notes
    -----
    .. math:: H(s) = C (sI - A)^{-1} B + D, \\qquad s = j\\omega \\;\\text{or}\\; z = e^{j\\omega T_s}.
    """
    import control

    sys = control.ss(lti("freqresp", "sys", sys, siso=True))
    w = _frequencies("freqresp", w, positive=False)
    s = np.exp(1j * w * sys.dt) if sys.dt else 1j * w
    n = sys.A.shape[0]
    D = complex(sys.D[0, 0])
    if n == 0:
        return np.full(w.shape, D)
    M = s[:, None, None] * np.eye(n) - sys.A[None, :, :]
    try:
        X = np.linalg.solve(M, np.broadcast_to(sys.B[:, :1], (w.size, n, 1)))
    except np.linalg.LinAlgError:
        raise SingularSystemError("freqresp: the system has a pole on the frequency grid (e.g. an integrator "
                                  "at w = 0); evaluate at w > 0 off its poles") from None
    return (sys.C[:1, :] @ X)[:, 0, 0] + D


def _frequencies(func, w, positive):
    """``w`` [rad/s] as a 1-D finite float array (of >= 2 values > 0 for :func:`margins`)."""
    if isinstance(w, (str, bytes)) or w is None:
        raise ArgumentTypeError(f"{func}: w must be an array of frequencies [rad/s], got {type(w).__name__} {w!r}")
    try:
        arr = np.asarray(w, dtype=float)
    except (TypeError, ValueError):
        raise ArgumentTypeError(f"{func}: w must be an array of frequencies [rad/s], got "
                                f"{type(w).__name__} {w!r}"[:300]) from None
    if arr.ndim != 1 or not np.all(np.isfinite(arr)):
        raise ParameterError(f"{func}: w must be a 1-D array of finite frequencies [rad/s], got shape "
                             f"{arr.shape}" + ("" if arr.ndim != 1 else " with NaN/inf"))
    if positive and (arr.size < 2 or not np.all(arr > 0)):
        raise ParameterError(f"{func}: w needs at least 2 frequencies > 0 [rad/s] (a log grid, e.g. "
                             f"numpy.logspace(0, 4, 2000)), got {arr.tolist()}"[:300])
    return arr


def _mag(sys, w):
    return np.abs(freqresp(sys, w))


def margins(L, w) -> tuple[float, float, float, float]:
    """Gain margin [dB], phase margin [deg] and their crossover frequencies [rad/s] from a dense grid.

    Crossings are located by linear interpolation in ``log w``; when there are several, the margin
    closest to instability (smallest magnitude) is returned, as python-control's ``stability_margins``.
    """
    lti("margins", "L", L, siso=True)
    w = _frequencies("margins", w, positive=True)
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
