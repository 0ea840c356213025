"""What an optimal-control solve returns (:class:`OcpResult`) and how it fails (:class:`OcpError`).

An :class:`OcpResult` holds the optimal trajectory on the transcription's grid in the model's own names
(states at the interval boundaries, piecewise-constant inputs per interval, bounded outputs) and can
re-run its input through :func:`bscomp.simulation.simulate` on the same or another model, the check
that the transcription told the truth (:meth:`OcpResult.resimulate`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from bscomp.errors import SolverError, UnknownNameError
from bscomp.kernel.signal_meta import declared_units, unit_suffix
from bscomp.model import as_dae
from bscomp.plotting.base import time_plot  # plotting (matplotlib) only when a figure is asked for
from bscomp.simulation.dispatch import simulate

__all__ = ["OcpResult", "OcpError", "active_fraction", "convergence_error"]


class OcpError(SolverError):
    """Ipopt did not converge; the message gives its status, the constraint violated most (name, time,
    amount), the bounds at their limits (name, bound, times) and a hint. ``infeasibility`` holds the same
    as a dict (``{"worst": ..., "bounds": [...]}``; empty for a problem refused before solving)."""

    infeasibility: dict = {}


def active_fraction(v, lo, hi) -> float:
    """Fraction of the values ``v`` within 1e-4 (relative to the larger finite bound) of ``lo`` or ``hi``."""
    v = np.asarray(v, float)
    span = max(abs(lo) if np.isfinite(lo) else 0, abs(hi) if np.isfinite(hi) else 0, 1e-300)
    act = np.zeros(len(v), bool)
    if np.isfinite(lo):
        act |= v <= lo + 1e-4 * span
    if np.isfinite(hi):
        act |= v >= hi - 1e-4 * span
    return float(np.mean(act))


def convergence_error(model_name: str, stats: dict, violation: float, residual: dict | None = None,
                      limits: dict | None = None, where: str = "", info: dict | None = None,
                      units=None) -> OcpError:
    """The :class:`OcpError` of a failed Ipopt run, with its status, the largest scaled constraint
    violation, the constraint it is on and the bounds at their limits (``where``, from
    :func:`bscomp.optimal.infeasibility.describe`) and, for residual-vibration limits, the bound reached at
    the last iterate. ``info`` (the same as a dict) becomes the error's ``infeasibility`` attribute.

    Parameters
    ----------
    model_name : str
    stats : dict
        Ipopt's statistics (``return_status``, ``iter_count``).
    violation : float
        Largest scaled constraint violation at the last iterate.
    residual, limits : dict, optional
        Residual-vibration bound at the last iterate (``None`` where it could not be evaluated) and its
        limit, by output name.
    where : str, optional
        The largest infeasibility in the model's names, units and times, and the bounds at their limits.
    info : dict, optional
        ``{"worst": {...}, "bounds": [...]}`` (see :func:`~bscomp.optimal.infeasibility.describe`).
    units : callable, optional
        ``units(name) -> str``, the unit of an output (:func:`bscomp.kernel.signal_meta.unit_of`).
    """
    vib = ""
    if residual:
        def unit(n):
            return unit_suffix(units(n) if units is not None else "")

        parts = [f"'{n}' {v:.3g}{unit(n)} (limit {limits[n]:.3g}{unit(n)})" if v is not None
                 else f"'{n}' ? (limit {limits[n]:.3g}{unit(n)})" for n, v in residual.items()]
        vib = (" Residual-vibration bound at the last iterate: " + ", ".join(parts) + "; a limit below what "
               "the input grid can reach is infeasible: raise N (finer torque shaping before arrival) or the "
               "limit, or add time (fixed-T problems).")
    err = OcpError(
        f"Ipopt did not converge on '{model_name}' (status: {stats.get('return_status')}, iterations "
        f"{stats.get('iter_count')}, largest scaled constraint violation {violation:.3g})."
        f"{' ' + where if where else ''}"
        f"{vib} Hints: check that the final state is reachable within the bounds (a bound held on most of the "
        "horizon is the one to loosen, or give more time), give a better T_guess or warm start, or give scale= "
        "for signals of very different magnitudes")
    err.infeasibility = dict(info or {})
    return err


@dataclass
class OcpResult:
    """Solution of an :class:`~bscomp.optimal.Ocp`.

    Attributes
    ----------
    T : float
        Horizon [s].
    t : ndarray (N+1,)
        Interval boundaries.
    x : ndarray (N+1, nx)
    u : ndarray (N, nu)
        Piecewise-constant inputs on each interval.
    outputs : dict name -> ndarray (N+1,)
    active : dict name -> fraction of points where the bound is active (within 1e-4 of it); rate limits as
        ``"rate:<name>"`` (fraction of intervals at the limit)
    residual : dict name -> certified residual-vibration amplitude after arrival (unit of the output), for
        the outputs given to :meth:`Ocp.limit_residual_vibration` (see there)
    """

    T: float
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    outputs: dict
    x_names: list
    u_names: list
    active: dict
    stats: dict = field(default_factory=dict)
    dae: Any = None
    p: Any = None
    xd: Any = None
    z: Any = None
    residual: dict = field(default_factory=dict)

    def __getitem__(self, name):
        if name in self.outputs:
            return self.outputs[name]
        if name in self.x_names:
            return self.x[:, self.x_names.index(name)]
        if name in self.u_names:
            return self.u[:, self.u_names.index(name)]
        if self.dae is not None and self.xd is not None and name in self.dae.observables:
            # any other observable, from the solution at the grid points (input of the interval ending there)
            n = len(self.t)
            uk = np.vstack([self.u[:1], self.u])
            y = self.dae.output_function([name]).map(n)(self.xd.T, self.x.T, self.z.T, uk.T,
                                                        np.tile(np.asarray(self.p)[:, None], (1, n)))
            self.outputs[name] = np.asarray(y).ravel()
            return self.outputs[name]
        raise UnknownNameError(f"no signal '{name}' in this OCP result")

    def input_function(self, name) -> Callable:
        """The optimal piecewise-constant input as a function of time (for :func:`simulate`)."""
        u = self[name]
        t = self.t

        def f(tt):
            k = min(max(int(np.searchsorted(t, tt, side="right") - 1), 0), len(u) - 1)
            return u[k]
        return f

    def resimulate(self, model=None, outputs=None, n_per_interval=10, names: dict | None = None, **kw):
        """Run the optimal input through :func:`bscomp.simulation.simulate` on the same model or another one.

        Parameters
        ----------
        model : optional
            Default: the model the OCP was solved on. Anything :func:`bscomp.model.as_dae` takes (a name,
            ``.py`` path, build function, System, Dae or ModelSpec), e.g. the full model the OCP's reduced
            model came from.
        outputs : list of str, optional
            Signals to record and compare (default: this result's outputs); states are recorded by naming
            them here too.
        n_per_interval : int
            Output points per OCP interval.
        names : dict, optional
            This result's names -> the other model's (e.g. ``{"plant.motor_tau": "motor.tau",
            "plant.table_s": "table.s"}`` for a reduced model in a SecondOrderBlock). Inputs not in the
            other model must be mapped or be zero, else :class:`OcpError`.
        **kw
            Further keywords of ``simulate`` (e.g. ``method="lti"`` for a linear model).

        Returns
        -------
        (SimulationResult, dict)
            The simulation (the other model's names) and the deviation per name (this result's names),
            ``max_t |sim(t) - ocp(t)| / max_t |ocp(t)|``, the OCP values interpolated linearly between its
            grid points.
        """
        names = dict(names or {})
        model = as_dae(model) if model is not None else self.dae
        outputs = list(outputs or self.outputs)
        tt = np.linspace(self.t[0], self.t[-1], n_per_interval * (len(self.t) - 1) + 1)
        inputs = {}
        for n in self.u_names:
            m = names.get(n, n)
            if m in model.u_names:
                inputs[m] = self.input_function(n)
            elif np.any(self[n] != 0.0):
                raise OcpError(f"resimulate: input '{n}' of the OCP is not an input of '{model.name}' "
                               f"({model.u_names}); map it with names={{'{n}': ...}}")
        x0 = {names.get(n, n): v for n, v in zip(self.x_names, self.x[0]) if names.get(n, n) in model.x_names}
        r = simulate(model, tt, inputs=inputs, x0=x0,
                     outputs=[names.get(n, n) for n in outputs if names.get(n, n) not in model.x_names], **kw)
        dev = {}
        for n in outputs:
            if n in self.outputs or n in self.x_names or (self.xd is not None and n in self.dae.observables):
                ref = np.interp(tt, self.t, self[n])
                dev[n] = float(np.max(np.abs(r[names.get(n, n)] - ref)) / max(np.max(np.abs(ref)), 1e-300))
        return r, dev

    def plot(self, names=None, path=None, title="optimal control"):
        """Time plot of the named signals (default: outputs and inputs); inputs drawn as staircases."""

        names = list(names or (list(self.outputs) + self.u_names))
        sig = []
        for n in names:
            v = self[n]
            sig.append(np.r_[v, v[-1]] if len(v) == len(self.t) - 1 else v)
        return time_plot(self.t, sig, names, title=title, path=path, units=declared_units(self.dae, names))
