"""Effects an evaluation engine can apply outside the model: extra modal damping and the amplifier delay.

Both are also real model edits (:class:`AddedModalDamping` as the system damping, a Padé delay in the
signal line), so an updated System carries them; :meth:`~.base.Candidate.engine_hooks` tells an engine
to apply them exactly instead (``structure(..., for_engine=True)`` leaves the model unchanged).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from bscomp.components import Damper, Spring, TorsionalDamper, TorsionalSpring
from bscomp.components.pade_delay import PadeDelay
from bscomp.kernel.damping import matrix_from_ratios, modal_damping_matrix
from bscomp.kernel.interface import NotApplicable
from bscomp.kernel.system_damping import system_damping_matrix
from bscomp.memo import kept
from bscomp.validate.candidates._edits import insert_series
from bscomp.validate.candidates.base import Candidate, CandidateParameter, _state

__all__ = ["AddedModalDamping", "AddedDampingOnMatrix", "DetachedBodyDamping", "ExtraDamping", "AmplifierDelay"]


class AddedModalDamping:
    """System-level damping: a base option with ``modal_ratios`` plus ``zeta`` on every elastic mode.

    Wraps e.g. :class:`~bscomp.systems.testbed.DriveModalDamping`; rigid-body modes stay undamped
    (Sec 5.2.2.1). The matrix follows Eq A.10-A.15 (:func:`bscomp.kernel.damping.modal_damping_matrix`).
    """

    needs_coordinates = True

    def __init__(self, base, zeta: float):
        self.base = base
        self.zeta = float(zeta)

    def modal_ratios(self, lam, phi, M, coordinates=None) -> np.ndarray:
        if getattr(self.base, "needs_coordinates", False):
            z = np.asarray(self.base.modal_ratios(lam, phi, M, coordinates), float)
        else:
            z = np.asarray(self.base.modal_ratios(lam, phi, M), float)
        rigid = np.abs(lam) <= 1e-9 * np.max(np.abs(lam))
        z = z + self.zeta
        z[rigid] = 0.0
        return z

    def matrix(self, M, K, coordinates=None):
        return matrix_from_ratios(self, M, K, coordinates)

    def __repr__(self):
        return f"AddedModalDamping({self.base!r}, zeta={self.zeta:g})"


class AddedDampingOnMatrix:
    """A base system damping given only as a matrix (e.g. :class:`DetachedBodyDamping`) plus ``zeta`` of
    modal damping on every elastic mode (Eq A.10-A.15); rigid-body modes stay undamped."""

    needs_coordinates = True

    def __init__(self, base, zeta: float):
        self.base = base
        self.zeta = float(zeta)

    def matrix(self, M, K, coordinates=None):
        Md = M.toarray() if hasattr(M, "toarray") else np.asarray(M)
        Kd = K.toarray() if hasattr(K, "toarray") else np.asarray(K)
        # modal_damping_matrix: one eigh, the rigid modes (undamped) found by the same rule as the other options
        return (np.asarray(system_damping_matrix(self.base, Md, Kd, coordinates), float)
                + modal_damping_matrix(Md, Kd, self.zeta))

    def __repr__(self):
        return f"AddedDampingOnMatrix({self.base!r}, zeta={self.zeta:g})"


class DetachedBodyDamping:
    """System-level damping of a drive to which an effect attached a body on its own joint.

    The drive's damping (e.g. the modal ratios of Tables 4.1/4.2) describes the drive as measured, the
    body part of the drive; a body the effect adds on its own spring and dashpot (a table sub-assembly)
    is damped by that dashpot alone. So the base option's matrix is computed on the drive with each body
    lumped rigidly on the coordinate its joint attaches it to (the joint removed), and embedded with no
    damping on the body's own coordinate: the added mode neither takes the place of the drive's first or
    second mode nor changes the damping forces among the drive's coordinates. A body joined to more than
    one coordinate (another effect attached to it) stays part of the drive.

    ``held`` bodies are taken out instead, as if grounded (a bearing housing: the drive's damping was measured
    with the housing the model has, rigid; the bearing's spring stays on the screw's diagonal).
    """

    needs_coordinates = True

    def __init__(self, base, bodies, held=()):
        self.base = base
        self.bodies = list(bodies)
        self.held = list(held)

    def matrix(self, M, K, coordinates=None):
        M = M.toarray() if hasattr(M, "toarray") else np.array(M, float)
        K = K.toarray() if hasattr(K, "toarray") else np.array(K, float)
        names = list(coordinates)
        drop = [names.index(b) for b in self.held]
        M2, K2 = M.copy(), K.copy()
        for b in self.bodies:
            i = names.index(b)
            row = K[i].copy()
            row[i] = 0.0
            j = np.flatnonzero(row)
            if j.size > 1 or np.any(np.delete(M[i], i) != 0.0):
                continue                     # joined to several coordinates: it stays part of the drive
            if j.size:                       # (none: linearized inside a clearance, the body is free)
                j = int(j[0])
                M2[j, j] += M[i, i]          # the body rides rigidly on coordinate j (direction +-1)
                K2[j, j] -= abs(row[j])      # ... and its joint's stiffness leaves the drive
            drop.append(i)
        keep = [n for n in range(len(names)) if n not in drop]
        C = np.zeros_like(M)
        C[np.ix_(keep, keep)] = self._base_matrix(M2[np.ix_(keep, keep)], K2[np.ix_(keep, keep)],
                                                  [names[n] for n in keep])
        return C

    def _base_matrix(self, M, K, names):
        """The base option's matrix of the drive without the bodies, kept for the same matrices and base: the
        body's own joint leaves the lumped drive, so a fit that varies it (and a friction, a clearance) meets the
        same drive again (60 % of the damping matrices of the demo's diagnosis)."""
        key = (repr(self.base), tuple(names), hashlib.sha1(np.ascontiguousarray(M).tobytes()
                                                             + np.ascontiguousarray(K).tobytes()).hexdigest())
        return kept(self.__dict__.setdefault("_memo", {}), key,
                    lambda: np.asarray(system_damping_matrix(self.base, M, K, names), float), 16)

    def __repr__(self):
        held = f", held={self.held!r}" if self.held else ""
        return f"DetachedBodyDamping({self.base!r}, bodies={self.bodies!r}{held})"


class ExtraDamping(Candidate):
    """Extra damping of every elastic mode (the ``structure`` point).

    On a drive with system-level modal damping (``system.damping`` with ``modal_ratios``, e.g. the FE
    test bed's :class:`~bscomp.systems.testbed.DriveModalDamping`): ``zeta`` added to every elastic
    mode's ratio (:class:`AddedModalDamping`); an evaluation engine gets it as the hook
    ``{"extra_modal_damping": zeta}``. Otherwise (lumped drive) stiffness-proportional: a damper
    ``d = beta c`` beside every spring, so mode *i* gains ``zeta_i = zeta (f_i / f_1)`` with ``f_1`` the
    first elastic mode of the nominal model: ``f1`` [Hz] if given, else the ``frequency`` the drive
    declares on its ``structure`` insertion point (not applicable when neither names it).
    """

    def __init__(self, f1: float | None = None):
        super().__init__(
            name="extra_damping", title="extra modal damping", role="structure",
            parameters=[CandidateParameter("zeta", "1", 1e-3, 0.3, 0.02, 1.0, "added damping ratio (at f_1)")],
            signature="resonance peaks lower and broader than modelled at unchanged frequencies; ringing after "
                      "each step dies out faster than the model's",
            group="damping", kinds=("all",))
        self.f1 = f1

    def _edit(self, e, point, vi, for_engine):
        base = e.s.damping
        if base is not None and (hasattr(base, "modal_ratios") or hasattr(base, "matrix")):
            if not for_engine:
                cls = AddedModalDamping if hasattr(base, "modal_ratios") else AddedDampingOnMatrix
                e.s.damping = cls(base, self.parameters[0].median)
            return {"mode": "modal", "engine": bool(for_engine)}
        effects = {n for st in (getattr(e.s, "_effect_state", {}) or {}).values() for n in st.get("added", ())}
        springs = [(p, c) for p, c in e.s.leaves() if isinstance(c, (Spring, TorsionalSpring))
                   and p.split(".")[0] not in effects]
        if not springs:
            raise NotApplicable(f"{self.name}: '{e.s.name}' has neither modal damping (system.damping with "
                                "modal_ratios) nor springs to put dampers beside")
        dampers = {}
        for path, comp in springs:
            name = e.unique(f"extra_loss_{path.replace('.', '_')}")
            e.add(name, Damper if isinstance(comp, Spring) else TorsionalDamper, d=0.0)
            e.connect(f"{name}.flange_a", f"{path}.flange_a")
            e.connect(f"{name}.flange_b", f"{path}.flange_b")
            dampers[name] = float(comp.get("c"))
        return {"mode": "springs", "dampers": dampers, "f1": self._reference_frequency(e.s, point)}

    def _reference_frequency(self, system, point) -> float:
        f1 = self.f1 if self.f1 is not None else point.frequency
        if f1 is None:
            raise NotApplicable(f"{self.name}: stiffness-proportional damping is stated at the first elastic mode "
                                f"f_1, which '{system.name}' does not declare (InsertionPoint('structure', 'all', "
                                "frequency=...)); give ExtraDamping(f1=...) [Hz]")
        return float(f1)

    def _overrides(self, values, state):
        if state["mode"] == "modal":
            return {}
        beta = 2 * values["zeta"] / (2 * math.pi * state["f1"])
        return {f"{name}.d": beta * c for name, c in state["dampers"].items()}

    def _assign_extra(self, system, values, state):
        if state["mode"] == "modal" and isinstance(system.damping, (AddedModalDamping, AddedDampingOnMatrix)):
            system.damping.zeta = float(values["zeta"])

    def _extra_code(self, values, state):
        if state["mode"] != "modal":
            return []
        return ["from bscomp.validate.candidates import AddedModalDamping, AddedDampingOnMatrix",
                "s.damping = (AddedModalDamping if hasattr(s.damping, 'modal_ratios') else AddedDampingOnMatrix)("
                f"s.damping, zeta={values['zeta']:.10g})"]

    def engine_hooks(self, values, system=None):
        if system is not None and _state(system, self).get("mode") != "modal":
            return {}
        return {"extra_modal_damping": float(values["zeta"])}


class AmplifierDelay(Candidate):
    """D/A converter + amplifier latency ``T`` in the signal line of the ``amplifier`` point.

    In the model: a Padé delay (:class:`~components.pade_delay.PadeDelay`, order 2) inserted in the line,
    so an updated System runs anywhere. An evaluation engine applies the delay exactly instead
    (``exact_delay``; ``e^{-j omega T}`` on FRFs, a shift of the input in time) from
    :meth:`engine_hooks`, with ``structure(..., for_engine=True)`` leaving the model unchanged.
    """

    exact_delay = True

    def __init__(self, order: int = 2):
        super().__init__(
            name="amplifier_delay", title="amplifier / D/A time delay", role="amplifier",
            parameters=[CandidateParameter("T", "s", 1e-5, 5e-3, 3e-4, 1.2, "time delay")],
            signature="phase lag growing linearly with frequency in every FRF at unchanged magnitude; the "
                      "response to each voltage step starts late",
            group="delay", kinds=("connection",))
        self.order = order

    def _edit(self, e, point, vi, for_engine):
        if for_engine:
            return {"delay": None}
        a, b = point.ports[:2]
        name = e.unique("delay")
        insert_series(e, name, PadeDelay, {"order": self.order, "T": 3e-4}, a, b, ports=("u", "y"))
        return {"delay": name}

    def _overrides(self, values, state):
        return {} if state["delay"] is None else {f"{state['delay']}.T": values["T"]}

    def engine_hooks(self, values, system=None):
        return {"input_delay": float(values["T"])}
