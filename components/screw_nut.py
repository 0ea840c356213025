"""Screw-nut interface: lumped 12x12 ball-contact stiffness K_SN (thesis Sec 3.3.4, Eq 3.30-3.35).

Rigid-ballscrew method: the screw section inside the nut moves as a rigid body described by the
6-DOF screw point P on the axis at the nut centre (port ``screw``, usually a ``points`` port of
:class:`Ballscrew` or an FE node), and the nut is rigid (port ``nut``, e.g. a :class:`RigidBody`
point at the same place). Each ball is a spring ``k_ball`` along its contact normal; integrating over
the azimuth range of every ball (Eq 3.34-3.35) gives

.. math:: F = -K_{SN} \\begin{Bmatrix} d_{screw} \\\\ d_{nut} \\end{Bmatrix},\\qquad
          K_{SN} = \\begin{bmatrix} A & -A \\\\ -A & A \\end{bmatrix}

computed by :func:`components._screw_nut_fe.ksn_rigid`. ``preload`` is ``"oversize"`` (four-point
contact, two springs per ball, Eq 3.41), ``"spacer"`` or ``"offset"`` (two-point, Eq 3.40).
``k_ball`` may be given directly, from a catalogue axial stiffness (inverse of Eq 3.40/3.41) or from
Hertz contact (Eq 3.42/3.43); ``n_ball`` and the azimuth range from the nut geometry (Eq B.2-B.4),
see :meth:`ScrewNut.from_nut_geometry`.

K_SN has rank 5 when ``r_g = R tan(alpha)``: besides the common rigid motions, the relative helical
motion ``w_nut - w_screw = r_g (tz_nut - tz_screw)`` (the nut running along the thread) is free, as in
the real mechanism. A free nut on a free screw therefore has 7 zero-frequency modes, not 6.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from bscomp.errors import ModelDefinitionError, ParameterError
from bscomp.kernel.component import Component, LinearStructure, Parameter
from bscomp.kernel.ports import Node6

from ._node_dofs import DOF_NAMES
from ._nut_geometry import (
    PRELOADS,
    azimuth_range,
    gear_ratio,
    k_ball_from_axial_stiffness,
    k_ball_hertz,
    n_ball_from_geometry,
    pitch_angle,
)
from ._screw_nut_fe import ksn_rigid


class ScrewNut(Component):
    """Ball screw-nut interface stiffness (rigid-ballscrew method, Eq 3.35).

    Parameters
    ----------
    preload : {"oversize", "spacer", "offset"}
        Preload type (four-point contact with oversize balls, or two-point).
    hand : {1, -1}
        Thread hand (+1 right-hand).

    Attributes
    ----------
    screw : Node6
        Screw point P on the axis at the nut centre (required).
    nut : Node6
        Nut node at the same place (required).
    """

    screw = Node6("screw point P (on the screw axis at the nut centre)", optional=False)
    nut = Node6("nut node (coincident with P)", optional=False)
    k_ball = Parameter(unit="N/m", positive=True, doc="ball contact-normal stiffness (Table 3.1: 2.07e7)")
    n_ball = Parameter(unit="1", positive=True, doc="number of balls in contact (Eq B.3; Table 3.1: 100)")
    alpha = Parameter(unit="rad", min=-0.5 * np.pi, max=0.5 * np.pi, doc="pitch angle (Eq 3.6; Table 3.1: 4.55 deg)")
    beta = Parameter(unit="rad", min=0.0, max=0.5 * np.pi, doc="contact angle (Table 3.1: 50 deg)")
    R = Parameter(unit="m", positive=True, doc="radius of the ball centres (Sec B.6: 20 mm)")
    phi_start = Parameter(-np.pi, unit="rad", doc="start azimuth of each ball (Eq B.2; Table B.3: -1800 deg)")
    phi_end = Parameter(np.pi, unit="rad", doc="end azimuth of each ball (Eq B.2; Table B.3: +1800 deg)")
    r_g = Parameter(0.0, unit="m/rad", min=0.0, doc="lead per radian; 0 means R tan(alpha) (Eq 3.13)")

    def __init__(self, preload: str = "oversize", hand: int = 1, **params):
        super().__init__(**params)
        if preload not in PRELOADS:
            raise ModelDefinitionError(f"ScrewNut: preload must be one of {PRELOADS}, got {preload!r}")
        if hand not in (1, -1):
            raise ModelDefinitionError(f"ScrewNut: hand must be +1 or -1, got {hand!r}")
        self.preload, self.hand = preload, hand

    @classmethod
    def from_nut_geometry(cls, L_nut: float, lead: float, R: float, R_ball: float, beta: float, *,
                          k_ball: float | None = None, k_axial: float | None = None,
                          hertz: dict | None = None, preload: str = "oversize", n_ball: float | None = None,
                          rounding: str | None = "ceil", z_offset: float = 0.0, hand: int = 1) -> "ScrewNut":
        """Interface from the nut geometry (App B.6).

        ``alpha = atan(lead / (2 pi R))`` (Eq 3.6), azimuth range from ``L_nut`` (Eq B.2), ``n_ball``
        from the helix length (Eq B.3-B.4, ``rounding`` as
        :func:`components._nut_geometry.n_ball_from_geometry`; the thesis rounds 99.26 up to 100). Give
        exactly one of ``k_ball`` [N/m], ``k_axial`` [N/m] (catalogue axial stiffness, Eq 3.40/3.41) or
        ``hertz`` (keyword arguments of
        :func:`components._nut_geometry.k_ball_hertz` other than n_ball/alpha/beta/preload, Eq 3.42-3.43).
        """
        alpha = pitch_angle(lead, 2.0 * R)
        phi = azimuth_range(L_nut, lead, z_offset)
        if n_ball is None:
            n_ball = n_ball_from_geometry(R, lead, R_ball, phi, preload, rounding)
        given = [k is not None for k in (k_ball, k_axial, hertz)]
        if sum(given) != 1:
            raise ModelDefinitionError("ScrewNut.from_nut_geometry: give exactly one of k_ball, k_axial, "
                                       "hertz")
        if k_axial is not None:
            k_ball = k_ball_from_axial_stiffness(k_axial, n_ball, alpha, beta, preload)
        elif hertz is not None:
            k_ball = k_ball_hertz(n_ball, alpha, beta, preload=preload, **hertz)
        return cls(preload=preload, hand=hand, k_ball=k_ball, n_ball=n_ball, alpha=alpha, beta=beta, R=R,
                   phi_start=phi[0], phi_end=phi[1], r_g=gear_ratio(lead))

    def check(self, values):
        """The ball azimuth range of Eq B.2 is not empty: ``phi_end > phi_start``."""
        a, b = values["phi_start"], values["phi_end"]
        if a is not None and b is not None and not b > a:
            raise ParameterError(f"{self._where('phi_start', 'phi_end')}: the ball azimuth range needs phi_end > "
                                 f"phi_start (Eq B.2), got phi_start = {a!r} rad, phi_end = {b!r} rad")

    def stiffness_matrix(self) -> np.ndarray:
        """K_SN (12x12, screw point dofs first) at the current parameter values (Eq 3.35)."""
        v = self._values
        return self._ksn(*(v[n] for n in ("k_ball", "n_ball", "alpha", "beta", "R", "phi_start", "phi_end",
                                           "r_g")))

    def _ksn(self, k_ball, n_ball, alpha, beta, R, phi_start, phi_end, r_g):
        if phi_end <= phi_start:
            raise ModelDefinitionError(f"ScrewNut: phi_end ({phi_end}) must exceed phi_start ({phi_start})")
        return _ksn_cached(float(k_ball), int(round(n_ball)), float(alpha), float(beta), float(R), float(phi_start),
                           float(phi_end), self.preload, None if r_g == 0.0 else float(r_g), self.hand).copy()

    def structure(self):
        K = self._ksn(self.k_ball, self.n_ball, self.alpha, self.beta, self.R, self.phi_start, self.phi_end,
                      self.r_g)
        dofs = [f"screw.{d}" for d in DOF_NAMES] + [f"nut.{d}" for d in DOF_NAMES]
        return LinearStructure(dofs=dofs, K=sp.csr_matrix(K))


@lru_cache(maxsize=64)
def _ksn_cached(k_ball, n_ball, alpha, beta, R, phi_start, phi_end, preload, r_g, hand):
    """:func:`ksn_rigid` per distinct set of values (a drive flattened again -- a diagnose's candidate structures, a
    sweep's variants -- asks for the same 12x12 matrix: 85 ms of the FE test bed's 180 ms flattening)."""
    K = ksn_rigid(k_ball, n_ball, alpha, beta, R, (phi_start, phi_end), preload, r_g=r_g, hand=hand)
    K.setflags(write=False)
    return K
