"""Coulomb + viscous friction between two flanges (thesis Eq 5.7), regularised for IDAS.

Thesis Eq (5.7), the limit ``V1, V2 -> 0`` of the Stribeck law (5.6), gives the force of a sliding
interface (the guideways, Sec 5.2.2.1) as

.. math:: F_f^{\\pm}(v) = F_{coul}^{\\pm} + B^{\\pm} v,

with the sign of the sliding velocity ``v`` choosing the ``+`` or ``-`` constants. The sign function is
discontinuous at ``v = 0`` and CasADi 3.8's ``idas`` ignores zero-crossing events (casadi#4393), so the
law is **regularised**:

.. math::

    \\sigma = \\tanh(v / v_{reg}), \\qquad
    f = \\sigma \\Big(\\tfrac{1+\\sigma}{2} F_c^{+} + \\tfrac{1-\\sigma}{2} F_c^{-}\\Big)
        + \\Big(\\tfrac{1+\\sigma}{2} d^{+} + \\tfrac{1-\\sigma}{2} d^{-}\\Big) v .

For ``|v| >> v_reg`` this is Eq (5.7) exactly (``sigma = ±1``); the ``+/-`` constants are blended with
the same ``sigma`` so the law stays smooth (C-infinity) at ``v = 0``. Sticking is replaced by a very
steep viscous branch of slope ``F_c / v_reg``: below the breakaway force an interface **creeps** at
``v = v_reg artanh(F / F_c)`` instead of holding exactly. Errors measured against the exact
piecewise-analytic Coulomb oscillator are in ``docs/nonlinear.md``; choose ``v_reg`` about 1e-3 of the
smallest sliding speed of interest.

Sign convention (as :class:`~components.damper.Damper`): ``v_rel = der(flange_b.s - flange_a.s)``; the
element force ``f`` is positive when ``v_rel > 0`` and acts as ``-f`` on ``flange_b``'s body, so it always
opposes the relative sliding. Connect ``flange_a`` to a :class:`~components.fixed.Fixed` for friction
to ground. Mechanical power dissipated: ``f v_rel >= 0``.
"""

import casadi as ca

from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialCompliant

from .damper import Damper


class CoulombFriction(PartialCompliant):
    """Regularised Coulomb + viscous friction, Eq (5.7), with asymmetric ``+/-`` constants.

    Parameters
    ----------
    F_c, d : float, optional
        Set both directions at once (symmetric friction): ``F_c_pos = F_c_neg = F_c`` [N],
        ``d_pos = d_neg = d`` [N.s/m].

    Attributes
    ----------
    flange_a, flange_b : Flange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialCompliant`).
    f, s_rel, v_rel : observable
        Friction force [N], relative position [m] and relative velocity [m/s].
    power : observable
        Dissipated power [W] (``f v_rel >= 0``).
    """

    F_c_pos = Parameter(unit="N", min=0.0, doc="Coulomb force magnitude F_coul^+ for v_rel > 0 "
                      "(Table 5.2: 2066 N)")
    F_c_neg = Parameter(unit="N", min=0.0, doc="Coulomb force magnitude |F_coul^-| for v_rel < 0 "
                      "(Table 5.2: 2066 N)")
    d_pos = Parameter(0.0, unit="N.s/m", min=0.0, doc="viscous coefficient B for v_rel > 0 (Table 5.2: 12673 N.s/m)")
    d_neg = Parameter(0.0, unit="N.s/m", min=0.0, doc="viscous coefficient B for v_rel < 0 (Table 5.2: 12673 N.s/m)")
    v_reg = Parameter(1.0e-4, unit="m/s", positive=True, doc="regularisation velocity of tanh(v_rel/v_reg)")

    def __init__(self, F_c=None, d=None, **params):
        """``F_c=`` and ``d=`` set both directions at once (symmetric friction)."""
        if F_c is not None:
            params.setdefault("F_c_pos", F_c)
            params.setdefault("F_c_neg", F_c)
        if d is not None:
            params.setdefault("d_pos", d)
            params.setdefault("d_neg", d)
        super().__init__(**params)

    def friction_force(self, v):
        """Regularised friction force [N] at sliding velocity ``v`` (CasADi or float)."""
        sig = ca.tanh(v / self.v_reg)
        wp, wn = 0.5 * (1 + sig), 0.5 * (1 - sig)
        return sig * (wp * self.F_c_pos + wn * self.F_c_neg) + (wp * self.d_pos + wn * self.d_neg) * v

    def linear_equivalent(self):
        """Small-signal equivalent for FRFs: the viscous part only (Coulomb friction has no tangent at
        sliding; at rest its regularised slope F_c/v_reg is not what a swept-sine test sees)."""

        d = 0.5 * (self.d_pos + self.d_neg)
        return Damper(d=d) if d > 0 else None

    def force_law(self, s_rel, v_rel):
        """Element force ``f(s_rel, v_rel)`` (Eq 5.7, regularised): what :meth:`equations` states, and what
        a compiled simulator evaluates with parameters as symbols."""
        return self.friction_force(v_rel)

    def equations(self):
        return [self.f - self.force_law(self.s_rel, self.v_rel)]

    def observables(self):
        out = super().observables()
        out["power"] = self.f * self.v_rel
        return out
