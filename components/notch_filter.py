"""Digital notch filter ``G_N(z) = K_N (z^2 + n_1 z + n_2) / (z^2 + d_1 z + d_2)`` (Eq 4.18).

Placed in the position loop after the P controller (Fig 4.14) to cancel the first (axial) mode: the
numerator zeros sit on the mode's poles (Eq 4.20), the denominator has the same frequency with more
damping (Eq 4.21) and ``K_N`` makes the static gain one (Eq 4.19). :func:`notch_coefficients` computes
them from the mode (it is what :func:`bscomp.control.design.notch` returns; Table 4.3: n_1 = -1.9521,
n_2 = 0.9745, d_1 = -1.8390, d_2 = 0.8600, K_N = 0.9402 at T_s = 200 us). A sampled block
(:class:`bscomp.kernel.sampled.SampledBlock`).
"""

import math

from bscomp.errors import ParameterError
from bscomp.kernel.sampled import SampledBlock

__all__ = ["NotchFilter", "notch_coefficients"]


def _z_pair(zeta: float, omega: float, T_s: float) -> tuple[float, float]:
    """``(c_1, c_2)`` of ``z^2 + c_1 z + c_2`` whose roots are ``exp(s T_s)`` of the roots of
    ``s^2 + 2 zeta omega s + omega^2`` (Eq 4.20, 4.21):

    .. math:: c_1 = -2 e^{-\\zeta\\omega T_s}\\cos(\\omega T_s\\sqrt{1-\\zeta^2}), \\qquad
              c_2 = e^{-2\\zeta\\omega T_s}

    (``cosh(omega T_s sqrt(zeta^2 - 1))`` for ``zeta > 1``: two real poles).
    """
    for name, v in (("omega", omega), ("T_s", T_s)):
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f"{name} = {v!r} must be a finite number > 0")
    if not zeta >= 0:
        raise ParameterError(f"damping ratio zeta = {zeta!r} must be >= 0")
    x = omega * T_s
    c = math.cos(x * math.sqrt(1 - zeta * zeta)) if zeta <= 1 else math.cosh(x * math.sqrt(zeta * zeta - 1))
    return -2 * math.exp(-zeta * x) * c, math.exp(-2 * zeta * x)


def notch_coefficients(zeta_N: float, omega_N: float, zeta_D: float, T_s: float,
                       omega_D: float | None = None) -> tuple[float, float, float, float, float]:
    """Coefficients ``(n1, n2, d1, d2, K_N)`` of the notch cancelling the mode ``(zeta_N, omega_N)``.

    Parameters
    ----------
    zeta_N, omega_N : float
        Damping ratio and natural frequency [rad/s] of the mode to cancel: the numerator zeros are its
        sampled poles (Eq 4.20).
    zeta_D : float
        Damping ratio of the replacing poles (denominator, Eq 4.21).
    T_s : float
        Sampling period [s].
    omega_D : float, optional
        Natural frequency of the replacing poles [rad/s]; default ``omega_N`` as in the thesis.

    Returns
    -------
    tuple of float
        ``n1, n2, d1, d2`` and ``K_N = (1 + d1 + d2) / (1 + n1 + n2)`` (unit DC gain, Eq 4.19).
    """
    n1, n2 = _z_pair(zeta_N, omega_N, T_s)
    d1, d2 = _z_pair(zeta_D, omega_N if omega_D is None else omega_D, T_s)
    return n1, n2, d1, d2, (1 + d1 + d2) / (1 + n1 + n2)


class NotchFilter(SampledBlock):
    """Second-order digital notch (Eq 4.18).

    Parameters
    ----------
    n1, n2 : float
        Numerator coefficients (Eq 4.20).
    d1, d2 : float
        Denominator coefficients (Eq 4.21); the poles must lie inside the unit circle.
    K_N : float or None
        Gain; ``None`` computes the unit-DC-gain value of Eq 4.19.
    T_s : float
        Sampling period [s].
    """

    def __init__(self, n1: float, n2: float, d1: float, d2: float, K_N: float | None = None,
                 T_s: float = 2.0e-4):
        if not (abs(d2) < 1 and abs(d1) < 1 + d2):  # Jury test for z^2 + d1 z + d2
            raise ParameterError(f"NotchFilter: denominator z^2 + {d1:g} z + {d2:g} has poles on or outside "
                                 "the unit circle (an unstable filter)")
        if K_N is None:
            if 1 + n1 + n2 == 0:
                raise ParameterError("NotchFilter: numerator vanishes at z = 1, K_N of Eq 4.19 is undefined")
            K_N = (1 + d1 + d2) / (1 + n1 + n2)
        self.n1, self.n2, self.d1, self.d2, self.K_N = map(float, (n1, n2, d1, d2, K_N))
        super().__init__([[self.K_N, self.K_N * self.n1, self.K_N * self.n2]], [1.0, self.d1, self.d2], T_s,
                         inputs=["u"], output="y")

    @classmethod
    def design(cls, zeta_N: float, omega_N: float, zeta_D: float, T_s: float, omega_D: float | None = None):
        """Notch from the mode to cancel and the damping of the new poles (Eq 4.19-4.21,
        :func:`notch_coefficients`)."""
        return cls(*notch_coefficients(zeta_N, omega_N, zeta_D, T_s, omega_D=omega_D), T_s)
