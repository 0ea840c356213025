"""A time series against the model: fit % per channel, the residual over time and the windows that carry
it, MATLAB ``resid``'s tests (:mod:`~bscomp.validate.residual_tests`) and the residual's signatures
(:mod:`~bscomp.validate.signatures`). Residuals are measured minus model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bscomp.validate.datasets import TimeData
from bscomp.validate.periodicity import angle_channel, periodic_in_angle
from bscomp.validate.residual_tests import resid
from bscomp.validate.residuals import fit_percent, simulate_at
from bscomp.validate.signatures import channel_signatures, physical_signals, signal_names

__all__ = ["TimeComparison", "compare_time"]


@dataclass
class TimeComparison:
    """A time-series dataset against the model.

    Attributes
    ----------
    source : str
    t : ndarray [s]
    inputs : dict name -> ndarray
    measured, model, residual : dict channel -> ndarray (residual = measured - model, SI)
    units : dict channel -> str
    fit : dict channel -> float
        Fit % (MATLAB ``compare``).
    resid : dict channel -> ResidTest
        Against the first input.
    signals : dict name -> ndarray
        The model's physical signals used for the signatures (``velocity``, ``acceleration``...).
    signatures : dict channel -> dict name -> float
        Correlation of the channel's residual with each signal (see :data:`SIGNATURES`).
    delays : dict channel -> float
        Least-squares delay [s] in :math:`e \\approx -\\tau\\,\\dot{\\hat y}`.
    windows : list of dict
        Equal time windows with their share of the squared (normalised) residual and what the model
        does there (``"velocity reversal"``, ``"acceleration"``, ``"constant velocity"``, ``"rest"``).
    cost : float
    orders : list of AngleOrder
        Residual components periodic in the motor angle (:mod:`~bscomp.validate.periodicity`: a torque
        ripple, an eccentric, a lead error), most significant first; empty when none or no angle.
    """

    source: str
    t: np.ndarray
    inputs: dict
    measured: dict
    model: dict
    residual: dict
    units: dict
    fit: dict
    resid: dict
    signals: dict
    signatures: dict
    windows: list
    cost: float
    conditions: dict = field(default_factory=dict)
    delays: dict = field(default_factory=dict)
    index: int | None = None
    orders: list = field(default_factory=list)

    def user_errors(self) -> dict:
        """``{"frf": [], "time": [{"channel", "fit_percent"}, ...]}``."""
        return {"frf": [], "time": [{"channel": n, "fit_percent": float(v)} for n, v in self.fit.items()]}

    def worst_windows(self, share: float = 0.5) -> list:
        rows = sorted(self.windows, key=lambda w: -w["share"])
        out, acc = [], 0.0
        for w in rows:
            if acc >= share or w["share"] <= 0:
                break
            out.append(w)
            acc += w["share"]
        return out

    def to_dict(self):
        return {"kind": "time", "source": self.source, "conditions": self.conditions, "cost": self.cost,
                "t": self.t.tolist(), "fit_pct": self.fit, "units": self.units,
                "measured": {k: v.tolist() for k, v in self.measured.items()},
                "model": {k: v.tolist() for k, v in self.model.items()},
                "resid": {k: v.to_dict() for k, v in self.resid.items()},
                "signatures": self.signatures, "windows": self.windows,
                "orders": [o.to_dict() for o in self.orders]}



def compare_time(system, data: TimeData, n_windows: int = 20) -> TimeComparison:
    """Simulate ``system`` (built at the dataset's conditions) with the measured inputs and compare.

    The cost is the mean squared residual normalised by each channel's rms (as
    :func:`~bscomp.validate.residuals.time_residuals`); the residual tests are against the first input.
    """
    names = signal_names(system)
    res = simulate_at(system, data, extra=list(names.values()))
    t = data.t
    y_hat = {n: np.asarray(res[n], float) for n in data.outputs}
    e = {n: data.outputs[n] - y_hat[n] for n in data.outputs}
    fit = {n: fit_percent(y_hat[n], data.outputs[n]) for n in data.outputs}
    rms = {n: (float(np.sqrt(np.mean(y ** 2))) or 1.0) for n, y in data.outputs.items()}
    en = {n: e[n] / rms[n] for n in e}
    cst = float(np.mean(np.concatenate([en[n] ** 2 for n in en]))) if en else 0.0
    u0 = next(iter(data.inputs.values()))
    rt = {n: resid(e[n], u0) for n in e}
    sig = physical_signals(res, names, t, u0)
    signatures, delays = {}, {}
    for n in e:
        signatures[n], delays[n] = channel_signatures(e[n], y_hat[n], t, sig)
    angle = angle_channel(data.units) or names.get("phi")
    orders = periodic_in_angle(e, res[angle], t, angle, data.units) if angle else []
    return TimeComparison(source=data.source, t=t, inputs=dict(data.inputs), measured=dict(data.outputs),
                          model=y_hat, residual=e, units=dict(data.units), fit=fit, resid=rt, signals=sig,
                          signatures=signatures, windows=_windows(t, en, sig, n_windows), cost=cst,
                          conditions=dict(data.conditions), delays=delays, orders=orders)


def _windows(t, en, sig, n_windows) -> list:
    """Equal time windows with their share of the squared normalised residual ``en`` and what the model
    does there."""
    edges = np.linspace(t[0], t[-1], n_windows + 1)
    sq = sum(en[n] ** 2 for n in en)
    tot = float(sq.sum())
    windows = []
    for k in range(n_windows):
        sel = (t >= edges[k]) & ((t < edges[k + 1]) if k < n_windows - 1 else (t <= edges[k + 1]))
        if not sel.any():
            continue
        windows.append({"t0": float(edges[k]), "t1": float(edges[k + 1]),
                        "share": float(sq[sel].sum() / tot) if tot > 0 else 0.0, "activity": _activity(sig, sel)})
    return windows


def _activity(sig, sel) -> str:
    """What the model does in the samples ``sel``: velocity reversal, rest, acceleration, constant velocity."""
    if "velocity" not in sig:
        return "-"
    v = sig["velocity"]
    vmax = np.max(np.abs(v)) or 1.0
    a = sig["acceleration"]
    amax = np.max(np.abs(a)) or 1.0
    if np.any(sig["reversal"][sel] > 0):
        return "velocity reversal"
    if np.max(np.abs(v[sel])) < 0.02 * vmax:
        return "rest"
    if np.max(np.abs(a[sel])) > 0.3 * amax:
        return "acceleration"
    return "constant velocity"
