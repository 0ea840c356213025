"""Rigid body with lumped inertia at its centre of mass (rotor, nut, table; thesis Sec 3.3.2).

The 6x6 mass matrix at the centre of mass (COM), Eq (3.2),

.. math:: M = \\operatorname{diag}(m, m, m, I),\\qquad I = [I_{ij}]_{3\\times 3}

acts on the ``com`` port. Each attachment point P at offset ``r`` (from the COM to P, body axes =
global axes, small rotations) moves with the body through Eq (3.3)-(3.4),

.. math:: d_P = T_{P-COM}\\, d_{COM},\\qquad T_{P-COM} = \\begin{bmatrix} I & -S(r) \\\\ 0 & I\\end{bmatrix}

written as ideal constraints; forces at P reach the COM as ``T^T F_P`` (Eq 3.5) through the kernel's
constraint reactions. ``dofs`` restricts the body's motion: a table that only slides along the screw
(``("w",)``, Sec 3.5.1), a rotor that only spins (``("tz",)``); the other COM potentials are
constrained to zero, so the body adds exactly ``len(dofs)`` coordinates.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ModelDefinitionError, ParameterError
from bscomp.kernel.component import Component, Constraint, LinearStructure, Parameter
from bscomp.kernel.ports import Node6

from ._node_dofs import DOF_NAMES, check_dofs, pin_unused, t_point_com


class RigidBody(Component):
    """Lumped rigid body: mass ``m`` and inertia tensor ``I`` at the COM, Eq (3.2)-(3.5).

    Parameters
    ----------
    points : dict of str -> array (3,)
        Attachment points: port name -> offset r = P - COM [m]. One Node6 port each.
    dofs : tuple of str
        COM motions kept, subset of ``("u", "v", "w", "tx", "ty", "tz")``.

    Attributes
    ----------
    com : Node6
        Centre of mass (optional).
    <point> : Node6
        One port per entry of ``points`` (optional).
    kinetic_energy : observable
        Kinetic energy [J].
    """

    com = Node6("centre of mass")
    m = Parameter(0.0, unit="kg", min=0.0, doc="mass (may be 0 only if no translation is kept)")
    I = Parameter(np.zeros((3, 3)), unit="kg.m^2", doc="inertia tensor at the COM (Eq 3.2): 3x3 symmetric, or a "
                  "3-vector of principal moments; only its kept rows matter")

    def __init__(self, points: dict | None = None, dofs=DOF_NAMES, **params):
        if "I" in params and np.ndim(params["I"]) == 1:
            params["I"] = np.diag(np.asarray(params["I"], dtype=float))
        super().__init__(**params)
        self.dofs = check_dofs(dofs, "RigidBody")
        self.points = {}
        for name, r in (points or {}).items():
            r = np.asarray(r, dtype=float)
            if r.shape != (3,):
                raise ModelDefinitionError(f"RigidBody point '{name}': offset must be a 3-vector, got {r!r}")
            self.points[name] = r
            self.add_port(name, Node6(f"attachment point at r = {tuple(r)} m from the COM (Eq 3.3)"))

    def check(self, values):
        """``I`` is a symmetric 3x3 tensor (Eq 3.2): a non-symmetric one is an input error, not symmetrised."""
        I = np.asarray(values["I"], dtype=float)
        if I.shape != (3, 3):
            raise ParameterError(f"{self._where('I')}: the inertia tensor must be 3x3 (the constructor also takes a "
                                 f"3-vector of principal moments), got shape {I.shape}")
        scale = np.abs(I).max()
        if np.abs(I - I.T).max() > 1e-9 * scale:
            raise ParameterError(f"{self._where('I')}: the inertia tensor must be symmetric (I_ij = I_ji, Eq 3.2), "
                                 f"got {I.tolist()}; largest asymmetry |I - I^T| = {np.abs(I - I.T).max():.6g} "
                                 "kg.m^2")

    def template_key(self):
        """Instance configuration baked into the constraints (kept dofs, attachment offsets)."""
        return (self.dofs, tuple((n, tuple(r)) for n, r in self.points.items()))

    def mass_matrix(self, m=None, I=None) -> np.ndarray:
        """The full 6x6 mass matrix of Eq (3.2) at the COM."""
        m = self.m if m is None else m
        I = np.asarray(self.I if I is None else I, dtype=float)
        M = np.zeros((6, 6))
        M[:3, :3] = m * np.eye(3)
        M[3:, 3:] = 0.5 * (I + I.T)
        return M

    def structure(self):
        keep = [DOF_NAMES.index(d) for d in self.dofs]
        Mk = self.mass_matrix(self.m, self.I)[np.ix_(keep, keep)]
        if np.any(np.linalg.eigvalsh(Mk) <= 0.0):
            raise ParameterError(f"RigidBody '{self._display_name()}': the mass matrix of the kept dofs "
                                 f"{self.dofs} is not positive definite (m = {self.m} kg, "
                                 f"I = {np.asarray(self.I).tolist()})")
        return LinearStructure(dofs=[f"com.{d}" for d in self.dofs], M=Mk)

    def constraints(self):
        cons = pin_unused(self.com, self.dofs)
        for name, r in self.points.items():
            port = getattr(self, name)
            T = t_point_com(r)
            for k, d in enumerate(DOF_NAMES):
                expr = getattr(port, d)
                for j, dj in enumerate(DOF_NAMES):
                    if T[k, j] != 0.0 and dj in self.dofs:
                        expr = expr - float(T[k, j]) * getattr(self.com, dj)
                cons.append(Constraint(expr, solve_for=getattr(port, d)))
        return cons

    def observables(self):
        v = self.der(self.com.d)
        vt, om = v[:3], v[3:]
        return {"kinetic_energy": 0.5 * (self.m * (vt.T @ vt) + om.T @ self.I @ om)}
