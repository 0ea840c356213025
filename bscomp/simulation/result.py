"""What every simulation method returns (:class:`SimulationResult`) and raises (:class:`SimulationError`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import SolverError, UnknownNameError
from bscomp.files import atomic_path
from bscomp.plotting.base import time_plot  # matplotlib only when plotting

__all__ = ["SimulationResult", "SimulationError"]


class SimulationError(SolverError):
    """The integrator failed; the message names the time window, the variable and a hint."""


@dataclass
class SimulationResult:
    """Time histories of a simulation.

    Attributes
    ----------
    t : ndarray (nt,)
    x, xd : ndarray (nt, nx)
        States and their derivatives.
    z : ndarray (nt, nz)
    u : ndarray (nt, nu)
        Inputs applied on the interval ending at each time (at t0: the first interval's).
    outputs : dict name -> ndarray (nt,)
    stats : dict
        What the method reports: ``wall_s``, ``real_time_factor``, ``method`` and its own counters.
    """

    t: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    z: np.ndarray
    u: np.ndarray
    x_names: list
    z_names: list
    u_names: list
    outputs: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    def __getitem__(self, name):
        if name in self.outputs:
            return self.outputs[name]
        if name in self.x_names:
            return self.x[:, self.x_names.index(name)]
        if name in self.z_names:
            return self.z[:, self.z_names.index(name)]
        if name in self.u_names:
            return self.u[:, self.u_names.index(name)]
        raise UnknownNameError(f"no signal '{name}' in this result; outputs: {list(self.outputs)}, states: "
                               f"{self.x_names[:10]}..., inputs: {self.u_names}")

    def to_csv(self, path, names=None):
        """Write t and the named signals (default: outputs, else states) as CSV with a header row."""
        names = list(names or (list(self.outputs) or self.x_names))
        data = np.column_stack([self.t] + [self[n] for n in names])
        header = ",".join(["t"] + names)
        if hasattr(path, "write"):
            np.savetxt(path, data, delimiter=",", header=header, comments="")
            return path
        with atomic_path(path) as tmp:
            np.savetxt(tmp, data, delimiter=",", header=header, comments="")
        return path

    def plot(self, names=None, path=None, title=""):
        """Plot the named signals against time (one axis each)."""

        names = list(names or (list(self.outputs) or self.x_names[:4]))
        return time_plot(self.t, [self[n] for n in names], names, title=title, path=path)
