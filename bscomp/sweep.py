"""Position-dependent dynamics: modes (and FRFs) against the nut/table position (thesis Sec 3.5.2.2,
Table 4.1's L/C/R positions).

Every position is rebuilt from the pair ``(build, overrides)`` -- a system name or ``.py`` path (or a
picklable callable) and a dict of parameter values -- which is all a worker process needs. With
``workers > 1`` the positions run on a :class:`concurrent.futures.ProcessPoolExecutor`; any executor
with the same ``map`` interface (e.g. a Dask ``Client.get_executor()``) can be passed as ``executor``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from .errors import UnknownNameError

__all__ = ["position_sweep", "PositionSweep", "build_system"]


def build_system(build, overrides: dict | None = None):
    """A System from a name / ``.py`` path (``bscomp.systems.get``) or a callable, with parameter overrides.

    A callable is called without arguments and must return a :class:`bscomp.System`; the overrides are
    then applied with ``System.set`` (so structural parameters such as the nut position re-mesh at
    flattening).
    """
    if isinstance(build, str):
        from bscomp.systems import get

        return get(build, overrides)
    if callable(build):
        system = build()
        for k, v in (overrides or {}).items():
            system.set(k, v)
        return system
    raise TypeError(f"build must be a system name, a .py path or a callable returning a System, "
                    f"got {build!r}")


def position_parameter(system) -> str:
    """The dotted name of a system's nut-position parameter: its ``position_parameter`` attribute.

    Convention: a system's build function sets ``system.position_parameter = "screw.z_nut"`` (or the
    parameter that moves the nut/table along the screw).
    """
    name = getattr(system, "position_parameter", None)
    if not name:
        raise UnknownNameError(f"system '{getattr(system, 'name', system)}' declares no nut-position "
                               "parameter: set system.position_parameter = '<component>.<parameter>' in its "
                               "build function, or name the parameter explicitly")
    return name


def _analyse(build, overrides, inputs, outputs, freqs, n_modes, at):
    """One position, in this process or a worker: frequencies, damping and optionally the FRF."""
    from .frf import frf
    from .linear import second_order
    from .modal import modes

    system = build_system(build, overrides)
    so = second_order(system, inputs=inputs, outputs=outputs, at=at)
    md = modes(so)
    el = ~md.rigid_body
    f, z = md.frequencies[el], md.damping[el]
    if n_modes is not None:
        f, z = f[:n_modes], z[:n_modes]
    out = {"frequencies": f, "damping": z, "inputs": md.inputs, "outputs": md.outputs}
    if freqs is not None:
        out["H"] = frf(so, freqs=freqs).H
    return out


@dataclass
class PositionSweep:
    """Elastic natural frequencies (and FRFs) against position (result of :func:`position_sweep`).

    Attributes
    ----------
    parameter : str
        Dotted name of the swept parameter.
    positions : (npos,) ndarray
    frequencies : (npos, m) ndarray
        Elastic natural frequencies [Hz], sorted per position (NaN-padded when the count differs).
    damping : (npos, m) ndarray
    freqs : (nf,) ndarray or None
    H : (npos, nf, n_out, n_in) complex ndarray or None
    inputs, outputs : list of str
    """

    parameter: str
    positions: np.ndarray
    frequencies: np.ndarray
    damping: np.ndarray
    freqs: np.ndarray | None = None
    H: np.ndarray | None = None
    inputs: list = field(default_factory=list)
    outputs: list = field(default_factory=list)
    name: str = ""

    def to_csv(self, path) -> None:
        """One row per position: position, ``f1..fm`` [Hz], ``zeta1..zetam``."""
        import csv

        m = self.frequencies.shape[1]
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([self.parameter] + [f"f{k + 1}_hz" for k in range(m)]
                       + [f"zeta{k + 1}" for k in range(m)])
            for p, f, z in zip(self.positions, self.frequencies, self.damping, strict=True):
                w.writerow([repr(float(p))] + [repr(float(x)) for x in f] + [repr(float(x)) for x in z])

    def to_dict(self) -> dict:
        def clean(a):
            return [[None if not np.isfinite(x) else float(x) for x in row] for row in a]

        d = {"name": self.name, "parameter": self.parameter, "positions": self.positions.tolist(),
             "frequencies_hz": clean(self.frequencies), "damping": clean(self.damping),
             "inputs": list(self.inputs), "outputs": list(self.outputs)}
        if self.H is not None:
            d.update(freqs_hz=self.freqs.tolist(), H_re=self.H.real.tolist(), H_im=self.H.imag.tolist())
        return d

    def to_json(self, path=None) -> str:
        text = json.dumps(self.to_dict())
        if path is not None:
            with open(path, "w") as fh:
                fh.write(text)
        return text

    def plot(self, path=None, kind: str = "frequencies", output=None, input=None, title=None):
        """``kind="frequencies"``: natural frequency against position
        (:func:`bscomp.plotting.frequency_position_plot`); ``kind="frf"``: the magnitude of one FRF pair at
        every position (:func:`bscomp.plotting.frf_overlay_plot`)."""
        from . import plotting

        if kind == "frequencies":
            return plotting.frequency_position_plot(
                self.positions, self.frequencies, parameter=self.parameter,
                title=title or f"{self.name}: natural frequencies", path=path)
        if kind == "frf":
            if self.H is None:
                raise ValueError("this sweep has no FRFs: pass freqs to position_sweep")
            j = 0 if output is None else self.outputs.index(output)
            i = 0 if input is None else self.inputs.index(input)
            labels = [f"{self.parameter} = {p:g}" for p in self.positions]
            return plotting.frf_overlay_plot(
                self.freqs, self.H[:, :, j, i], labels=labels,
                title=title or f"{self.inputs[i]} -> {self.outputs[j]}", path=path)
        raise ValueError(f"kind must be 'frequencies' or 'frf', got {kind!r}")


def position_sweep(build, positions, parameter: str | None = None, freqs=None, inputs=None, outputs=None,
                   n_modes: int | None = None, overrides: dict | None = None, at: dict | None = None,
                   workers: int | None = None, executor=None) -> PositionSweep:
    """Modes (and FRFs) of a drive at several nut positions.

    Parameters
    ----------
    build : str or callable
        System name registered in ``bscomp.systems``, path to a ``.py`` file defining ``build()``, or a
        callable returning a System (module-level, i.e. picklable, when ``workers > 1``).
    positions : array_like
        Values of ``parameter``.
    parameter : str, optional
        Dotted name of the nut-position parameter; default the system's ``position_parameter``.
    freqs : array_like, optional
        Frequencies [Hz] at which FRFs are also computed.
    inputs, outputs : list of str, optional
    n_modes : int, optional
        Number of lowest elastic modes kept per position (default all).
    overrides : dict, optional
        Further parameter overrides applied at every position.
    at : dict, optional
        Operating point.
    workers : int, optional
        ``> 1``: run the positions on a ``ProcessPoolExecutor`` with that many processes.
    executor : concurrent.futures.Executor, optional
        Use this executor instead (its ``submit`` is used), e.g. a Dask client's executor.

    Returns
    -------
    PositionSweep
    """
    positions = np.atleast_1d(np.asarray(positions, float))
    if parameter is None:
        parameter = position_parameter(build_system(build, overrides))
    freqs = None if freqs is None else np.atleast_1d(np.asarray(freqs, float))
    tasks = [(build, {**(overrides or {}), parameter: float(x)}, inputs, outputs, freqs, n_modes, at)
             for x in positions]
    if executor is not None:
        results = [fut.result() for fut in [executor.submit(_analyse, *t) for t in tasks]]
    elif workers is not None and workers > 1 and len(tasks) > 1:
        import pickle
        from concurrent.futures import ProcessPoolExecutor

        try:
            pickle.dumps(build)
        except Exception as exc:
            raise TypeError("with workers > 1, build must be picklable: a system name, a .py path or a "
                            "module-level function (not a lambda or closure)") from exc
        with ProcessPoolExecutor(max_workers=min(workers, len(tasks))) as pool:
            results = [fut.result() for fut in [pool.submit(_analyse, *t) for t in tasks]]
    else:
        results = [_analyse(*t) for t in tasks]
    m = max(r["frequencies"].size for r in results)
    F = np.full((positions.size, m), np.nan)
    Z = np.full((positions.size, m), np.nan)
    for k, r in enumerate(results):
        F[k, : r["frequencies"].size] = r["frequencies"]
        Z[k, : r["damping"].size] = r["damping"]
    H = np.stack([r["H"] for r in results]) if freqs is not None else None
    name = build if isinstance(build, str) else getattr(build, "__name__", "")
    return PositionSweep(parameter=parameter, positions=positions, frequencies=F, damping=Z, freqs=freqs, H=H,
                         inputs=list(results[0]["inputs"]), outputs=list(results[0]["outputs"]), name=name)
