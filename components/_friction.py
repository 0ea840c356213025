"""What the friction laws share (:class:`~components.coulomb_friction.CoulombFriction`, Eq 5.7,
:class:`~components.stribeck_friction.StribeckFriction`, Eq 5.6, and the rotational
:class:`~components.rotational_friction.RotationalFriction`): a two-flange element whose force (torque) is a law of
the sliding velocity with ``+/-`` constants blended by ``w^{\\pm} = (1 \\pm \\tanh(v/v_{reg}))/2``, symmetric
short-hand parameters, the dissipated power and the small-signal (viscous) equivalent for FRFs."""

import casadi as ca

from bscomp.kernel.partials import PartialCompliant, PartialRotCompliant

from .damper import Damper
from .torsional_damper import TorsionalDamper


def coulomb_viscous(v, c_pos, c_neg, d_pos, d_neg, v_reg):
    """Regularised Coulomb + viscous law (Eq 5.7, module docstring of ``coulomb_friction``) at velocity ``v``:
    ``sigma (w+ c+ + w- c-) + (w+ d+ + w- d-) v`` with ``sigma = tanh(v / v_reg)``, ``w+- = (1 +- sigma) / 2``."""
    sig = ca.tanh(v / v_reg)
    wp, wn = 0.5 * (1 + sig), 0.5 * (1 - sig)
    return sig * (wp * c_pos + wn * c_neg) + (wp * d_pos + wn * d_neg) * v


class _Symmetric:
    """Short-hand parameters: each name ``x`` in :attr:`SYMMETRIC` sets ``x_pos`` and ``x_neg`` at once."""

    SYMMETRIC: tuple = ()

    def __init__(self, **params):
        for short in self.SYMMETRIC:
            value = params.pop(short, None)
            if value is not None:
                params.setdefault(f"{short}_pos", value)
                params.setdefault(f"{short}_neg", value)
        super().__init__(**params)


class PartialFriction(_Symmetric, PartialCompliant):
    """Base of the regularised friction laws: a subclass sets :attr:`SYMMETRIC` (the short names ``x`` that set
    ``x_pos`` and ``x_neg`` at once) and defines :meth:`friction_force`; it needs parameters ``d_pos``, ``d_neg``."""

    def friction_force(self, v):     # pragma: no cover - every law defines it
        raise NotImplementedError

    def linear_equivalent(self):
        """Small-signal equivalent for FRFs: the viscous part only (Coulomb friction has no tangent at
        sliding; at rest its regularised slope F_c/v_reg is not what a swept-sine test sees)."""
        d = 0.5 * (self.d_pos + self.d_neg)
        return Damper(d=d) if d > 0 else None

    def force_law(self, s_rel, v_rel):
        """Element force ``f(s_rel, v_rel)`` (the regularised law): what :meth:`equations` states, and what a
        compiled simulator evaluates with parameters as symbols."""
        return self.friction_force(v_rel)

    def equations(self):
        return [self.f - self.force_law(self.s_rel, self.v_rel)]

    def observables(self):
        out = super().observables()
        out["power"] = self.f * self.v_rel
        return out


class PartialRotFriction(_Symmetric, PartialRotCompliant):
    """The rotational twin of :class:`PartialFriction`: a torque law of the relative angular speed ``w_rel``
    (:meth:`friction_torque`), between two rotational flanges; parameters ``d_pos``, ``d_neg`` [N.m.s/rad]."""

    def friction_torque(self, w):     # pragma: no cover - every law defines it
        raise NotImplementedError

    def linear_equivalent(self):
        """Small-signal equivalent for FRFs: the viscous part only (as :meth:`PartialFriction.linear_equivalent`)."""
        d = 0.5 * (self.d_pos + self.d_neg)
        return TorsionalDamper(d=d) if d > 0 else None

    def force_law(self, phi_rel, w_rel):
        """Element torque ``tau(phi_rel, w_rel)`` (the regularised law), as :meth:`PartialFriction.force_law`:
        the compiled simulators evaluate it with parameters as symbols."""
        return self.friction_torque(w_rel)

    def equations(self):
        return [self.tau - self.force_law(self.phi_rel, self.w_rel)]

    def observables(self):
        out = super().observables()
        out["power"] = self.tau * self.w_rel
        return out
