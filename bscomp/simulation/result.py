"""What every simulation method returns (:class:`SimulationResult`) and raises (:class:`SimulationError`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bscomp.errors import ArgumentTypeError, SolverError, UnknownNameError, check_names
from bscomp.files import atomic_path, check_path_type
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
    units : dict name -> str
        The declared unit of each output and input, for people to read (``m/s^2``; absent: none declared).
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
    units: dict = field(default_factory=dict)

    def __getitem__(self, name):
        if not isinstance(name, str):
            raise ArgumentTypeError(
                f"a SimulationResult is indexed by one signal name (r['table.s']), got {type(name).__name__} "
                f"{name!r}"[:200] + "; for a time window index the arrays instead: "
                "w = (r.t >= t0) & (r.t <= t1); r['table.s'][w], r.t[w]")
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

    def _names(self, names, what, default, unique=True):
        """``names`` as a list of signal names: one str is one name; ``None`` or empty gives ``default``;
        ``unique``: refuse a name listed twice (a CSV column must be unambiguous)."""
        names = check_names(what, names, unique=unique) or list(default)
        for n in names:
            self[n]                     # an unknown name raises here, before anything is written
        return names

    def to_csv(self, path, names=None):
        """Write t and the named signals (default: outputs, else states) as CSV with a header row.

        ``path``: a file name ending in ``.csv`` (written through a temporary file renamed into place) or an
        open text file; ``names``: one signal name or a list of them.
        """
        if not hasattr(path, "write"):
            check_path_type(path, "SimulationResult.to_csv: path")
        names = self._names(names, "SimulationResult.to_csv: names", list(self.outputs) or self.x_names)
        data = np.column_stack([self.t] + [self[n] for n in names])
        header = ",".join(["t"] + names)
        if hasattr(path, "write"):
            np.savetxt(path, data, delimiter=",", header=header, comments="")
            return path
        with atomic_path(path, "SimulationResult.to_csv: path", (".csv",)) as tmp:
            np.savetxt(tmp, data, delimiter=",", header=header, comments="")
        return path

    def plot(self, names=None, path=None, title=""):
        """Plot the named signals (one name or a list; default: outputs, else 4 states) against time, one axis
        each; saved to ``path`` (``.png``, ``.pdf``, ``.svg``...) if given. Returns the figure."""
        if path is not None:
            check_path_type(path, "SimulationResult.plot: path")
        names = self._names(names, "SimulationResult.plot: names", list(self.outputs) or self.x_names[:4], False)
        return time_plot(self.t, [self[n] for n in names], names, title=title, path=path, units=self.units)
