"""The hidden effects of the truth systems (:mod:`bscomp.systems.truths`): components whose structure no candidate
of :mod:`bscomp.validate.candidates` has (no class of it is imported here), and the damping rule for a body
detached from the drive.

* :class:`AtanFriction` -- guideway friction smoothed by an arc tangent (the candidates use ``tanh``);
* :class:`AtanTorqueFriction` -- the same law for a friction torque on the screw (its bearings and the nut);
* :class:`SoftBacklash` -- a clearance with softplus contact corners of finite stiffness;
* :class:`TorqueRipple` -- a motor's cogging torque, periodic in the motor angle (no candidate has one);
* :class:`RigidJointDamping` -- the drive's modal damping computed with a detached body joined rigidly.
* :class:`HeldBodyDamping` -- the same with bodies held (a housing taken as rigid, as the model has it).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from bscomp.components import Damper, Spring, TorsionalDamper
from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialCompliant, PartialRotCompliant

__all__ = ["AtanFriction", "AtanTorqueFriction", "atan_friction", "SoftBacklash", "TorqueRipple", "RigidJointDamping",
           "HeldBodyDamping",
           "softplus"]


def atan_friction(level, smoothing, d, rate):
    """``level (2/pi) atan(rate / smoothing) + d rate``: the truths' friction law, for a force or a torque (CasADi or
    float); Eq (5.7) as ``smoothing -> 0``."""
    return level * (2.0 / math.pi) * ca.atan(rate / smoothing) + d * rate


class AtanFriction(PartialCompliant):
    """Guideway friction smoothed by an arc tangent: ``f = F_c (2/pi) atan(v_rel / v_s) + d v_rel``.

    A truth's friction law, deliberately not the ``tanh`` regularisation of
    :class:`~components.coulomb_friction.CoulombFriction`: the Coulomb part approaches ``F_c`` only as
    ``1 - 2 v_s / (pi |v|)`` (an algebraic, not exponential, tail). The limit ``v_s -> 0`` is Eq (5.7).

    # Parameters
    - ``F_c`` [N]: Coulomb force magnitude (symmetric)
    - ``v_s`` [m/s]: smoothing velocity (> 0)
    - ``d`` [N.s/m]: viscous coefficient

    # Connectors
    - ``flange_a``, ``flange_b`` (``flange_a`` to a :class:`Fixed` for friction to ground)
    """

    F_c = Parameter(unit="N", min=0.0, doc="Coulomb force magnitude")
    v_s = Parameter(unit="m/s", positive=True, doc="smoothing velocity of atan(v / v_s)")
    d = Parameter(0.0, unit="N.s/m", min=0.0, doc="viscous coefficient")

    def force_law(self, s_rel, v_rel):
        """Friction force [N] at sliding velocity ``v_rel`` (CasADi expression or float)."""
        return atan_friction(self.F_c, self.v_s, self.d, v_rel)

    def equations(self):
        return [self.f - self.force_law(self.s_rel, self.v_rel)]

    def linear_equivalent(self):
        """For an FRF: the viscous part (the Coulomb part has no tangent while sliding)."""
        return Damper(d=self.d) if self.d > 0 else None


class AtanTorqueFriction(PartialRotCompliant):
    """A friction torque smoothed by an arc tangent: ``tau = T_c (2/pi) atan(w_rel / w_s) + d w_rel``.

    The truths' bearing and nut friction (``bearing_friction``): :class:`AtanFriction`'s law for a torque and the
    relative angular speed, placed on the screw at the thrust bearing (not at the rotor, where a candidate would put
    it). The limit ``w_s -> 0`` is Eq (5.7) for a torque.

    # Parameters
    - ``T_c`` [N.m]: Coulomb torque magnitude (symmetric)
    - ``w_s`` [rad/s]: smoothing speed (> 0)
    - ``d`` [N.m.s/rad]: viscous coefficient

    # Connectors
    - ``flange_a``, ``flange_b`` (``flange_a`` to a :class:`FixedRotational` for friction to ground)
    """

    T_c = Parameter(unit="N.m", min=0.0, doc="Coulomb torque magnitude")
    w_s = Parameter(unit="rad/s", positive=True, doc="smoothing speed of atan(w / w_s)")
    d = Parameter(0.0, unit="N.m.s/rad", min=0.0, doc="viscous coefficient")

    def force_law(self, phi_rel, w_rel):
        """Friction torque [N.m] at relative angular speed ``w_rel`` (CasADi expression or float)."""
        return atan_friction(self.T_c, self.w_s, self.d, w_rel)

    def equations(self):
        return [self.tau - self.force_law(self.phi_rel, self.w_rel)]

    def linear_equivalent(self):
        """For an FRF: the viscous part (the Coulomb part has no tangent while sliding)."""
        return TorsionalDamper(d=self.d) if self.d > 0 else None


def softplus(x, w):
    """``w log(1 + e^(x/w))``, written so that it does not overflow (CasADi or float)."""
    return ca.fmax(x, 0) + w * ca.log1p(ca.exp(-ca.fabs(x) / w))


class SoftBacklash(PartialCompliant):
    """Clearance of total width ``b`` with a contact of stiffness ``c`` switched in over a width ``w``.

    ``f = c [softplus(delta - b/2) - softplus(-delta - b/2)]``, ``delta = s_rel``, ``softplus(x) =
    w log(1 + e^{x/w})``: C-infinity, zero force in the middle of the gap (``c w e^{-b/2w}``, 5e-9 of
    ``c b`` for ``w = 0.05 b``), slope ``c`` in contact with the clearance shifted by ``w log 2`` at the edge.
    Not the dead zone with bounded damping of :class:`~components.backlash.Backlash`: no contact damping
    (the table is damped through the drive, :class:`RigidJointDamping`).

    # Parameters
    - ``b`` [m]: total clearance; ``c`` [N/m]: contact stiffness; ``w`` [m]: transition width
    """

    b = Parameter(unit="m", min=0.0, doc="total clearance")
    c = Parameter(unit="N/m", positive=True, doc="contact stiffness")
    w = Parameter(unit="m", positive=True, doc="width of the smooth contact transition")

    def force_law(self, s_rel, v_rel):
        return self.c * (softplus(s_rel - self.b / 2, self.w) - softplus(-s_rel - self.b / 2, self.w))

    def equations(self):
        return [self.f - self.force_law(self.s_rel, self.v_rel)]

    def linear_equivalent(self):
        """For an FRF (excitation large against the gap, contact engaged): the contact spring."""
        return Spring(c=self.c)


class TorqueRipple(PartialRotCompliant):
    """A motor's torque ripple (cogging) between the frame and the rotor: ``tau = A sin(p phi_rel + phi_0)``.

    Not a candidate of the diagnosis (no class of :mod:`bscomp.validate.candidates` makes a torque periodic
    in the motor angle): the ``ripple`` truth tests that a diagnosis leaves an effect outside its library
    unexplained instead of naming a wrong one. Its FRF is that of the drive without it (``linear_equivalent``
    None: an FRF measured while the drive creeps through many ripple periods sees the ripple averaged out; at a
    standstill it would act as a spring ``A p cos(p phi + phi_0)`` of either sign).

    # Parameters
    - ``A`` [N.m]: amplitude; ``p`` [1]: periods per revolution; ``phi_0`` [rad]: phase at ``phi_rel = 0``
    """

    A = Parameter(unit="N.m", min=0.0, doc="ripple amplitude")
    p = Parameter(unit="1", positive=True, doc="ripple periods per revolution")
    phi_0 = Parameter(0.0, unit="rad", doc="phase at phi_rel = 0")

    def torque_law(self, phi_rel):
        """Ripple torque [N m] at the rotor angle ``phi_rel`` (CasADi expression or float)."""
        return self.A * ca.sin(self.p * phi_rel + self.phi_0)

    def equations(self):
        return [self.tau - self.torque_law(self.phi_rel)]

    def linear_equivalent(self):
        """None: the FRF of the drive without the ripple (class docstring)."""
        return None


class RigidJointDamping:
    """The drive's modal damping computed with a detached body joined rigidly to what it is attached to.

    Modal damping (:class:`~bscomp.systems.testbed.DriveModalDamping`, Tables 4.1/4.2) describes the drive
    as measured with the table bolted to the nut. A truth whose table part rides on its own spring
    (``joint``) or whose table is separated from the nut by a clearance (``backlash``) keeps that damping
    for the drive, evaluated with the body's mass lumped on the coordinate it is attached to and the joint
    between them removed; the joint's own dashpot (or nothing, in the gap) is all that acts between them.
    So no damping force crosses an open clearance, and an extra mode is damped by its own dashpot.
    """

    needs_coordinates = True

    def __init__(self, base, body: str):
        self.base, self.body = base, body

    def matrix(self, M, K, coordinates=None):
        M = M.toarray() if hasattr(M, "toarray") else np.array(M, float)
        K = K.toarray() if hasattr(K, "toarray") else np.array(K, float)
        names = list(coordinates)
        i = names.index(self.body)
        row = K[i].copy()
        row[i] = 0.0
        if np.any(np.delete(M[i], i) != 0.0):
            raise ValueError(f"RigidJointDamping: {self.body} is inertially coupled to other coordinates")
        nz = np.flatnonzero(row)
        if nz.size != 1:
            raise ValueError(f"RigidJointDamping: {self.body} must be joined to exactly one coordinate, found "
                             f"{[names[n] for n in nz]}")
        j = int(nz[0])
        keep = [n for n in range(len(names)) if n != i]
        M2, K2 = M[np.ix_(keep, keep)].copy(), K[np.ix_(keep, keep)].copy()
        jj = keep.index(j)
        M2[jj, jj] += M[i, i]                       # the body rides rigidly on coordinate j (direction +-1)
        K2[jj, jj] -= abs(K[i, j])                  # ... and the joint between them is removed
        C = np.zeros_like(M)
        C[np.ix_(keep, keep)] = np.asarray(
            self.base.matrix(M2, K2, coordinates=[names[n] for n in keep]), float)
        return C

    def __repr__(self):
        return f"RigidJointDamping({self.base!r}, body={self.body!r})"


class HeldBodyDamping:
    """The drive's modal damping computed with some coordinates held at zero (bodies taken as rigidly grounded).

    The ``housing`` truth un-grounds the thrust bearing: the drive's modal damping
    (:class:`~bscomp.systems.testbed.DriveModalDamping`) is that of the drive with the rigid housing the model
    has, so it is evaluated on ``M``, ``K`` without the housing's coordinates (the bearing's spring then acts
    to ground, as in the model); the housing's own dashpots are all that damp its bodies.
    """

    needs_coordinates = True

    def __init__(self, base, held):
        self.base, self.held = base, tuple(held)

    def matrix(self, M, K, coordinates=None):
        M = M.toarray() if hasattr(M, "toarray") else np.array(M, float)
        K = K.toarray() if hasattr(K, "toarray") else np.array(K, float)
        names = list(coordinates)
        missing = [n for n in self.held if n not in names]
        if missing:
            raise ValueError(f"HeldBodyDamping: no coordinate(s) {missing} in the model")
        keep = [i for i, n in enumerate(names) if n not in self.held]
        C = np.zeros_like(M)
        C[np.ix_(keep, keep)] = np.asarray(self.base.matrix(M[np.ix_(keep, keep)], K[np.ix_(keep, keep)],
                                                            coordinates=[names[i] for i in keep]), float)
        return C

    def __repr__(self):
        return f"HeldBodyDamping({self.base!r}, held={self.held!r})"
