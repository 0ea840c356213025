"""Limiter expression shared by :class:`Saturation` and :class:`CurrentAmplifier` (private helper).

``limit(u, lo, hi, delta)`` is the hard clip ``min(max(u, lo), hi)`` when ``delta = 0`` and a C1 clip
with quadratic corners of half-width ``delta`` otherwise. In both cases it is *exactly* ``u`` for
``lo + delta <= u <= hi - delta``, so a linearization at an operating point inside the limits has gain 1
(CasADi differentiates the active branch of ``if_else``/``fmin``/``fmax``).

Upper corner (``hi - delta < u < hi + delta``): ``y = hi - (hi + delta - u)^2 / (4 delta)``, which meets
``y = u`` with slope 1 at ``u = hi - delta`` and ``y = hi`` with slope 0 at ``u = hi + delta``.
"""




def limit(u, lo, hi, delta=0.0):
    """Clip ``u`` to ``[lo, hi]`` (CasADi SX); ``delta`` > 0 rounds the corners (see module docstring)."""
    import casadi as ca

    hard = ca.fmin(ca.fmax(u, lo), hi)
    if isinstance(delta, (int, float)) and delta == 0.0:
        return hard
    d = ca.fmax(delta, 1e-300)  # symbolic delta: guard the division, the branch below picks `hard` at 0
    upper = hi - (hi + d - u) ** 2 / (4 * d)
    lower = lo + (u - lo + d) ** 2 / (4 * d)
    smooth = ca.if_else(u >= hi + d, hi,
                        ca.if_else(u > hi - d, upper,
                                   ca.if_else(u >= lo + d, u,
                                              ca.if_else(u > lo - d, lower, lo))))
    return ca.if_else(delta > 0, smooth, hard)
