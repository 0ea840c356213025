r"""A model structure compiled once and evaluated at many parameter values: FRFs and time series.

Fitting a model to measurements (:func:`bscomp.validate.diagnose`, calibration) evaluates one structure
hundreds of times with different parameter values. :class:`CompiledModel` flattens it **once** and
evaluates, per parameter vector, in modal coordinates:

1. **Linear part.** Every nonlinear two-flange element (a component with ``force_law`` and
   ``linear_equivalent``: friction, backlash) is cut out and replaced by its small-signal equivalent in
   parallel with a :class:`~components.force_between.ForceBetween` driven by a signal ``w``. The rest
   is linear: :func:`bscomp.linear.second_order` gives ``M q'' + C q' + K q = B [u; w]`` with outputs
   ``y = C_q q + C_v q' + C_a q'' + D u`` (thesis Eq 3.44 / 5.1). Non-structural parameters enter
   through the Dae's Jacobians; *structural* ones (FE blocks, bearing and coupling stiffness: baked
   into matrices) through exact affine sensitivities ``M(p) = M_0 + \sum_i \Delta M_i (p_i - p_{i0})``
   measured once by re-flattening and checked at a second point (a non-affine one is re-flattened per
   evaluation).
2. **Modes.** ``K \phi = \lambda M \phi`` (dense ``eigh``, mass-normalised); the system damping
   (modal, Eq A.10-A.15, by mode character for :class:`~bscomp.systems.testbed.DriveModalDamping`) is
   re-derived from these modes at every evaluation, plus the discrete dampers ``\Phi^T C_s \Phi``. Modes
   below ``f_keep`` are kept; the others enter statically (residual flexibility
   ``R_t = \Phi_t \Lambda_t^{-1} \Phi_t^T``, the modal-acceleration idea of Eq 5.16-5.18).
3. **FRF.** ``H(j\omega) = (C_q + j\omega C_v - \omega^2 C_a)\,[\Phi_k (\Lambda_k - \omega^2 I + j\omega
   C_{kk})^{-1} \Phi_k^T + R_t] B + D``, times ``e^{-j\omega T}`` for an input delay ``T``.
4. **Time series.** The kept modes are stepped *exactly* (matrix exponential) with the measured inputs
   held over each sample (zero-order hold, the delay applied exactly as a shift of the held input,
   switching inside a step where it must), the element forces ``w`` first-order held between step ends
   and solved implicitly at each step end by Newton on the few element laws
   ``w = f_{law}(s, v) - f_{lin}(s, v)``. Each step is one CasADi MX function of the state and the
   discretised matrices, so one compiled ``mapaccum`` serves every parameter vector. A contact (an element whose
   equivalent is a spring: backlash) is cut from the time series' linear part (its whole law the correction, the
   clearance free), with sub-steps enough for stability and its own modes' band kept dynamic
   (:meth:`~bscomp.simulation.compiled_time.TimeSeriesMixin.simulate`).

Costs (2-core machine, axial+torsional test bed, 98 coordinates): one FRF evaluation a few ms; one
0.6 s time series at 5 kHz in tens of ms when linear, a few hundred ms with friction and backlash.
"""

from __future__ import annotations

import hashlib
import itertools
from os import PathLike

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.components.force_between import ForceBetween
from bscomp.components.torque_between import TorqueBetween
from bscomp.errors import ArgumentTypeError, UnknownNameError, check_names, check_number
from bscomp.kernel.component import _Context
from bscomp.kernel.dae import Dae
from bscomp.kernel.flattening import flatten
from bscomp.kernel.partials import PartialRotCompliant
from bscomp.kernel.system import System
from bscomp.kernel.system_damping import system_damping_matrix
from bscomp.linear.frf_engine import dense, modal_frf
from bscomp.linear.linearization import second_order
from bscomp.memo import kept
from bscomp.model import ModelSpec, as_system
from bscomp.simulation.compiled_checks import check_frf
from bscomp.simulation.compiled_hot import HotSteps
from bscomp.simulation.compiled_sensitivity import (
    affine,
    block_sensitivity,
    damped_beyond_static,
    dense_sens,
    flatten_sensitivity,
    probe_values,
    verify,
)
from bscomp.simulation.compiled_time import CompiledModelError, TimeSeriesMixin
from bscomp.simulation.harmonic_balance import HarmonicBalance

__all__ = ["CompiledModel", "ModalModel", "nonlinear_elements"]


_SERIALS = itertools.count()
_VERIFIED: dict = {}
"""(component class, parameter) -> whether its structural-block sensitivity matched a re-flattening."""


def nonlinear_elements(system) -> list:
    """``(path, component)`` of every two-flange element with a nonlinear force law."""
    return [(p, c) for p, c in system.leaves() if hasattr(c, "force_law") and hasattr(c, "linear_equivalent")]


def element_coordinates(comp) -> tuple:
    """The two observables a two-flange element's law reads: ``("s_rel", "v_rel")``, or ``("phi_rel", "w_rel")``
    for a rotational one (:class:`~bscomp.kernel.partials.PartialRotCompliant`: friction torque, torsional backlash)."""
    return ("phi_rel", "w_rel") if isinstance(comp, PartialRotCompliant) else ("s_rel", "v_rel")


#: The small-signal equivalents an element may have, with the names of their ``(k, s_rel0, d)`` parameters.
_LINEAR_KINDS = {"Spring": ("c", "s_rel0", None), "Damper": (None, None, "d"), "SpringDamper": ("c", "s_rel0", "d"),
                 "TorsionalSpring": ("c", "phi_rel0", None), "TorsionalDamper": (None, None, "d")}


def _with_params(comp, values: dict):
    """Call-context in which ``comp.<param>`` reads ``values`` (numbers or CasADi symbols)."""
    ctx = _Context()
    ctx.params = values
    return ctx


def _law_expr(comp, s, v, psyms: dict):
    old = comp.__dict__.get("_ctx")
    comp._ctx = _with_params(comp, psyms)
    try:
        return comp.force_law(s, v)
    finally:
        comp._ctx = old


class _Element:
    """One nonlinear element cut out of the linear part."""

    def __init__(self, path, comp):
        self.path, self.comp = path, comp
        self.coords = element_coordinates(comp)
        self.pnames = [n for n, v in comp._values.items() if v is not None and np.ndim(v) == 0]
        self.values = {n: float(comp._values[n]) for n in self.pnames}
        s, v = ca.SX.sym("s"), ca.SX.sym("v")
        psym = {n: ca.SX.sym(n) for n in self.pnames}
        law = _law_expr(comp, s, v, psym)
        self.law = ca.Function(f"law_{path}", [s, v, ca.vertcat(*psym.values())], [law])
        self.lin = comp.linear_equivalent()

    def lin_values(self, values: dict) -> dict:
        """Parameters of the small-signal equivalent for element parameters ``values``."""
        old = dict(self.comp._values)
        try:
            self.comp._values.update(values)
            lin = self.comp.linear_equivalent()
        finally:
            self.comp._values.clear()
            self.comp._values.update(old)
        return {} if lin is None else {k: float(v) for k, v in lin._values.items() if v is not None}


def _cut_nonlinear(system, elements):
    """The linear system: each nonlinear element -> small-signal equivalent + ForceBetween ``<path>``."""
    lin = system.copy()
    for el in elements:
        path = el.path
        owner = lin.component(path.rpartition(".")[0]) if "." in path else lin
        leaf = path.rpartition(".")[2]
        owner.replace(leaf, TorqueBetween() if isinstance(el.comp, PartialRotCompliant) else ForceBetween())
        if el.lin is not None:
            owner.add(f"{leaf}__lin", el.lin.copy())
            owner.connect(f"{leaf}__lin.flange_a", f"{leaf}.flange_a")
            owner.connect(f"{leaf}__lin.flange_b", f"{leaf}.flange_b")
    return lin


class ModalModel:
    """The linear part at one parameter vector, in modal coordinates (see the module docstring)."""

    def __init__(self, lam, phi, Ckk, Rt, so, keep, delay, f_keep, c_modal=None, C_struct=None):
        self.serial = next(_SERIALS)      # a cache key that, unlike id(), is never reused
        self.lam, self.phi, self.Ckk, self.Rt, self.so, self.keep = lam, phi, Ckk, Rt, so, keep
        self.delay, self.f_keep = delay, f_keep
        # what Ckk was made of, for the FRF engine: diagonal modal damping + physical discrete dampers
        self.c_modal = np.zeros(lam.size) if c_modal is None else c_modal
        self.C_struct = sp.csr_matrix((phi.shape[0],) * 2) if C_struct is None else sp.csr_matrix(C_struct)

    @property
    def frequencies(self):
        """Undamped natural frequencies [Hz] of all modes (rigid-body modes 0)."""
        return np.sqrt(np.clip(self.lam, 0.0, None)) / (2 * np.pi)


def _as_system(model) -> System:
    """The System of what :class:`CompiledModel` takes, else :class:`ArgumentTypeError` saying what that is."""
    if isinstance(model, System):
        return model
    if isinstance(model, (str, PathLike, ModelSpec, Dae)):
        return as_system(model)
    raise ArgumentTypeError(f"CompiledModel: system must be a bscomp.System, a system name, a .py path, a ModelSpec "
                            f"or a Dae that keeps its System, got {type(model).__name__} {model!r}"[:300])


def _required_names(names, argument: str) -> list:
    """One name or a list of names (one str is one name), at least one."""
    out = check_names(f"CompiledModel: {argument}", names)
    if not out:
        raise ArgumentTypeError(f"CompiledModel: {argument} must name at least one signal, got {names!r}")
    return out


class CompiledModel(TimeSeriesMixin):
    """One model structure, flattened once, evaluated at parameter overrides (module docstring).

    Parameters
    ----------
    system : System, str, path, ModelSpec or Dae
        The model, nonlinear elements included (a name, path or spec is built, a Dae's System is used).
    inputs : str or list of str
        The measured inputs (system inputs, e.g. ``"amp.u"``).
    outputs : str or list of str
        Every output any evaluation will ask for: signals (a parameter or a constant is refused,
        :meth:`bscomp.Dae.require_signals`).
    free : list of str, optional
        Parameters that will be varied (structural ones get their sensitivities measured here).
    f_keep : float
        Modes up to this frequency [Hz] are kept dynamically, the others statically.
    participation : float
        Modes whose (normalised) input participation times output visibility is below this are also
        taken statically (bending modes of the 6-DOF screw seen by an axial/torsional test).
    """

    def __init__(self, system, inputs, outputs, free=(), f_keep: float = 6000.0, participation: float = 1e-9):
        self.system = system = _as_system(system)
        self.inputs, self.outputs = _required_names(inputs, "inputs"), _required_names(outputs, "outputs")
        self.f_keep = check_number("CompiledModel: f_keep", f_keep, positive=True)
        self.participation = check_number("CompiledModel: participation", participation, nonnegative=True)
        self.elements = [_Element(p, c) for p, c in nonlinear_elements(system)]
        self._el_of = {}
        for i, el in enumerate(self.elements):
            for n in el.pnames:
                self._el_of[f"{el.path}.{n}"] = (i, n)
        self.linear_system = _cut_nonlinear(system, self.elements) if self.elements else system
        self.dae = flatten(self.linear_system)
        dae = self.dae
        self.w_inputs = [f"{el.path}.w" for el in self.elements]
        for name in self.inputs:
            if name not in dae.u_names or name in self.w_inputs:
                raise UnknownNameError(f"CompiledModel: '{name}' is not an input of '{dae.name}' (inputs: "
                                       f"{[u for u in dae.u_names if u not in self.w_inputs]})")
        self.nl_outputs = [f"{el.path}.{q}" for el in self.elements for q in el.coords]
        cut = [o for o in self.outputs for el in self.elements if o.startswith(el.path + ".")
               and o not in self.nl_outputs]
        if cut:        # after the cut "<path>" is the Force/TorqueBetween of the correction: not the element's force
            raise UnknownNameError(
                f"CompiledModel: {cut} are signals of the nonlinear elements "
                f"{sorted({el.path for el in self.elements})}, which the compiled evaluator cuts out (their force "
                "is carried as a correction, not as the element's force); request their s_rel / v_rel (phi_rel / "
                "w_rel), or use bscomp.simulate for the element's own signals")
        dae.require_signals(self.outputs, "CompiledModel")
        self._so_args = dict(inputs=self.inputs + self.w_inputs, outputs=self.outputs + self.nl_outputs)
        self.so0 = second_order(dae, refresh_damping=False, **self._so_args)
        if dae.mech.has_internal_states:
            raise CompiledModelError(f"'{dae.name}' has internal differential states (controllers, Pade delays): "
                                     "the compiled evaluator needs a mechanical model; apply delays as an input "
                                     "delay (CompiledModel.frf/simulate delay=)")
        self.damping = getattr(dae, "system_damping", None)
        self._Cadd0 = sp.csr_matrix(dae.system_damping_basis[2]) if self.damping is not None else None
        yf = dae.output_function(self.outputs + self.nl_outputs)
        x0 = dae.x_start
        xd0, z0 = dae.initialize(x0, np.zeros(dae.nu), dae.p0)
        y0 = np.asarray(yf(xd0, x0, z0, np.zeros(dae.nu), dae.p0), float).ravel()
        self.y_op, self._el_rest = y0[:len(self.outputs)], y0[len(self.outputs):]   # outputs; elements' (s, v)
        self._sens = {}
        self._reflatten = set()
        self._lin_sens = {}          # non-structural parameter -> (v0, dM, dK, dC) or None (not affine)
        for name in free:
            self.prepare(name)
        self._steps = {}
        self._runs = {}
        self._hot = HotSteps()                 # sample Functions compiled to C once hot
        self._modal_cache = {}
        self.stats = {"evaluations": 0}

    # ---- parameters -------------------------------------------------------------------------------
    def has_parameter(self, name: str) -> bool:
        """True if ``name`` is a parameter of the linear part or of a nonlinear element."""
        return name in self._el_of or name in self.dae.p_names

    def prepare(self, name):
        """Sensitivity of a structural parameter (no-op for others): from the component's own structural
        block at two values (exact, no re-flattening), verified once per component type and parameter
        against a re-flattening; a parameter that is not affine is re-flattened per evaluation."""
        if name in self._el_of or name in self._sens or name in self._reflatten:
            return
        dae = self.dae
        if name not in dae.p_names:
            raise UnknownNameError(f"'{name}' is not a parameter of '{dae.name}'")
        if name not in dae.structural_parameters:
            return
        v0 = float(dae.p0[dae.p_names.index(name)])
        sens = block_sensitivity(self, name, v0)
        key = None
        if sens is not None:
            path = name.rpartition(".")[0]
            key = (type(self.linear_system.component(path)).__name__, name.rpartition(".")[2])
            if key not in _VERIFIED:
                _VERIFIED[key] = verify(self, name, v0, sens)
            if not _VERIFIED[key]:
                sens = None
        if sens is None:
            sens = flatten_sensitivity(self, name, v0)
        if sens is None:
            self._reflatten.add(name)
        else:
            self._sens[name] = dense_sens(sens)

    def _split(self, params):
        lin, law, struct = {}, {}, {}
        for k, v in params.items():
            if k in self._el_of:
                law[k] = float(v)
            elif k in self._sens or k in self._reflatten:
                struct[k] = float(v)
            elif k in self.dae.structural_parameters:
                self.prepare(k)
                struct[k] = float(v)
            elif k in self.dae.p_names:
                self._to_lin_or_struct(k, float(v), lin, struct)
            else:
                raise UnknownNameError(f"'{k}' is not a parameter of '{self.dae.name}' or of its nonlinear elements")
        # small-signal equivalents follow their element's parameters (e.g. backlash contact stiffness)
        for el in self.elements:
            mine = {n: law[f"{el.path}.{n}"] for n in el.pnames if f"{el.path}.{n}" in law}
            if mine and el.lin is not None:
                leaf = el.path
                for n, v in el.lin_values({**el.values, **mine}).items():
                    key = f"{leaf}__lin.{n}"
                    if key in self.dae.p_names and key not in params:    # a given value wins
                        self._to_lin_or_struct(key, float(v), lin, struct)
        return lin, law, struct

    def _to_lin_or_struct(self, name, v, lin, struct):
        """File a non-structural parameter of the linear part: dropped at its flattening value, applied as
        an exact affine update of M, K, C (like a structural one) where the model is affine in it, else
        re-linearized (``lin``)."""
        v0 = float(self.dae.p0[self.dae.p_names.index(name)])
        if v == v0:
            return
        sens = self._linear_sensitivity(name, v0)
        if sens is None:
            lin[name] = v
        else:
            self._sens[name] = sens
            struct[name] = v

    def _linear_sensitivity(self, name, v0):
        """``(v0, dM, dK, dC)`` of a non-structural parameter from two linearizations at ``v0 (1 +- 0.1)``
        when M, K and C are affine in it and the input/output matrices do not move; ``None`` otherwise
        (cached per parameter). A spring's stiffness, a damper's coefficient: exact, and a fit's evaluation
        then costs no linearization."""
        if name in self._lin_sens:
            return self._lin_sens[name]
        out = None
        if v0 != 0.0 and np.isfinite(v0):        # a parameter at 0: re-linearized (its bound forbids a probe below)
            so1, so2 = (second_order(self.dae, refresh_damping=False, params={name: v}, **self._so_args)
                        for v in probe_values(v0)[1:])
            so0 = self.so0
            is_affine = so1.coordinates == so0.coordinates == so2.coordinates
            for attr in ("M", "K", "C"):
                is_affine &= affine(*(getattr(x, attr) for x in (so0, so1, so2)), 1e-9)
            for attr in ("B", "Cq", "Cv", "Ca", "D"):
                for x in (so1, so2):
                    diff = sp.csr_matrix(getattr(x, attr) - getattr(so0, attr))
                    is_affine &= not (diff.nnz and abs(diff).max() > 1e-12 * max(abs(getattr(so0, attr)).max(),
                                                                                   1e-300))
            if is_affine:
                dv = 0.2 * v0
                out = dense_sens((v0, *(sp.csr_matrix((getattr(so1, a) - getattr(so2, a)) / dv)
                                         for a in ("M", "K", "C"))))
        self._lin_sens[name] = out
        return out

    def _n_plaw(self):
        return max(sum(len(el.pnames) + 3 for el in self.elements), 1)

    def law_slices(self, plaw) -> list:
        """Per element of packed law values (:meth:`law_values`; numbers or CasADi symbols): ``(its law's
        parameters, k_lin, s0_lin, d_lin)``."""
        out, off = [], 0
        for el in self.elements:
            k = len(el.pnames)
            out.append((plaw[off:off + k], plaw[off + k], plaw[off + k + 1], plaw[off + k + 2]))
            off += k + 3
        return out

    def law_values(self, law: dict) -> np.ndarray:
        """Packed element parameters: per element its law parameters, then the small-signal equivalent's
        ``(k, s_rel0, d)`` (:data:`_LINEAR_KINDS`: a spring, a damper, both, or nothing)."""
        out = []
        for el in self.elements:
            vals = {n: law.get(f"{el.path}.{n}", el.values[n]) for n in el.pnames}
            lv = el.lin_values(vals)
            kind = type(el.lin).__name__ if el.lin is not None else None
            if kind is not None and kind not in _LINEAR_KINDS:
                raise CompiledModelError(f"{el.path}: small-signal equivalent {kind} is not supported "
                                         f"({', '.join(_LINEAR_KINDS)})")
            names = _LINEAR_KINDS.get(kind, (None, None, None))
            out += [vals[n] for n in el.pnames] + [lv.get(n, 0.0) if n else 0.0 for n in names]
        return np.array(out if out else [0.0], float)

    # ---- the linear part in modal coordinates --------------------------------------------------------
    def modal(self, params: dict | None = None, extra_damping: float = 0.0, delay: float = 0.0,
              damping_of: ModalModel | None = None, f_keep: float | None = None) -> ModalModel:
        """Modes, modal damping and residual flexibility of the linear part at ``params`` (cached: a change
        of a nonlinear element's parameter only re-runs the time integration). ``damping_of``: the modal damping is
        that model's, as a physical matrix ``M Phi diag(c) Phi^T M`` (the time series' linear part, whose contacts
        are cut, keeps the damping of the drive linearised at rest, as a flattened model's is); ``f_keep``: instead
        of the model's."""
        lin, _law, struct = self._split(dict(params or {}))
        key = (tuple(sorted(lin.items())), tuple(sorted(struct.items())), float(extra_damping), float(delay),
               getattr(damping_of, "serial", None), f_keep)
        return kept(self._modal_cache, key,
                    lambda: self._modal(lin, struct, extra_damping, delay, damping_of, f_keep or self.f_keep), 9)

    def _modal(self, lin, struct, extra_damping, delay, damping_of, f_keep):
        refl = {k: v for k, v in struct.items() if k in self._reflatten}
        if refl:
            d = flatten(self.linear_system.with_parameters(refl))
            so = second_order(d, refresh_damping=False, params=lin or None, **self._so_args)
            Cadd = sp.csr_matrix(d.system_damping_basis[2]) if self.damping is not None else None
        else:
            so = second_order(self.dae, refresh_damping=False, params=lin or None, **self._so_args) if lin else self.so0
            Cadd = self._Cadd0
        # the structural parameters' affine changes summed densely, in the order of the sparse sums they replace
        # (each entry the same IEEE operations: bit for bit; 13 sparse sums a call were ~1/3 of its time)
        Md, Kd = dense(so.M, float), dense(so.K, float)
        Csd = dense(so.C, float) - dense(Cadd, float) if Cadd is not None else dense(so.C, float)
        changed = False
        for k, v in struct.items():
            if k in self._sens:
                v0, dM, dK, dC = self._sens[k]
                Md, Kd, Csd = Md + (v - v0) * dM, Kd + (v - v0) * dK, Csd + (v - v0) * dC
                changed = True
        M, K = (sp.csr_matrix(Md), sp.csr_matrix(Kd)) if changed else (sp.csr_matrix(so.M), sp.csr_matrix(so.K))
        massless = np.flatnonzero(np.abs(np.diag(Md)) == 0)
        if massless.size:
            raise CompiledModelError(f"coordinates {[so.coordinates[i] for i in massless[:5]]} have no mass: give "
                                     "the joint a mass or use bscomp.simulate")
        lam, phi = sla.eigh(Kd, Md, check_finite=False)
        rigid = np.abs(lam) <= 1e-9 * np.max(np.abs(lam))
        lam = np.where(rigid, 0.0, lam)
        c, C_sys = self._damping(lam, phi, M, K, Md, rigid, extra_damping, damping_of)
        csd = Csd + C_sys
        w_keep = 2 * np.pi * f_keep
        # modes the inputs (measured and element forces) cannot excite or the outputs cannot see -- e.g.
        # the bending modes of the 6-DOF screw for an axial/torsional drive -- enter statically too
        om = np.sqrt(lam)
        b = np.max(np.abs(phi.T @ dense(so.B, float)), axis=1) if so.B.shape[1] else np.zeros(lam.size)
        g = np.max(np.abs(dense(so.Cq, float) @ phi) + om * np.abs(dense(so.Cv, float) @ phi)
                   + om ** 2 * np.abs(dense(so.Ca, float) @ phi), axis=0) if so.Cq.shape[0] else np.zeros(lam.size)
        seen = (b / max(b.max(), 1e-300)) * (g / max(g.max(), 1e-300)) > self.participation
        keep = np.flatnonzero((lam <= w_keep ** 2) & (seen | (lam == 0.0)))
        if not self.elements:        # with cut elements (a contact's own dashpot) the band stays: docs/validation.md
            keep = np.union1d(keep, damped_beyond_static(phi, lam, Csd, keep, w_keep))
        trunc = np.setdiff1d(np.arange(lam.size), keep)
        pk = phi[:, keep]
        Ckk = np.diag(c[keep]) + pk.T @ csd @ pk
        pt = phi[:, trunc]
        if np.any(lam[trunc] == 0.0):
            raise CompiledModelError("a rigid-body mode is not excited by the inputs: check the model's inputs")
        Rt = (pt / lam[trunc]) @ pt.T if trunc.size else np.zeros_like(Md)
        self.stats["evaluations"] += 1
        mm = ModalModel(lam, phi, Ckk, Rt, so, keep, delay, f_keep, c_modal=c, C_struct=csd)
        mm.C_system = C_sys
        return mm

    def _damping(self, lam, phi, M, K, Md, rigid, extra_damping, damping_of):
        """``(c, C_sys)``: modal damping ``2 zeta omega`` per mode and the system damping's physical matrix (a
        Rayleigh-type model; or, with ``damping_of``, that model's whole modal and system damping as a matrix)."""
        c, C_sys = np.zeros(lam.size), np.zeros_like(Md)
        if damping_of is not None:
            mp = Md @ damping_of.phi
            return c, (mp * damping_of.c_modal) @ mp.T + damping_of.C_system
        if self.damping is not None:
            coords = list(self.dae.mech.coordinate_names)
            if hasattr(self.damping, "modal_ratios"):
                c = 2.0 * np.asarray(self.damping.modal_ratios(lam, phi, M, coords), float) * np.sqrt(lam)
            else:
                C_sys = dense(system_damping_matrix(self.damping, M, K, coords), float)
        if extra_damping:
            c = c + np.where(rigid, 0.0, 2.0 * extra_damping * np.sqrt(lam))
        return c, C_sys

    # ---- FRF ------------------------------------------------------------------------------------------
    def frf(self, params, freqs, pairs, extra_damping: float = 0.0, delay: float = 0.0, mm: ModalModel = None,
            amplitude: dict | None = None, points: int = 256, tol: float = 1e-8, harmonics: int = 1):
        """``{(input, output): H(freqs)}`` of the linear equivalent at ``params``.

        With ``amplitude`` (``{input: A}``, the input's unit) the pairs of those inputs are the response to a sine
        of that amplitude by the describing function of the nonlinear elements (thesis Eq 5.7-5.9 laws, first
        harmonic: :class:`~bscomp.simulation.harmonic_balance.HarmonicBalance`, as :func:`bscomp.describing_frf` does
        on the flattened model; ``harmonics=h``: the odd orders up to ``2h - 1`` balanced too), the linear part
        being this modal model; a model without nonlinear elements has the same FRF at every amplitude.

        ``freqs`` must be positive and finite [Hz], every pair an ``(input, output)`` of this model, every amplitude
        a positive finite number for one of its inputs: else a named :class:`~bscomp.errors.UsageError`,
        :class:`~bscomp.errors.ArgumentTypeError` or :class:`~bscomp.errors.UnknownNameError`."""
        freqs, pairs, amp = check_frf(self, freqs, pairs, amplitude, extra_damping, delay, points, tol, harmonics)
        mm = mm or self.modal(params, extra_damping, delay)
        amp = amp if self.elements else {}
        out = {}
        small = [pq for pq in pairs if pq[0] not in amp]
        if small:
            ins = list(dict.fromkeys(i for i, _ in small))
            outs = list(dict.fromkeys(o for _, o in small))
            H = self._linear_map(mm, freqs, ins, outs, delay)
            out.update({(i, o): H[:, outs.index(o), ins.index(i)] for i, o in small})
        for inp in dict.fromkeys(i for i, _ in pairs if i in amp):
            outs = list(dict.fromkeys(o for i, o in pairs if i == inp))
            H = self._describing(mm, params, freqs, inp, outs, amp[inp], delay, points, tol, harmonics)
            out.update({(inp, o): H[:, k] for k, o in enumerate(outs)})
        return {pq: out[pq] for pq in pairs}

    @classmethod
    def _linear_map(cls, mm, freqs, inputs, outputs, delay=0.0):
        """:meth:`_modal_map` kept on ``mm`` (a copy returned): a fit's evaluations that change only a friction or a
        clearance -- finite-difference columns, screening scans -- meet the same linear part and frequencies again
        (40 % of the FRFs of the demo's diagnosis)."""
        f = np.asarray(freqs, float)
        key = (f.shape, hashlib.sha1(f.tobytes()).hexdigest(), tuple(inputs), tuple(outputs), float(delay))
        return kept(mm.__dict__.setdefault("_frf", {}), key, lambda: cls._modal_map(mm, f, inputs, outputs, delay),
                    16).copy()

    @staticmethod
    def _modal_map(mm, freqs, inputs, outputs, delay=0.0):
        """``H[freq, output, input]`` of the linear part (its inputs and outputs by name) at ``freqs``."""
        so = mm.so
        bi = [so.inputs.index(i) for i in inputs]
        yo = [so.outputs.index(o) for o in outputs]
        B = dense(so.B, float)[:, bi]
        Cq, Cv, Ca = (dense(m, float)[yo] for m in (so.Cq, so.Cv, so.Ca))
        D = dense(so.D, float)[yo][:, bi]
        return modal_frf(mm.lam, mm.phi, mm.c_modal, mm.C_struct, B, Cq, Cv, Ca, D, freqs, modes=mm.keep,
                         delay=delay)

    def _describing(self, mm, params, freqs, inp, outs, amplitude, delay, points, tol, harmonics=1):
        """``H[freq, output]`` of ``outs`` to ``inp`` at ``amplitude`` (:meth:`frf`)."""
        _lin, law, _struct = self._split(dict(params or {}))
        parts = self.law_slices(self.law_values(law))
        hb = HarmonicBalance([el.law for el in self.elements], [pe for pe, *_ in parts], self._el_rest[0::2],
                             self._el_rest[1::2], [kl for _, kl, _, _ in parts], [dl for *_, dl in parts], points,
                             harmonics)
        f = np.asarray(freqs, float)
        T = {k: self._modal_map(mm, k * f, [inp] + self.w_inputs, self.nl_outputs + outs) for k in hb.orders}
        if delay:                                 # the input is delayed, the element forces are not
            T[1][:, :, 0] *= np.exp(-2j * np.pi * f * delay)[:, None]
        Y, _S, _V, rel = hb.sweep(freqs, lambda i, k=1: T[k][i], amplitude, tol)
        self.stats["describing_residual"] = float(np.max(rel, initial=0.0))
        self.stats["describing_orders_min"] = 2 * int(np.min(hb.used, initial=len(hb.orders))) - 1
        return Y / amplitude

    # ---- time series ------------------------------------------------------------------------------------
