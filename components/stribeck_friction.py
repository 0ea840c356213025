"""Stribeck friction between two flanges (thesis Eq 5.6), regularised for IDAS.

Thesis Eq (5.6) (its ref [14]) gives the friction of a lubricated sliding
interface over the static, boundary, partial-fluid and full-fluid regions of the Stribeck curve
(Fig 5.3):

.. math::

    F_f^{\\pm}(v) = F_{stat}^{\\pm} e^{-|v|/V_1^{\\pm}}
        + F_{coul}^{\\pm}\\big(1 - e^{-|v|/V_2^{\\pm}}\\big) + B^{\\pm} |v|,

applied against the sliding direction, with the ``+`` or ``-`` constants by the sign of ``v``. ``V1``
sets the drop from the static (breakaway) force, ``V2`` the rise to the Coulomb level; ``V1, V2 -> 0``
gives Eq (5.7) (:class:`~components.coulomb_friction.CoulombFriction`). Like that class, the sign
function is **regularised** because CasADi 3.8's ``idas`` ignores zero-crossing events (casadi#4393):

.. math::

    \\sigma = \\tanh(v/v_{reg}), \\quad w^{\\pm} = \\tfrac{1 \\pm \\sigma}{2}, \\quad
    f = \\sigma \\sum_{\\pm} w^{\\pm}\\Big(F_{stat}^{\\pm} e^{-|v|/V_1^{\\pm}}
        + F_{coul}^{\\pm}\\big(1 - e^{-|v|/V_2^{\\pm}}\\big)\\Big) + \\sum_{\\pm} w^{\\pm} B^{\\pm} v .

For ``|v| >> v_reg`` it is Eq (5.6) exactly. The largest force the regularised law can resist, i.e. the
effective breakaway force, is ``F_stat (1 - O(v_reg/V1))``: keep ``v_reg`` well below ``V1`` (10x or
more). Below breakaway the interface creeps at about ``v_reg artanh(F/F_stat)`` instead of sticking
exactly; measured errors are in ``docs/nonlinear.md``.

Sign convention as :class:`~components.damper.Damper`: ``f`` has the sign of
``v_rel = der(flange_b.s - flange_a.s)``, so the element dissipates ``f v_rel >= 0``. Connect
``flange_a`` to a :class:`~components.fixed.Fixed` for friction to ground.
"""

import casadi as ca

from bscomp.kernel.component import Parameter

from ._friction import PartialFriction


class StribeckFriction(PartialFriction):
    """Regularised Stribeck friction, Eq (5.6), with asymmetric ``+/-`` constants.

    No value of ``F_stat``, ``V1`` or ``V2`` is published for the test bed (the thesis uses Eq 5.7):
    the velocity defaults are placeholders of typical lubricated-guideway magnitude, not data.

    Parameters
    ----------
    F_s, F_c, v1, v2, d : float, optional
        Set both directions at once (symmetric friction): ``F_s`` sets ``F_s_pos`` and ``F_s_neg`` [N],
        likewise ``F_c`` [N], ``v1``, ``v2`` [m/s] and ``d`` [N.s/m].

    Attributes
    ----------
    flange_a, flange_b : Flange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialCompliant`).
    f, s_rel, v_rel : observable
        Friction force [N], relative position [m] and relative velocity [m/s].
    power : observable
        Dissipated power [W] (``f v_rel >= 0``).
    """

    F_s_pos = Parameter(unit="N", min=0.0, doc="static (breakaway) force magnitude F_stat^+, v_rel > 0")
    F_s_neg = Parameter(unit="N", min=0.0, doc="static (breakaway) force magnitude F_stat^-, v_rel < 0")
    F_c_pos = Parameter(unit="N", min=0.0, doc="Coulomb force magnitude F_coul^+ (Table 5.2: 2066 N)")
    F_c_neg = Parameter(unit="N", min=0.0, doc="Coulomb force magnitude F_coul^- (Table 5.2: 2066 N)")
    v1_pos = Parameter(1.0e-3, unit="m/s", positive=True, doc="Stribeck velocity V1 (decay of the static term), v > 0")
    v1_neg = Parameter(1.0e-3, unit="m/s", positive=True, doc="Stribeck velocity V1 (decay of the static term), v < 0")
    v2_pos = Parameter(1.0e-3, unit="m/s", positive=True, doc="velocity V2 of the rise to the Coulomb level, v_rel > 0")
    v2_neg = Parameter(1.0e-3, unit="m/s", positive=True, doc="velocity V2 of the rise to the Coulomb level, v_rel < 0")
    d_pos = Parameter(0.0, unit="N.s/m", min=0.0, doc="viscous coefficient B, v_rel > 0 (Table 5.2: 12673 N.s/m)")
    d_neg = Parameter(0.0, unit="N.s/m", min=0.0, doc="viscous coefficient B, v_rel < 0 (Table 5.2: 12673 N.s/m)")
    v_reg = Parameter(1.0e-5, unit="m/s", positive=True, doc="regularisation velocity of tanh(v/v_reg), << v1")

    SYMMETRIC = ("F_s", "F_c", "v1", "v2", "d")     # F_s=, F_c=, v1=, v2=, d= set both directions at once

    def friction_force(self, v):
        """Regularised friction force [N] at sliding velocity ``v`` (CasADi or float)."""
        sig = ca.tanh(v / self.v_reg)
        av = ca.fabs(v)

        def curve(F_s, F_c, v1, v2):
            return F_s * ca.exp(-av / v1) + F_c * (1 - ca.exp(-av / v2))

        wp, wn = 0.5 * (1 + sig), 0.5 * (1 - sig)
        level = (wp * curve(self.F_s_pos, self.F_c_pos, self.v1_pos, self.v2_pos)
                 + wn * curve(self.F_s_neg, self.F_c_neg, self.v1_neg, self.v2_neg))
        return sig * level + (wp * self.d_pos + wn * self.d_neg) * v
