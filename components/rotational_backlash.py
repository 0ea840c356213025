"""Rotational backlash (dead zone) with elastic, damped contact (thesis Eq 5.8-5.9, Fig 5.5/5.6).

The rotational twin of :class:`~components.backlash.Backlash`, with the same law and helpers: the
thesis applies its backlash (``L = 0.001885 rad``, Table 5.2) to the torsional DOF of the screw-nut
joint (Sec 5.3.1). With ``delta = phi_rel - phi_rel0``, ``e`` the dead-zone penetration outside the
clearance ``b`` and ``e'`` its slope,

.. math:: \\tau = \\min\\big(\\max(c\\,e + d\\,w_{rel}, 0), 2c\\,e\\big)\\ (\\delta > 0), \\qquad
          \\tau = \\max\\big(\\min(c\\,e + d\\,w_{rel}, 0), 2c\\,e\\big)\\ (\\delta \\le 0),

zero inside the gap (damping only in contact, never adhesive, bounded by the elastic torque);
``eps > 0`` smooths the corners over that width [rad]. See ``backlash.py`` and
``docs/nonlinear.md`` for the regularisation and its measured error.
"""

from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialRotCompliant

from .backlash import contact_force, dead_zone
from .torsional_spring import TorsionalSpring


class RotationalBacklash(PartialRotCompliant):
    """Rotational backlash: clearance ``b`` with a torsional spring-damper contact on either side.

    Attributes
    ----------
    flange_a, flange_b : RotFlange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialRotCompliant`).
    tau, phi_rel, w_rel : observable
        Element torque [N.m], relative angle [rad] and relative angular speed [rad/s].
    penetration : observable
        Contact penetration [rad] (0 in the gap).
    """

    b = Parameter(unit="rad", min=0.0, doc="total clearance, the dead-zone width L (Table 5.2: 0.001885 rad)")
    c = Parameter(unit="N.m/rad", positive=True, doc="contact stiffness")
    d = Parameter(0.0, unit="N.m.s/rad", min=0.0, doc="contact damping, active only in contact")
    phi_rel0 = Parameter(0.0, unit="rad", doc="relative angle of the gap centre")
    eps = Parameter(0.0, unit="rad", min=0.0, doc="width of the smoothed corners (0: sharp dead zone)")

    def linear_equivalent(self):
        """Small-signal equivalent for FRFs: the contact in engagement (torsional spring ``c``)."""

        return TorsionalSpring(c=self.c)

    def force_law(self, phi_rel, w_rel):
        """Element torque ``tau(phi_rel, w_rel)`` (Eq 5.8-5.9 as a contact law), as ``Backlash.force_law``: the
        compiled simulators (``method="modal"``, diagnose's evaluator) evaluate it with parameters as symbols."""
        return contact_force(phi_rel - self.phi_rel0, w_rel, self.b, self.c, self.d, self.eps)

    def equations(self):
        return [self.tau - self.force_law(self.phi_rel, self.w_rel)]

    def observables(self):
        out = super().observables()
        out["penetration"] = dead_zone(self.phi_rel - self.phi_rel0, self.b, self.eps)[0]
        return out
