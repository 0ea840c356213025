"""Pole-placement (RST) controller ``R(z) u = T(z) r - S(z) y`` (Eq 4.22, Fig 4.19).

The mode-compensating controller of Sec 4.5 acts directly on the amplifier command ``u`` [V] from the
reference ``r`` and the measured table position ``y`` [m]; the closed loop is
``y = B T / (A R + B S) r`` (Eq 4.22) with ``A R + B S = A_c A_o`` (Eq 4.26) and ``T = t_0 A_o``
(Eq 4.29). The polynomials come from :func:`bscomp.control.design.rst_design`. ``deg S <= deg R`` and
``deg T <= deg R`` are required (causal; Eq 4.27 assumes ``deg S = deg R``). A sampled block
(:class:`bscomp.kernel.sampled.SampledBlock`): :meth:`step` takes ``(r_k, y_k)`` and returns ``u_k``.
"""

import numpy as np

from bscomp.errors import ParameterError
from bscomp.kernel.sampled import SampledBlock


class RSTController(SampledBlock):
    """Two-degree-of-freedom digital controller ``u = (T r - S y) / R``.

    Parameters
    ----------
    R, S, T : array_like
        Polynomials in ``z``, descending powers (``R`` usually monic).
    T_s : float
        Sampling period [s].
    """

    def __init__(self, R, S, T, T_s: float = 2.0e-4):
        R, S, T = (np.atleast_1d(np.asarray(p, float)) for p in (R, S, T))
        if not np.any(R):
            raise ParameterError("RSTController: R is the zero polynomial")
        self.R, self.S, self.T = R, S, T
        super().__init__([T, -S], R, T_s, inputs=["r", "y"], output="u")
