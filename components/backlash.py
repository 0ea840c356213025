"""Translational backlash (dead zone) with elastic, damped contact (thesis Eq 5.8-5.9, Fig 5.5/5.6).

The thesis models backlash as the classical dead zone of Fig 5.5: the output element is disengaged
while the input moves inside a clearance of total width ``L`` (here ``b``), and is carried along once
either side of the clearance is reached (Eq 5.8), the side distances ``L_lag``/``L_lead`` being updated
by the rule (5.9). Fig 5.6 places that switch in a joint between two sub-models. In an acausal model
the same switch is a force law across the joint, with the joint's stiffness ``c`` and damping ``d``
acting only in contact (as Modelica's ``ElastoBacklash``). With ``delta = s_rel - s_rel0``:

.. math::

    e = \\begin{cases} \\delta - b/2 & \\delta > b/2 \\\\ 0 & |\\delta| \\le b/2 \\\\
        \\delta + b/2 & \\delta < -b/2 \\end{cases}, \\qquad
    f = \\begin{cases} \\min\\big(\\max(c\\,e + d\\,v_{rel},\\ 0),\\ 2c\\,e\\big) & \\delta > 0 \\\\
        \\max\\big(\\min(c\\,e + d\\,v_{rel},\\ 0),\\ 2c\\,e\\big) & \\delta \\le 0 \\end{cases}

i.e. ``f = c (|delta| - b/2) sign(delta)`` outside the gap and zero inside, with the damping force
acting only in contact and bounded as in Modelica's ``ElastoBacklash``: never adhesive (the contact
cannot pull) and never larger than the elastic force, so ``f`` is continuous when contact starts
(an undamped jump ``d v`` at impact made IDAS fail). The rigid limit ``c -> inf`` is Eq (5.8)-(5.9):
the side distances ``L_lag``, ``L_lead`` of the thesis are ``b/2 + delta`` and ``b/2 - delta``.

Corner smoothing (optional): with ``eps > 0`` each corner of ``e(delta)`` is replaced over a width
``eps`` by a parabola (``corner="parabolic"``, the default: ``e`` and ``e'`` continuous; exact for
``|delta| >= (b + eps)/2`` and zero for ``|delta| <= (b - eps)/2``), so the contact stiffness is switched
in over ``eps``; the apparent clearance shrinks by up to ``eps``. ``corner="gaussian"`` is the mean
engagement of a nut whose balls take load at normally scattered gaps (ball-size scatter, lead errors):
``e = E[max(delta - b/2 - g, 0)]``, ``g ~ N(0, sigma^2)``, ``sigma = sqrt(2 pi) eps / 8`` (the same
penetration ``eps/8`` at the nominal edge as the parabola), smooth with tails on both sides -- the parabola
is the same mean over a *uniform* scatter of width ``eps``.
CasADi 3.8's ``idas`` has no working event location (casadi#4393);
with the default ``eps = 0`` it steps through the kinks by error control. That is robust in the tests
(docs/nonlinear.md, with the measured loop width), but a very light body chattering on a stiff contact
can still exhaust IDAS: then add contact damping, set ``eps`` ~ 1e-3 b, or refine ``t``.

Sign convention (as :class:`~components.spring.Spring`): ``s_rel = flange_b.s - flange_a.s``; ``f > 0``
for ``delta > b/2``, like a spring in tension pulling the flanges back together.
"""

import math

import casadi as ca

from bscomp.errors import ParameterError
from bscomp.kernel.component import Parameter
from bscomp.kernel.partials import PartialCompliant

from .spring import Spring
from .spring_damper import SpringDamper

#: corner shapes of the dead zone (module docstring)
CORNERS = ("parabolic", "gaussian")
_SQRT_2PI = math.sqrt(2.0 * math.pi)


def dead_zone(delta, b, eps, corner: str = "parabolic"):
    """Dead-zone penetration ``e(delta)`` and its slope ``e'(delta)`` (CasADi expressions).

    ``b`` is the total clearance; ``eps >= 0`` the width of the corner blend (0: sharp), ``corner`` its
    shape: ``"parabolic"`` (compact: zero penetration for ``|delta| <= (b - eps)/2``) or ``"gaussian"``
    (the mean engagement of balls whose individual gaps scatter normally with
    ``sigma = sqrt(2 pi) eps / 8``, so that the penetration at ``|delta| = b/2`` is ``eps/8`` as for the
    parabola; tails on both sides).
    """
    if corner not in CORNERS:
        raise ParameterError(f"dead_zone: corner must be one of {CORNERS}, got {corner!r}")

    def ramp(x):  # max(x, 0) with a parabolic corner of width eps
        width = ca.fmax(eps, 1e-300)  # the blend branch is never selected when eps = 0
        value = ca.if_else(x >= eps / 2, x, ca.if_else(x <= -eps / 2, 0, (x + eps / 2) ** 2 / (2 * width)))
        slope = ca.if_else(x >= eps / 2, 1, ca.if_else(x <= -eps / 2, 0, (x + eps / 2) / width))
        return value, slope

    def ramp_gaussian(x):  # E[max(x - g, 0)], g ~ N(0, sigma^2): x Phi(x/sigma) + sigma phi(x/sigma)
        sigma = ca.fmax(_SQRT_2PI / 8.0 * eps, 1e-300)
        z = x / sigma
        cdf = 0.5 * (1.0 + ca.erf(z / math.sqrt(2.0)))
        pdf = ca.exp(-0.5 * ca.fmin(z * z, 1400.0)) / _SQRT_2PI
        sharp = eps <= 0
        return ca.if_else(sharp, ca.fmax(x, 0), x * cdf + sigma * pdf), ca.if_else(sharp, x > 0, cdf)

    r = ramp if corner == "parabolic" else ramp_gaussian
    up, dup = r(delta - b / 2)
    dn, ddn = r(-delta - b / 2)
    return up - dn, dup + ddn


def contact_force(delta, v, b, c, d, eps, corner: str = "parabolic"):
    """Backlash contact force: elastic + damped in contact, zero in the gap, never adhesive.

    As Modelica's ``ElastoBacklash``, the damping part is bounded by the elastic part,
    ``|d v| <= c |e|``, so the force is continuous when contact starts or ends.
    """
    e, _ = dead_zone(delta, b, eps, corner)
    f_c = c * e
    raw = f_c + d * v
    return ca.if_else(delta > 0, ca.fmin(ca.fmax(raw, 0), 2 * f_c), ca.fmax(ca.fmin(raw, 0), 2 * f_c))


class Backlash(PartialCompliant):
    """Translational backlash: clearance ``b`` with a spring-damper contact on either side.

    ``corner``, a constructor argument (``"parabolic"``, the default, or ``"gaussian"``): the shape of the
    corners smoothed over ``eps`` (module docstring).

    Attributes
    ----------
    flange_a, flange_b : Flange
        The two flanges (from :class:`~bscomp.kernel.partials.PartialCompliant`).
    f, s_rel, v_rel : observable
        Element force [N], relative position [m] and relative velocity [m/s].
    penetration : observable
        Contact penetration ``e`` [m] (0 in the gap).
    """

    b = Parameter(unit="m", min=0.0, doc="total clearance, the dead-zone width L of Eq 5.8 (0.001885 rad r_g = "
                  "3.0 um at the test-bed table, Table 5.2)")
    c = Parameter(unit="N/m", positive=True, doc="contact stiffness")
    d = Parameter(0.0, unit="N.s/m", min=0.0, doc="contact damping (only in contact)")
    s_rel0 = Parameter(0.0, unit="m", doc="relative position of the gap centre")
    eps = Parameter(0.0, unit="m", min=0.0, doc="width of the smoothed corners (0: sharp)")

    def __init__(self, corner: str = "parabolic", **params):
        super().__init__(**params)
        if corner not in CORNERS:
            raise ParameterError(f"Backlash: corner must be one of {CORNERS}, got {corner!r}")
        self.corner = corner

    def template_key(self):
        return self.corner

    def linear_equivalent(self):
        """Small-signal equivalent for FRFs: the contact in engagement (spring ``c``, with the contact
        damper ``d`` beside it when there is one)."""
        if self.d > 0:

            return SpringDamper(c=self.c, d=self.d)

        return Spring(c=self.c)

    def force_law(self, s_rel, v_rel):
        """Element force ``f(s_rel, v_rel)`` (Eq 5.8-5.9 as a contact law); see CoulombFriction.force_law."""
        return contact_force(s_rel - self.s_rel0, v_rel, self.b, self.c, self.d, self.eps, self.corner)

    def equations(self):
        return [self.f - self.force_law(self.s_rel, self.v_rel)]

    def observables(self):
        out = super().observables()
        out["penetration"] = dead_zone(self.s_rel - self.s_rel0, self.b, self.eps, self.corner)[0]
        return out
