"""Digital proportional position controller with zero-order hold, ``u_k = K_p (x_r,k - x_k)`` (Sec 4.3.2).

The outer loop of the P-PI cascade (Fig 4.3) samples the table position every T_s = 200 us, multiplies
the error by K_p [V/m] and writes the result to the D/A converter, a zero-order hold (Eq 4.16) that
feeds the analog velocity loop. The open loop of Eq 4.17, ``L(z) = Z{ZOH K_p G_v(s) G_x(s)}``, is what
:func:`bscomp.control.closed_loop.p_pi_loop` analyses. This object is a sampled block
(:class:`bscomp.kernel.sampled.SampledBlock`): the simulator calls :meth:`step` once per sample and holds the output.
"""

from bscomp.errors import ParameterError
from bscomp.kernel.sampled import SampledBlock


class DigitalPController(SampledBlock):
    """``u_k = K_p (r_k - y_k)``, a static sampled gain on the position error.

    Parameters
    ----------
    K_p : float
        Position gain [V/m] (7000 V/m in Sec 4.3.2, 5000 V/m with the notch filter, Sec 4.4.2).
    T_s : float
        Sampling period [s] (200e-6 s, Eq 4.17).

    Notes
    -----
    :meth:`step` takes ``(r_k, y_k)``: reference and measured table position [m].
    """

    def __init__(self, K_p: float, T_s: float = 2.0e-4):
        if not K_p >= 0:
            raise ParameterError(f"DigitalPController: K_p = {K_p!r} V/m must be >= 0")
        self.K_p = float(K_p)
        super().__init__([[self.K_p], [-self.K_p]], [1.0], T_s, inputs=["r", "y"], output="u")
