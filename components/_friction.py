"""What the friction laws share (:class:`~components.coulomb_friction.CoulombFriction`, Eq 5.7, and
:class:`~components.stribeck_friction.StribeckFriction`, Eq 5.6): a two-flange element whose force is a law of
the sliding velocity with ``+/-`` constants blended by ``w^{\\pm} = (1 \\pm \\tanh(v/v_{reg}))/2``, symmetric
short-hand parameters, the dissipated power and the small-signal (viscous) equivalent for FRFs."""

from bscomp.kernel.partials import PartialCompliant

from .damper import Damper


class PartialFriction(PartialCompliant):
    """Base of the regularised friction laws: a subclass sets :attr:`SYMMETRIC` (the short names ``x`` that set
    ``x_pos`` and ``x_neg`` at once) and defines :meth:`friction_force`; it needs parameters ``d_pos``, ``d_neg``."""

    SYMMETRIC: tuple = ()

    def __init__(self, **params):
        for short in self.SYMMETRIC:
            value = params.pop(short, None)
            if value is not None:
                params.setdefault(f"{short}_pos", value)
                params.setdefault(f"{short}_neg", value)
        super().__init__(**params)

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
