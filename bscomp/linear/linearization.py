"""Linearization of a flattened model.

* :func:`linearize` -> python-control ``StateSpace`` with state, input and output names, from the
  implicit DAE at an operating point: with ``W = [dF/dx', dF/dz]`` (index 1, non-singular),

  .. math:: \\begin{bmatrix}\\delta\\dot x\\\\ \\delta z\\end{bmatrix}
            = -W^{-1}\\left(F_x\\,\\delta x + F_u\\,\\delta u\\right)

  solved with a sparse LU (no dense inverse).
* :func:`second_order` -> :class:`SecondOrderModel` ``M q'' + C q' + K q = B u``,
  ``y = C_q q + C_v q' + C_a q'' + D u`` over the reduced mechanical coordinates (thesis Eq 3.44 / 5.1),
  sparse. Internal algebraic variables are eliminated by a Schur complement.

Operating points and parameters passed in are honoured: ``at`` sets states and inputs by name, ``params``
overrides parameters (structural ones re-flatten a copy of the system).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bscomp.errors import (
    ModelLimitationWarning,
    NotLinearError,
    SingularSystemError,
    UnknownNameError,
    check_names,
)
from bscomp.kernel.dae import Dae, _sp
from bscomp.kernel.mechanics import (
    OperatingPoint,
    operating_point,
    require_second_order,
    second_order_blocks,
    sparse_jacobians,
)
from bscomp.kernel.signal_meta import declared_units
from bscomp.kernel.system_damping import system_damping_matrix
from bscomp.linear.frf_engine import direct_frf, state_space_decomposition, state_space_modal_frf
from bscomp.model import resolve_model

__all__ = ["linearize", "second_order", "SecondOrderModel", "OperatingPoint", "resolve_model", "control_labels",
           "nonlinear_variables", "linearized_parts", "warn_linearized"]


def control_labels(names):
    """bscomp names as python-control signal labels: python-control forbids '.', so ``motor.tau`` ->
    ``motor/tau``."""
    return [n.replace(".", "/") for n in names]


def _output_jac(dae: Dae, names, op: OperatingPoint):
    import casadi as ca

    key = ("output_jacobian", tuple(names))
    f = dae._cache.get(key)
    if f is None:  # built once per (Dae, outputs), reused by every linearization
        y = dae.output_expr(names)
        f = dae._cache[key] = ca.Function(
            "gj", [dae.xds, dae.xs, dae.zs, dae.us, dae.ps],
            [ca.jacobian(y, dae.xds), ca.jacobian(y, dae.xs), ca.jacobian(y, dae.zs), ca.jacobian(y, dae.us)])
    return [_sp(m) for m in f(op.xd, op.x, op.z, op.u, op.p)]


def nonlinear_variables(dae, p=None) -> list:
    """Names of the variables the residual's Jacobian depends on (empty for a linear model): the one test of
    whether linearizing ``dae`` drops anything (``simulate(method="lti")``, :func:`frf`, :func:`modes`).

    With parameter values ``p`` the test is of the model *at those values*: a branch a parameter switches off
    (an amplifier current limit ``i_max = 0``, Eq 4.1 without saturation) folds away and is not reported."""
    memo = dae._cache.setdefault("nonlinear_variables_at", {})     # bounded below: a sweep visits many p
    key = None if p is None else np.asarray(p, float).tobytes()
    if key in memo:
        return memo[key]
    w = [(dae.xds, [f"der({n})" for n in dae.x_names]), (dae.xs, dae.x_names), (dae.zs, dae.z_names),
         (dae.us, dae.u_names)]
    wv = ca.vertcat(*(v for v, _ in w))
    names = [n for _, ns in w for n in ns]
    F = dae.F_sx
    if p is not None and F.numel() and dae.ps.numel():
        F = ca.substitute(F, dae.ps, ca.DM(np.asarray(p, float)))     # constant folding drops switched-off branches
    # the unknowns entering the residual with order >= 2 (those its Jacobian depends on), by one
    # dependency walk: no Jacobian of the Jacobian (seconds on the moving-nut test bed)
    cols = [i for i, dep in enumerate(ca.which_depends(F, wv, 2, False)) if dep] if F.numel() else []
    if len(memo) >= 64:
        memo.pop(next(k for k in memo if k is not None))
    memo[key] = out = [names[c] for c in cols]
    return out


def linearized_parts(dae, p=None) -> tuple:
    """``(model name, components, variables)`` a linearization of ``dae`` (at parameter values ``p``, default:
    any) replaces by their tangent: the components whose equations are nonlinear (``"fric (CoulombFriction)"``,
    recorded by flattening) and the variables the residual's Jacobian depends on; ``()`` for a linear model
    (:func:`nonlinear_variables` decides)."""
    names = nonlinear_variables(dae, p)
    if not names:
        return ()
    comps = list(getattr(dae, "nonlinear_components", []) or [])
    if p is not None:           # at these values: the components a nonlinear variable belongs to (else all)
        def mine(c):
            path = c.split(" ")[0] + "."
            return any(n.startswith(path) or n.startswith("der(" + path) for n in names)

        comps = [c for c in comps if mine(c)] or comps
    return dae.name, comps, names


#: what a frequency-domain analysis of a nonlinear model should be replaced by
SIMULATE_INSTEAD = ("for the response at a real amplitude, take a stepped-sine FRF by simulation: "
                    "bscomp.stepped_sine(model, input, output, freqs, amplitude), or its one-harmonic estimate in "
                    "milliseconds: bscomp.describing_frf(model, input, output, freqs, amplitude)")


def warn_linearized(parts: tuple, what: str, instead: str, stacklevel: int = 2, measured: str = "") -> None:
    """Warn (:class:`~bscomp.errors.ModelLimitationWarning`) that ``what`` linearizes the nonlinear parts
    ``parts`` (:func:`linearized_parts`) at the operating point, naming them and saying what to use
    ``instead``; nothing for a linear model. ``stacklevel`` as in :func:`warnings.warn`, seen from the caller;
    ``measured``: what the linearization got wrong, where that was measured (a time response)."""
    if not parts:
        return
    name, comps, names = parts
    which = (f"the nonlinear component(s) {', '.join(comps[:6])}{' ...' if len(comps) > 6 else ''}"
             if comps else "its nonlinearity")
    vars_ = f"{', '.join(names[:5])}{' ...' if len(names) > 5 else ''}"
    warnings.warn(f"{what} on '{name}' linearizes {which} at the operating point (nonlinear in {vars_}): "
                  "friction, backlash, saturation or a moving contact is replaced by its tangent there, which "
                  f"holds for small motions only{f' ({measured})' if measured else ''}; {instead}",
                  ModelLimitationWarning, stacklevel=stacklevel + 1)


def explicit_form(dae: Dae, Jxd, Jx, Jz, Ju):
    """``(A, B, Zx, Zu)`` of the index-1 linearization from the Jacobians of F at a point (scipy sparse):
    ``x' = A dx + B du``, ``z = Zx dx + Zu du``, i.e. ``[A B; Zx Zu] = -[dF/dx', dF/dz]^{-1} [dF/dx, dF/du]``.

    ``Ju`` holds the columns of the inputs wanted. Raises :class:`SingularSystemError` if
    ``[dF/dx', dF/dz]`` is singular at the point.
    """
    nx = dae.nx
    W = sp.hstack([Jxd, Jz]).tocsc()
    try:
        lu = spla.splu(W)
    except RuntimeError as exc:
        raise SingularSystemError(dae._singular_message(W)) from exc
    ncol = Jx.shape[1] + Ju.shape[1]
    sol = -lu.solve(sp.hstack([Jx, Ju]).toarray()) if ncol else np.zeros((W.shape[0], 0))
    return sol[:nx, :nx], sol[:nx, nx:], sol[nx:, :nx], sol[nx:, nx:]


def _select_inputs(dae: Dae, inputs):
    inputs = check_names("inputs", inputs)
    if inputs is None:
        return list(range(dae.nu)), list(dae.u_names)
    idx = []
    for n in inputs:
        if n not in dae.u_names:
            raise UnknownNameError(f"'{n}' is not an input of '{dae.name}'; inputs are the unconnected signal inputs "
                                   f"{dae.u_names}")
        idx.append(dae.u_names.index(n))
    return idx, list(inputs)


def linearize(model, inputs=None, outputs=None, at: dict | None = None, params: dict | None = None):
    """Linearize a System or Dae into a python-control ``StateSpace``.

    Parameters
    ----------
    model : System or Dae
    inputs : list of str, optional
        Input names (unconnected signal inputs, e.g. ``"motor.tau"``); default all.
    outputs : list of str, optional
        Output names (any observable, e.g. ``"table.a"``, ``"rotor.w"``); default the states.
    at : dict, optional
        Operating point: state and input values by name; the rest of the state is at its start value
        and ``(x', z)`` are solved consistently.
    params : dict, optional
        Parameter overrides by dotted name.

    Returns
    -------
    control.StateSpace
        With ``state_labels``, ``input_labels`` and ``output_labels`` set (python-control forbids '.' in
        labels, so ``"motor.tau"`` appears as ``"motor/tau"``). Its attribute
        ``second_order`` holds the :class:`SecondOrderModel` when the model is mechanical-linear
        (else None).
    """
    import control

    dae = resolve_model(model, params)
    op = operating_point(dae, at, params)
    Jxd, Jx, Jz, Ju = sparse_jacobians(dae, op)
    uidx, unames = _select_inputs(dae, inputs)
    outputs = check_names("outputs", outputs)
    if not uidx:
        raise NotLinearError(f"'{dae.name}' has no inputs and python-control's StateSpace needs at least one: add a "
                             "Force/Torque source (its unconnected input becomes a system input); second_order() "
                             "works without inputs")
    nx = dae.nx
    A, B, Zx, Zu = explicit_form(dae, Jxd, Jx, Jz, Ju[:, uidx])
    if outputs is None:
        outputs = list(dae.x_names)
        C = np.eye(nx)
        D = np.zeros((nx, len(uidx)))
    else:
        Gxd, Gx, Gz, Gu = _output_jac(dae, outputs, op)
        C = np.asarray(Gx.toarray() + Gxd @ A + Gz @ Zx).reshape(len(outputs), nx)
        D = np.asarray(Gu[:, uidx].toarray() + Gxd @ B + Gz @ Zu).reshape(len(outputs), len(uidx))
    sys = control.ss(A, B, np.asarray(C), np.asarray(D), states=control_labels(dae.x_names),
                     inputs=control_labels(unames), outputs=control_labels(outputs), name=dae.name)
    try:
        sys.second_order = second_order(dae, inputs=unames, outputs=outputs, at=at, params=params, _op=op)
    except NotLinearError:
        sys.second_order = None
    sys.operating_point = op
    sys.linearized = linearized_parts(dae, op.p)
    return sys


@dataclass
class SecondOrderModel:
    """``M q'' + C q' + K q = B u``, ``y = Cq q + Cv q' + Ca q'' + D u`` (sparse), thesis Eq 3.44 / 5.1-5.3.

    Attributes
    ----------
    coordinates : list of str
        Names of the reduced coordinates ``q``.
    units : list of str
    inputs, outputs : list of str
    linearized : tuple
        ``(model name, nonlinear components, variables)`` replaced by their tangent at the operating point
        (:func:`linearized_parts`); ``()`` for a linear model.
    signal_units : dict
        The declared unit of each input and output that has one (``{"amp.u": "V", "table.a": "m/s^2"}``).
    """

    M: Any
    C: Any
    K: Any
    B: Any
    Cq: Any
    Cv: Any
    Ca: Any
    D: Any
    coordinates: list
    units: list
    inputs: list
    outputs: list
    linearized: tuple = ()
    signal_units: dict = field(default_factory=dict)

    @property
    def n(self):
        return self.M.shape[0]

    def frf(self, freqs_hz, method: str = "auto"):
        r"""Frequency response ``H[k, i, j]`` (freq, output, input); no dense inverse.

        .. math:: H(j\omega) = (C_q + j\omega C_v - \omega^2 C_a)
                  (K + j\omega C - \omega^2 M)^{-1} B + D

        Parameters
        ----------
        method : {"auto", "modal", "direct"}
            ``"modal"``: one eigen-decomposition of the first-order form ``(q, q')`` (any viscous
            damping, non-proportional included), then the exact partial-fraction sum per frequency:
            cheap for many frequencies. ``"direct"``: one sparse LU per frequency (large models, or a
            singular mass matrix). ``"auto"``: modal up to 1500 coordinates with a non-singular M.
        """
        f = np.atleast_1d(np.asarray(freqs_hz, float))
        if method not in ("auto", "modal", "direct"):
            raise ValueError(f"frf method must be 'auto', 'modal' or 'direct', got {method!r}")
        if method != "direct" and self.n <= 1500:
            dec = self._modal_decomposition()
            if dec is not None:
                return state_space_modal_frf(dec, self.D, f)
            if method == "modal":
                raise SingularSystemError("frf(method='modal') needs a non-singular mass matrix")
        return direct_frf(self.M, self.C, self.K, self.B, self.Cq, self.Cv, self.Ca, self.D, f)

    def _modal_decomposition(self):
        """:func:`~bscomp.linear.frf_engine.state_space_decomposition` of this model (cached)."""
        cache = self.__dict__.setdefault("_cache", {})
        if "modal" not in cache:
            cache["modal"] = state_space_decomposition(self.M, self.C, self.K, self.B, self.Cq, self.Cv, self.Ca)
        return cache["modal"]

    def to_statespace(self):
        """First-order form x = (q, q') (Eq 5.3); needs a non-singular M."""
        import control

        M = self.M.toarray()
        try:
            Minv_K = np.linalg.solve(M, self.K.toarray())
            Minv_C = np.linalg.solve(M, self.C.toarray())
            Minv_B = np.linalg.solve(M, self.B.toarray())
        except np.linalg.LinAlgError as exc:
            raise SingularSystemError("mass matrix is singular (massless coordinates): use linearize() on the Dae, "
                                      "which handles quasi-static coordinates") from exc
        n = self.n
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv_K, -Minv_C]])
        B = np.vstack([np.zeros((n, Minv_B.shape[1])), Minv_B])
        Ca = self.Ca.toarray()
        C = np.hstack([self.Cq.toarray() - Ca @ Minv_K, self.Cv.toarray() - Ca @ Minv_C])
        D = self.D.toarray() + Ca @ Minv_B
        return control.ss(A, B, C, D,
                          states=control_labels(self.coordinates + [f"der({c})" for c in self.coordinates]),
                          inputs=control_labels(self.inputs), outputs=control_labels(self.outputs))


def _close(A, B) -> bool:
    scale = max(abs(B).max(), 1e-300) if B.nnz else 1.0
    D = (A - B).tocsr()
    return D.nnz == 0 or abs(D).max() <= 1e-12 * scale


def _refresh_system_damping(dae, M, K, C):
    """Replace the system damping computed at flattening by the one of this linearization's (M, K).

    Modal damping (Eq A.10-A.15) is defined on the modes, so when parameters (e.g. the nut position of a
    :class:`~components.moving_screw_nut.MovingScrewNut`) or the operating point change M or K it is
    re-derived here, exactly as flattening at those values would.
    """
    damping = getattr(dae, "system_damping", None)
    if damping is None:
        return C
    M0, K0, Cadd0 = dae.system_damping_basis
    if _close(M, M0) and _close(K, K0):
        return C
    Cadd = system_damping_matrix(damping, M, K, dae.mech.coordinate_names)
    return sp.csr_matrix(C - Cadd0 + sp.csr_matrix(Cadd))


def second_order(model, inputs=None, outputs=None, at: dict | None = None, params: dict | None = None,
                 _op: OperatingPoint | None = None, refresh_damping: bool = True) -> SecondOrderModel:
    """Second-order form of a mechanical system, linearized at ``at`` (see :class:`SecondOrderModel`).

    ``refresh_damping=False`` keeps the system damping of the flattening (``dae.system_damping_basis``)
    instead of re-deriving it from this linearization's modes: for callers that re-derive it themselves
    in modal coordinates (:class:`bscomp.simulation.compiled.CompiledModel`).

    Raises
    ------
    NotLinearError
        If the model has internal differential states (controllers, electrical dynamics...): use
        :func:`linearize` for the first-order form.
    """
    dae = resolve_model(model, params, damping_refreshed=True)
    m = dae.mech
    require_second_order(dae)
    op = _op if _op is not None else operating_point(dae, at, params)
    jac = sparse_jacobians(dae, op)
    uidx, unames = _select_inputs(dae, inputs)
    b = second_order_blocks(dae, jac, uidx)
    outputs = check_names("outputs", outputs)
    if outputs is None:
        outputs = list(m.coordinate_names)
    Gxd, Gx, Gz, Gu_y = _output_jac(dae, outputs, op)
    Cq = Gx @ b.Sq_x + Gz @ b.Sq_z
    Cv = Gx @ b.Sv_x + Gxd @ b.Sv_xd_out
    Ca = Gxd @ b.Sa_xd
    Dy = Gu_y[:, uidx]
    Yw = Gz @ b.Sw
    if b.zint and Yw.nnz:
        def ysub(Yx, Gx_):
            return sp.csr_matrix(Yx - Yw @ b.lu.solve(sp.csc_matrix(Gx_).toarray()))
        Gq, Gv, Ga, Gu = b.G
        Cq, Cv, Ca, Dy = ysub(Cq, Gq), ysub(Cv, Gv), ysub(Ca, Ga), ysub(Dy, Gu)
    C = b.C
    if refresh_damping:
        C = _refresh_system_damping(dae, sp.csr_matrix(b.M), sp.csr_matrix(b.K), sp.csr_matrix(C))
    return SecondOrderModel(
        M=sp.csr_matrix(b.M), C=sp.csr_matrix(C), K=sp.csr_matrix(b.K), B=-sp.csr_matrix(b.Bu),
        Cq=sp.csr_matrix(Cq), Cv=sp.csr_matrix(Cv), Ca=sp.csr_matrix(Ca), D=sp.csr_matrix(Dy),
        coordinates=list(m.coordinate_names), units=list(m.coordinate_units), inputs=unames,
        outputs=list(outputs), linearized=linearized_parts(dae, op.p),
        signal_units=declared_units(dae, [*unames, *outputs]))
