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

from bscomp.kernel.component import Parameter

from ._friction import PartialFriction, coulomb_viscous


class CoulombFriction(PartialFriction):
    """Regularised Coulomb + viscous friction, Eq (5.7), with asymmetric ``+/-`` constants.

    Parameters
    ----------
    F_c, d : float, optional
        Set both directions at once (symmetric friction): ``F_c_pos = F_c_neg = F_c`` [N],
        ``d_pos = d_neg = d`` [N.s/m].

    Attributes
    ----------
    flange_a, flange_b : Flange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialCompliant`; force law, equation, power
        and viscous FRF equivalent from :class:`components._friction.PartialFriction`).
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

    SYMMETRIC = ("F_c", "d")     # F_c=, d= set both directions at once (symmetric friction)

    def friction_force(self, v):
        """Regularised friction force [N] at sliding velocity ``v`` (CasADi or float)."""
        return coulomb_viscous(v, self.F_c_pos, self.F_c_neg, self.d_pos, self.d_neg, self.v_reg)
