"""Position-dependent dynamics: modes (and FRFs) against the nut/table position (thesis Sec 3.5.2.2,
Table 4.1's L/C/R positions).

Every position is rebuilt from the pair ``(build, overrides)`` -- a system name or ``.py`` path (or a
picklable callable) and a dict of parameter values -- which is all a worker process needs. With
``workers > 1`` the positions run on a :class:`concurrent.futures.ProcessPoolExecutor`; any executor
with the same ``map`` interface (e.g. a Dask ``Client.get_executor()``) can be passed as ``executor``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import numpy as np

from bscomp import plotting
from bscomp.errors import ArgumentTypeError, BscompError, UnknownNameError, UsageError, check_names
from bscomp.files import atomic_write
from bscomp.kernel.flattening import flatten
from bscomp.kernel.system import System
from bscomp.kernel.system_damping import system_damping_matrix
from bscomp.linear.frf_engine import modal_frf
from bscomp.linear.linearization import second_order
from bscomp.linear.modal import modes
from bscomp.linear.response import frf, refuse_constant_outputs
from bscomp.model import ModelSpec, as_system

__all__ = ["position_sweep", "PositionSweep", "build_system", "check_count"]


def check_count(name: str, value, who: str, minimum: int = 1, allow_none: bool = True):
    """``value`` as an int ``>= minimum`` (or None when ``allow_none``): a count such as ``n_modes``,
    ``workers`` or ``chunksize``. :class:`ArgumentTypeError` for a value that is not a whole number (``"2"``,
    ``1.5``, ``True``), :class:`UsageError` for one below ``minimum``; both name the argument."""
    if value is None and allow_none:
        return None
    ok_type = isinstance(value, (int, np.integer, float, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not ok_type or not np.isfinite(value) or value != int(value):
        raise ArgumentTypeError(f"{who}: {name} must be {'None or ' if allow_none else ''}a whole number >= {minimum}, "
                                f"got {value!r} ({type(value).__name__})")
    if int(value) < minimum:
        raise UsageError(f"{who}: {name} must be {'None or ' if allow_none else ''}>= {minimum}, got {value!r}")
    return int(value)


def build_system(build, overrides: dict | None = None):
    """A System from a name / ``.py`` path / :class:`~bscomp.model.ModelSpec` or a build callable, with overrides.

    A callable is called without arguments and must return a :class:`bscomp.System`; the overrides are
    then applied with ``System.set`` (so structural parameters such as the nut position re-mesh at
    flattening). Names and paths go through :func:`bscomp.model.as_system` (keys without a dot are build
    keywords).
    """
    if isinstance(build, (str, ModelSpec, System)):
        return as_system(build, overrides)
    if callable(build):
        system = build()
        for k, v in (overrides or {}).items():
            system.set(k, v)
        return system
    raise ArgumentTypeError(f"build must be a system name, a .py path, a System or a callable returning a System, "
                            f"got {type(build).__name__} {build!r}"[:300])


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

    system = build_system(build, overrides)
    so = second_order(system, inputs=inputs, outputs=outputs, at=at)
    if outputs is not None:
        refuse_constant_outputs(system, None, list(so.outputs), [so.Cq, so.Cv, so.Ca, so.D], "position_sweep")
    md = modes(so, warn=False)         # not a warning per position
    el = ~md.rigid_body
    f, z = md.frequencies[el], md.damping[el]
    if n_modes is not None:
        f, z = f[:n_modes], z[:n_modes]
    out = {"frequencies": f, "damping": z, "inputs": md.inputs, "outputs": md.outputs}
    if freqs is not None:
        out["H"] = frf(so, freqs=freqs, warn=False).H
    return out


def _tangent_component(system, parameter):
    """The component owning ``parameter`` if it is non-structural and the component has a tangent."""
    if "." not in parameter:
        return None
    path, pname = parameter.rsplit(".", 1)
    try:
        comp = system.component(path)
    except Exception:
        return None
    if not hasattr(comp, "_values") or pname not in comp._values or comp.tangent() is None:
        return None
    return path, pname, comp


class _TangentUpdate:
    """Linearizations at many values of one component parameter from one flattening.

    ``K(x) = K(x0) + P^T (K_t(x) - K_t(x0)) P`` (same for C; M unchanged), with ``K_t`` the component's
    exact tangent (:meth:`bscomp.Component.tangent`) over its port potentials and ``P`` the rows of the
    constraint map ``q = T q_r`` for those potentials. A system damping (modal, Eq A.10-A.15) is
    re-derived from the modes at every value, as flattening there would.
    """

    def __init__(self, system, parameter, path, pname, comp, inputs, outputs):
        import scipy.sparse as sp


        self.system, self.parameter, self.path, self.pname, self.comp = system, parameter, path, pname, comp
        t0 = time.perf_counter()
        self.dae = flatten(system)
        t1 = time.perf_counter()
        self.so0 = second_order(self.dae, inputs=inputs, outputs=outputs)
        if outputs is not None:
            so = self.so0
            refuse_constant_outputs(self.dae, None, list(so.outputs), [so.Cq, so.Cv, so.Ca, so.D], "position_sweep")
        self.times = {"flatten_s": t1 - t0, "linearize_s": time.perf_counter() - t1}
        self.inputs, self.outputs = inputs, outputs
        m = self.dae.mech
        t0 = comp.tangent()
        rows = [m.port_coordinates[f"{path}.{d}"] for d in t0.dofs]
        self.P = sp.csr_matrix(m.T)[rows]
        if np.any(np.asarray(m.t0)[rows] != 0.0):
            raise ValueError(f"{path}: its ports are offset by constraints; the tangent update needs rest")
        self.Kt0 = sp.csr_matrix(t0.K)
        self.Ct0 = None if t0.C is None else sp.csr_matrix(t0.C)
        self.x0 = float(comp._values[pname])
        damping = getattr(self.dae, "system_damping", None)
        self.damping = damping
        C = self.so0.C
        if damping is not None:
            C = C - sp.csr_matrix(self.dae.system_damping_basis[2])
        self.C_struct0 = sp.csr_matrix(C)

    def _tangent_at(self, x):
        """The component's tangent with its parameter at x (restored afterwards)."""
        old = self.comp._values[self.pname]
        try:
            self.comp._values[self.pname] = float(x)
            return self.comp.tangent()
        finally:
            self.comp._values[self.pname] = old

    def matrices(self, x):
        """(M, K, C_struct) at parameter value x (C_struct without the system damping)."""
        import scipy.sparse as sp

        t = self._tangent_at(x)
        P = self.P
        K = self.so0.K + P.T @ (sp.csr_matrix(t.K) - self.Kt0) @ P
        C = self.C_struct0
        if t.C is not None or self.Ct0 is not None:
            Ct = sp.csr_matrix(t.C) if t.C is not None else sp.csr_matrix(self.Kt0.shape)
            C0 = self.Ct0 if self.Ct0 is not None else sp.csr_matrix(self.Kt0.shape)
            C = C + P.T @ (Ct - C0) @ P
        return self.so0.M, sp.csr_matrix(K), sp.csr_matrix(C)

    def _factor(self):
        """Once per sweep: ``M = L L^T`` and ``A0 = L^-1 K0 L^-T`` (M does not change with the parameter)."""
        if getattr(self, "_L", None) is None:
            import scipy.linalg as sla

            Md = self.so0.M.toarray()
            L = np.linalg.cholesky(Md)
            Li = sla.solve_triangular(L, np.eye(L.shape[0]), lower=True)
            A0 = Li @ (self.so0.K @ Li.T)
            self._L, self._W = L, np.asarray(self.P @ Li.T).T            # W = L^-1 P^T  (n, r)
            self._A0 = 0.5 * (A0 + A0.T)
        return self._L, self._W, self._A0

    def modal(self, x):
        """Mass-normalised modes and modal damping at x: (lam, phi, c_modal, C_struct).

        ``K(x) phi = M phi lam`` as the standard problem ``(A0 + W dK W^T) v = v lam`` with ``A0 = L^-1 K0
        L^-T``, ``W = L^-1 P^T`` and ``phi = L^-T v`` (``M = L L^T`` factored once; the tangent change ``dK``
        touches a few coordinates, so the update costs O(n^2 r) for r of them, not a product of dense
        n x n matrices).
        """
        import scipy.linalg as sla
        import scipy.sparse as sp


        try:
            L, W, A0 = self._factor()
        except np.linalg.LinAlgError:        # M not symmetric positive definite (massless coordinates, or a
            return None                      # non-symmetric CMS superelement with MA recovery): rebuild instead
        t = self._tangent_at(x)
        dK = (sp.csr_matrix(t.K) - self.Kt0).tocoo()
        S = np.unique(np.concatenate([dK.row, dK.col]))
        A = A0.copy()
        if S.size:
            dKs = np.zeros((S.size, S.size))
            np.add.at(dKs, (np.searchsorted(S, dK.row), np.searchsorted(S, dK.col)), dK.data)
            WS = W[:, S]
            A += WS @ dKs @ WS.T
        lam, v = sla.eigh(A, driver="evd", overwrite_a=True, check_finite=False)
        phi = sla.solve_triangular(L, v, lower=True, trans="T", check_finite=False)
        Cs = self.C_struct0
        if t.C is not None or self.Ct0 is not None:
            Cs = self.matrices(x)[2]
        c = np.zeros(lam.size)
        if self.damping is not None:
            coords = list(self.dae.mech.coordinate_names)
            if hasattr(self.damping, "modal_ratios"):
                zeta = self.damping.modal_ratios(lam, phi, self.so0.M, coords)
                c = 2.0 * zeta * np.sqrt(np.clip(lam, 0.0, None))
            else:
                M, K, _ = self.matrices(x)
                Cadd = system_damping_matrix(self.damping, M, K, coords)
                Cm = phi.T @ np.asarray(Cadd.toarray() if hasattr(Cadd, "toarray") else Cadd) @ phi
                off = Cm - np.diag(np.diag(Cm))
                if np.abs(off).max() > 1e-8 * max(np.abs(np.diag(Cm)).max(), 1e-300):
                    return None
                c = np.diag(Cm).copy()
        return lam, phi, c, Cs

    def second_order(self, x):
        """Full linearization at x through the Dae (reference for the update)."""

        return second_order(self.dae, inputs=self.inputs, outputs=self.outputs, params={self.parameter: float(x)})


def _fast_sweep(upd, positions, freqs, n_modes, progress):
    """Frequencies, modal damping and FRFs at every position by the tangent update (one eigh each)."""
    so = upd.so0
    F, Z, H = [], [], []
    for k, x in enumerate(positions):
        mod = upd.modal(x)
        if mod is None:
            return None
        lam, phi, c, Cs = mod
        el = lam > 1e-9 * np.max(np.abs(lam))
        wn = np.sqrt(lam[el])
        zeta = (c[el] + np.sum(phi[:, el] * (Cs @ phi[:, el]), axis=0)) / (2.0 * wn)
        f, z = wn / (2.0 * np.pi), zeta
        if n_modes is not None:
            f, z = f[:n_modes], z[:n_modes]
        F.append(f)
        Z.append(z)
        if freqs is not None:
            H.append(modal_frf(lam, phi, c, Cs, so.B, so.Cq, so.Cv, so.Ca, so.D, freqs))
        if progress is not None:
            progress(k + 1, len(positions))
    return F, Z, H


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
    stats : dict
        Method and wall times [s] of its parts (tangent path: ``flatten_s``, ``linearize_s``, ``check_s``,
        ``positions_s``; every path: ``wall_s``).
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
    stats: dict = field(default_factory=dict)

    def to_csv(self, path) -> None:
        """One row per position: position, ``f1..fm`` [Hz], ``zeta1..zetam``."""
        import csv

        m = self.frequencies.shape[1]
        with atomic_write(path, what="PositionSweep.to_csv: path", suffixes=(".csv",), newline="") as fh:
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
            with atomic_write(path, what="PositionSweep.to_json: path", suffixes=(".json",)) as fh:
                fh.write(text)
        return text

    def plot(self, path=None, kind: str = "frequencies", output=None, input=None, title=None):
        """``kind="frequencies"``: natural frequency against position
        (:func:`bscomp.plotting.frequency_position_plot`); ``kind="frf"``: the magnitude of one FRF pair at
        every position (:func:`bscomp.plotting.frf_overlay_plot`)."""

        if kind not in ("frequencies", "frf"):
            raise UsageError(f"PositionSweep.plot: kind must be 'frequencies' or 'frf', got {kind!r}")
        if kind == "frequencies":
            return plotting.frequency_position_plot(
                self.positions, self.frequencies, parameter=self.parameter,
                title=title or f"{self.name}: natural frequencies", path=path)
        if kind == "frf":
            if self.H is None:
                raise UsageError("PositionSweep.plot(kind='frf'): this sweep has no FRFs: pass freqs to position_sweep")
            j = 0 if output is None else self._index(self.outputs, output, "output")
            i = 0 if input is None else self._index(self.inputs, input, "input")
            labels = [f"{self.parameter} = {p:g}" for p in self.positions]
            return plotting.frf_overlay_plot(
                self.freqs, self.H[:, :, j, i], labels=labels,
                title=title or f"{self.inputs[i]} -> {self.outputs[j]}", path=path)

    @staticmethod
    def _index(names, name, what):
        if name not in names:
            raise UnknownNameError(f"PositionSweep.plot: '{name}' is not an {what} of this sweep; {what}s: {names}")
        return names.index(name)


def position_sweep(build, positions, parameter: str | None = None, freqs=None, inputs=None, outputs=None,
                   n_modes: int | None = None, overrides: dict | None = None, at: dict | None = None,
                   workers: int | None = None, executor=None, method: str = "auto",
                   progress: bool | None = None) -> PositionSweep:
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
        Number (>= 1) of lowest elastic modes kept per position (default all).
    overrides : dict, optional
        Further parameter overrides applied at every position.
    at : dict, optional
        Operating point.
    workers : int, optional
        ``> 1``: run the positions on a ``ProcessPoolExecutor`` with that many processes (``1`` or None:
        serially).
    executor : concurrent.futures.Executor, optional
        Use this executor instead (its ``submit`` is used), e.g. a Dask client's executor.
    method : {"auto", "tangent", "rebuild"}
        ``"rebuild"``: rebuild, flatten and analyse the system at every position (any parameter, any
        system; parallel with ``workers``). ``"tangent"``: flatten once and update the linearization by
        the exact tangent of the component that owns a non-structural position parameter (e.g.
        ``sn.z0`` of :class:`~components.moving_screw_nut.MovingScrewNut`, ``testbed`` with
        ``nut_joint="moving"``), then one symmetric eigen-decomposition per position gives the modes
        and the exact FRF (:func:`~bscomp.linear.frf_engine.modal_frf`); the update is checked against a full
        linearization at the position farthest from the nominal one (relative 1e-8 on K and C).
        Reported frequencies are the undamped natural frequencies and damping the modal ratios
        (diagonal of the modal damping; the ``rebuild`` path reports damped eigenvalues, which differ
        by O(zeta^2)). ``"auto"``: ``tangent`` when possible (no ``at``, no executor), else ``rebuild``.
    progress : bool, optional
        Print progress to stderr (default: when more than 20 positions).

    Returns
    -------
    PositionSweep

    Raises
    ------
    UsageError, ArgumentTypeError
        Bad positions, method, ``n_modes`` or ``workers`` (named).
    UnknownNameError
        An unknown parameter, input or output, or an output that is a parameter or a constant
        (:meth:`bscomp.Dae.require_signals`).
    """
    t_start = time.perf_counter()
    try:
        positions = np.atleast_1d(np.asarray(positions, float))
    except (TypeError, ValueError):
        raise UsageError(f"positions must be numbers [m] (nut positions), got {positions!r}"[:300]) from None
    if positions.ndim != 1 or not positions.size or not np.all(np.isfinite(positions)):
        raise UsageError(f"positions must be a non-empty 1-D array of finite nut positions [m], got "
                         f"{positions!r}"[:300])
    if method not in ("auto", "tangent", "rebuild"):
        raise UsageError(f"position_sweep: method must be 'auto', 'tangent' or 'rebuild', got {method!r}")
    n_modes = check_count("n_modes", n_modes, "position_sweep")
    workers = check_count("workers", workers, "position_sweep")
    inputs, outputs = check_names("inputs", inputs), check_names("outputs", outputs)
    base = build_system(build, overrides)
    if parameter is None:
        parameter = position_parameter(base)
    freqs = None if freqs is None else np.atleast_1d(np.asarray(freqs, float))
    name = build if isinstance(build, str) else getattr(build, "__name__", "")
    if method != "rebuild" and at is None and executor is None:
        owner = _tangent_component(base, parameter)
        if owner is not None:                 # the tangent update writes the values itself: check them first
            _, pname, comp = owner
            for x in positions:
                comp.checked({pname: float(x)})
        if owner is None and method == "tangent":
            raise UsageError(f"position_sweep(method='tangent'): '{parameter}' is not a non-structural "
                             "parameter of a component with a tangent() (e.g. MovingScrewNut's z0); use "
                             "method='rebuild'")
        if owner is not None:
            res = _tangent_sweep(base, parameter, owner, positions, freqs, inputs, outputs, n_modes, progress, name)
            if res is not None:
                return res
            if method == "tangent":
                raise UsageError("position_sweep(method='tangent'): the tangent update needs a symmetric positive "
                                 "definite mass matrix and damping that is modal plus a few discrete dampers (not "
                                 "so here: e.g. massless coordinates, a CMS superelement with MA recovery); use "
                                 "method='rebuild'")
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
            raise ArgumentTypeError("with workers > 1, build must be picklable: a system name, a .py path or a "
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
    return PositionSweep(parameter=parameter, positions=positions, frequencies=F, damping=Z, freqs=freqs, H=H,
                         inputs=list(results[0]["inputs"]), outputs=list(results[0]["outputs"]), name=name,
                         stats={"method": "rebuild", "wall_s": time.perf_counter() - t_start})


def _tangent_sweep(system, parameter, owner, positions, freqs, inputs, outputs, n_modes, progress, name):
    """position_sweep by the tangent update; None when the model does not allow the one-eigh form (damping that is
    not modal plus dampers, or a mass matrix that is not symmetric positive definite)."""
    import sys

    import scipy.sparse as sp


    t_start = time.perf_counter()
    path, pname, comp = owner
    upd = _TangentUpdate(system, parameter, path, pname, comp, inputs, outputs)
    t_check = time.perf_counter()
    # check the update against a full linearization at the farthest position
    xc = float(positions[np.argmax(np.abs(positions - upd.x0))])
    M, K, Cs = upd.matrices(xc)
    ref = upd.second_order(xc)
    mod = upd.modal(xc)
    if mod is None:
        return None
    lam, phi, c, _ = mod
    Cm = np.diag(c) + phi.T @ (Cs @ phi)            # modal damping + discrete dampers, modal coordinates
    Cm_ref = phi.T @ (ref.C @ phi)
    for label, A, R in (("K", K, ref.K), ("M", M, ref.M), ("C", sp.csr_matrix(Cm), sp.csr_matrix(Cm_ref))):
        D = (A - R).tocsr()
        err = abs(D).max() if D.nnz else 0.0
        if err > 1e-8 * max(abs(R).max(), 1e-300):
            raise BscompError(f"position_sweep: the tangent of '{path}' does not reproduce the linearization at "
                              f"{parameter} = {xc} ({label} differs by {err:.3g}); its tangent() is wrong -- use "
                              "method='rebuild' and report the component")
    show = (positions.size > 20) if progress is None else progress
    last = [0.0]
    t_pos = time.perf_counter()

    def bar(k, n):
        now = time.perf_counter()
        if show and (k == n or now - last[0] > 0.5):
            last[0] = now
            sys.stderr.write(f"\r  position sweep {k}/{n} [{'#' * (30 * k // n):30s}]" + ("\n" if k == n else ""))

    out = _fast_sweep(upd, positions, freqs, n_modes, bar)
    if out is None:
        return None
    t_end = time.perf_counter()
    stats = dict(method="tangent", **upd.times, check_s=t_pos - t_check, positions_s=t_end - t_pos,
                 wall_s=t_end - t_start)
    F_list, Z_list, H_list = out
    m = max(f.size for f in F_list)
    F = np.full((positions.size, m), np.nan)
    Z = np.full((positions.size, m), np.nan)
    for k, (f, z) in enumerate(zip(F_list, Z_list, strict=True)):
        F[k, : f.size] = f
        Z[k, : z.size] = z
    so = upd.so0
    return PositionSweep(parameter=parameter, positions=positions, frequencies=F, damping=Z, freqs=freqs,
                         H=np.stack(H_list) if freqs is not None else None, inputs=list(so.inputs),
                         outputs=list(so.outputs), name=name, stats=stats)
