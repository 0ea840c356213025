"""Coulomb + viscous friction torque between two rotational flanges: the screw's bearings, seals and the
preloaded nut (the rotational twin of :class:`~components.coulomb_friction.CoulombFriction`), regularised for IDAS.

Thesis Sec 5.2.2.1 keeps friction at the guideways only ("while they can be neglected at the other sliding
surfaces, they cannot be disregarded at the guideways"); on drives with roller guideways the friction torque of
the angular-contact bearings and of the preloaded ball nut is often the larger part, and it acts on the screw,
not on the table. Its law is Eq (5.7) written for a torque and the relative angular speed
``w_rel = der(flange_b.phi - flange_a.phi)``, with the sign regularised as ``CoulombFriction``'s:

.. math::

    \\sigma = \\tanh(w_{rel} / w_{reg}), \\qquad
    \\tau = \\sigma \\Big(\\tfrac{1+\\sigma}{2} T_c^{+} + \\tfrac{1-\\sigma}{2} T_c^{-}\\Big)
        + \\Big(\\tfrac{1+\\sigma}{2} d^{+} + \\tfrac{1-\\sigma}{2} d^{-}\\Big) w_{rel} .

Below the breakaway torque the flanges creep at ``w_reg artanh(tau / T_c)`` instead of holding exactly; choose
``w_reg`` about 1e-3 of the smallest angular speed of interest (default 1e-2 rad/s: a 20 mm lead's
``CoulombFriction`` default of 1e-4 m/s is 3.1e-2 rad/s). Connect ``flange_a`` to a
:class:`~components.fixed_rotational.FixedRotational` for friction to ground (a bearing); between the screw and
the nut for the nut's own friction torque. Mechanical power dissipated: ``tau w_rel >= 0``.
"""

from bscomp.kernel.component import Parameter

from ._friction import PartialRotFriction, coulomb_viscous


class RotationalFriction(PartialRotFriction):
    """Regularised Coulomb + viscous friction torque, Eq (5.7) for a torque, with asymmetric ``+/-`` constants.

    Parameters
    ----------
    T_c, d : float, optional
        Set both directions at once (symmetric friction): ``T_c_pos = T_c_neg = T_c`` [N.m],
        ``d_pos = d_neg = d`` [N.m.s/rad].

    Attributes
    ----------
    flange_a, flange_b : RotFlange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialRotCompliant`).
    tau, phi_rel, w_rel : observable
        Friction torque [N.m], relative angle [rad] and relative angular speed [rad/s].
    power : observable
        Dissipated power [W] (``tau w_rel >= 0``).
    """

    T_c_pos = Parameter(unit="N.m", min=0.0, doc="Coulomb torque magnitude for w_rel > 0")
    T_c_neg = Parameter(unit="N.m", min=0.0, doc="Coulomb torque magnitude |T_c^-| for w_rel < 0")
    d_pos = Parameter(0.0, unit="N.m.s/rad", min=0.0, doc="viscous coefficient for w_rel > 0")
    d_neg = Parameter(0.0, unit="N.m.s/rad", min=0.0, doc="viscous coefficient for w_rel < 0")
    w_reg = Parameter(1.0e-2, unit="rad/s", positive=True, doc="regularisation speed of tanh(w_rel/w_reg)")

    SYMMETRIC = ("T_c", "d")     # T_c=, d= set both directions at once (symmetric friction)

    def friction_torque(self, w):
        """Regularised friction torque [N.m] at relative angular speed ``w`` (CasADi or float)."""
        return coulomb_viscous(w, self.T_c_pos, self.T_c_neg, self.d_pos, self.d_neg, self.w_reg)
