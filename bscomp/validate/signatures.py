"""Residual signatures: the correlation of a time-series residual with the model's own physical signals.

A missing effect leaves a trace in the residual :math:`e = y - \\hat y` that looks like one of the
signals of the simulated drive (thesis Sec 3.5.2.3-3.5.2.4 names the suspects): Coulomb friction
follows the sign of the table velocity, backlash the velocity reversals, a missing mass or compliance
the acceleration or the screw stretch, a delay the output's rate. :data:`SIGNATURES` names each signal;
:data:`EVIDENCE` the other numbers a comparison reports for the diagnosis.
"""

from __future__ import annotations

import numpy as np

from bscomp.components import IdealLeadScrew, Inertia, Mass

__all__ = ["SIGNATURES", "EVIDENCE", "signal_names", "physical_signals", "channel_signatures"]

#: names of :attr:`Comparison.signatures` and what each correlates the residual with
SIGNATURES = {
    "velocity": "table velocity v (viscous friction, velocity-dependent effects)",
    "sign_velocity": "sign(v) (Coulomb/Stribeck friction)",
    "reversal": "|residual| against an indicator of velocity reversals (backlash, stick-slip)",
    "acceleration": "table acceleration a (missing mass or compliance)",
    "screw_stretch": "axial deflection between nut and table (missing compliance in the axial path)",
    "position": "table position s (position-dependent stiffness, guideway)",
    "input": "the excitation at lag 0 (gain error)",
    "output_rate": "the model output's rate dy/dt (time delay, phase lag)",
}

#: names of :attr:`Comparison.evidence`: numbers that are not correlations
EVIDENCE = {
    "time_delay_s": "least-squares delay tau [s] in e = -tau dy/dt (time series)",
    "frf_phase_delay_s": "delay [s] fitted to the FRF phase error's slope",
    "frf_phase_delay_r2": "coefficient of determination of that linear phase fit",
    "frf_max_freq_error_pct": "largest |frequency error| [%] of paired resonances",
    "frf_unmatched_measured": "number of measured resonances with no model counterpart",
    "frf_unmatched_model": "number of model modes not seen in the measurement",
}




def signal_names(system) -> dict:
    """Observables of the model used for signatures: the heaviest mass (the table), the lead screw and the
    largest rotational inertia (the motor's rotor: its angle for :mod:`~bscomp.validate.periodicity`).

    Returns ``{"s", "v", "a": "<table>.s|v|a", "nut": "<lead screw>.flange_b.s", "phi": "<rotor>.phi"}`` (each
    where the model has the part).
    """
    masses, leads, inertias = [], [], []
    for name, comp in system.leaves():
        if isinstance(comp, Mass):
            masses.append((float(np.max(comp.m)), name))
        elif isinstance(comp, IdealLeadScrew):
            leads.append(name)
        elif isinstance(comp, Inertia):
            inertias.append((float(np.max(comp.J)), name))
    names = {"phi": f"{max(inertias)[1]}.phi"} if inertias else {}
    if masses:
        table = max(masses)[1]
        names.update({"s": f"{table}.s", "v": f"{table}.v", "a": f"{table}.a"})
        if leads:
            names["nut"] = f"{leads[0]}.flange_b.s"
    return names


def physical_signals(res, names: dict, t, u0) -> dict:
    """The model's signals of :data:`SIGNATURES` (all but ``output_rate``, which is per channel) from a
    simulation ``res`` that recorded the observables :func:`signal_names` gave, and the input ``u0``."""
    sig = {}
    if "v" in names and names["v"] in res.outputs:
        v = np.asarray(res[names["v"]], float)
        vmax = np.max(np.abs(v)) if v.size else 0.0
        sig["velocity"] = v
        sig["sign_velocity"] = np.sign(np.where(np.abs(v) < 1e-3 * vmax, 0.0, v))
        sig["reversal"] = _reversal_indicator(t, v)
        sig["acceleration"] = np.asarray(res[names["a"]], float)
        sig["position"] = np.asarray(res[names["s"]], float)
        if "nut" in names and names["nut"] in res.outputs:
            sig["screw_stretch"] = np.asarray(res[names["nut"]], float) - sig["position"]
    sig["input"] = u0
    return sig


def channel_signatures(e, y_hat, t, signals: dict) -> tuple[dict, float]:
    """``({signal: correlation}, delay)`` of one channel's residual ``e``.

    The correlations are with each of ``signals`` (``|e|`` against the reversal indicator) and with the
    model output's rate :math:`\\dot{\\hat y}`; the delay [s] is the least-squares :math:`\\tau` in
    :math:`e \\approx -\\tau\\,\\dot{\\hat y}` (a first-order Taylor expansion of a delayed output).
    """
    d = {k: _corr(np.abs(e), x) if k == "reversal" else _corr(e, x) for k, x in signals.items()}
    ydot = np.gradient(y_hat, t)
    d["output_rate"] = _corr(e, ydot)
    dd = float(np.dot(ydot, ydot))
    return d, (float(-np.dot(e, ydot) / dd) if dd > 0 else 0.0)


def _corr(a, b):
    a = np.asarray(a, float) - np.mean(a)
    b = np.asarray(b, float) - np.mean(b)
    den = np.linalg.norm(a) * np.linalg.norm(b)
    return float(np.dot(a, b) / den) if den > 0 else 0.0


def _reversal_indicator(t, v):
    """1 near velocity sign changes (within the time |v| stays under 10 % of its peak), else 0."""
    vmax = np.max(np.abs(v)) if v.size else 0.0
    ind = np.zeros(v.size)
    if vmax == 0:
        return ind
    s = np.sign(np.where(np.abs(v) < 1e-6 * vmax, 0.0, v))
    nz = np.flatnonzero(s)
    if nz.size < 2:
        return ind
    flips = nz[1:][s[nz[1:]] != s[nz[:-1]]]
    slow = np.abs(v) < 0.1 * vmax
    for k in flips:
        lo = k
        while lo > 0 and slow[lo - 1]:
            lo -= 1
        hi = k
        while hi < v.size - 1 and slow[hi + 1]:
            hi += 1
        ind[lo:hi + 1] = 1.0
    return ind

