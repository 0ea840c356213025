"""Ball stiffness and nut geometry of a ballscrew nut (thesis Eq 3.6, 3.13, 3.40-3.43; Appendix B.6,
Eq B.2-B.4): the relations between the ball contact-normal stiffness ``k_ball``, the catalogue axial
stiffness and Hertzian contact, and the pitch angle, gear ratio, azimuth range and number of balls that
follow from the nut's dimensions. SI units (m, rad, N/m) except where a docstring says otherwise (the
Hertz relations of Eq 3.42 are in the units of the thesis' ref [39]). The interface stiffness matrices
these feed are :mod:`components._screw_nut_fe`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "PRELOADS",
    "axial_stiffness_from_k_ball",
    "k_ball_from_axial_stiffness",
    "hertz_elastic_coefficient",
    "k_axial_hertz",
    "k_ball_hertz",
    "pitch_angle",
    "gear_ratio",
    "azimuth_range",
    "helix_arc_length",
    "n_ball_from_geometry",
]

#: Preload types: two-point contact with a spacer or an offset lead, four-point with oversize balls.
PRELOADS = ("spacer", "offset", "oversize")


def _check_preload(preload: str) -> str:
    p = preload.lower()
    if p not in PRELOADS:
        raise ValueError(f"preload must be one of {PRELOADS}, got {preload!r}")
    return p


# ---------------------------------------------------------------------------------------------
# Ball stiffness (Eq 3.40-3.43)
# ---------------------------------------------------------------------------------------------
def _n_springs(preload: str) -> float:
    return 2.0 if _check_preload(preload) == "oversize" else 1.0


def axial_stiffness_from_k_ball(
    k_ball: float, n_ball: float, alpha: float, beta: float, preload: str
) -> float:
    """Axial interface stiffness ``k_Ax`` (Eq 3.40 two-point, Eq 3.41 oversize balls) [N/m].

    ``k_Ax = k_Ball N_Ball cos^2(alpha) cos^2(beta)`` (x2 for oversize balls); equals
    ``K_SN[2, 2]`` of :func:`ksn_rigid` exactly, for any azimuth ranges.
    """
    return k_ball * n_ball * _n_springs(preload) * np.cos(alpha) ** 2 * np.cos(beta) ** 2


def k_ball_from_axial_stiffness(
    k_axial: float, n_ball: float, alpha: float, beta: float, preload: str
) -> float:
    """Ball stiffness from the catalogue axial stiffness (inverse of Eq 3.40 / 3.41) [N/m]."""
    return k_axial / (n_ball * _n_springs(preload) * np.cos(alpha) ** 2 * np.cos(beta) ** 2)


def hertz_elastic_coefficient(E_ball: float, E_thread: float, R_ball: float, R_thread: float) -> float:
    """Elastic coefficient ``C`` of Eq 3.43, as printed in the thesis.

    ``C = 0.775 * cbrt((E_Ball + E_thr) / (E_Ball E_thr) * (1/R_Ball - 1/R_thr))``.

    Notes
    -----
    The extracted equation reads ``0.775_{3}\\sqrt{...}``, read here as a cube root. Units are those
    of reference [39] of the thesis (not stated; Eq 3.42 takes the preload in daN), so use
    :func:`k_axial_hertz` only with the unit system of [39]. A textbook Hertz point contact would
    have the elastic term squared; that is not what the thesis prints and is not done here.
    """
    return 0.775 * np.cbrt((E_ball + E_thread) / (E_ball * E_thread) * (1.0 / R_ball - 1.0 / R_thread))


def k_axial_hertz(
    n_ball: float,
    alpha: float,
    beta: float,
    f_preload_daN: float,
    E_ball: float,
    E_thread: float,
    R_ball: float,
    R_thread: float,
) -> float:
    """Axial interface stiffness from Hertzian contact, Eq 3.42 (units of the thesis' ref [39]).

    ``k_Ax = 1500 N_Ball cos^2(alpha) cos^2(beta) cbrt(F_prd) / C`` with ``F_prd`` in daN and
    ``C`` from :func:`hertz_elastic_coefficient` (Eq 3.43).
    """
    C = hertz_elastic_coefficient(E_ball, E_thread, R_ball, R_thread)
    return 1500.0 * n_ball * np.cos(alpha) ** 2 * np.cos(beta) ** 2 * np.cbrt(f_preload_daN) / C


def k_ball_hertz(
    n_ball: float,
    alpha: float,
    beta: float,
    f_preload_daN: float,
    E_ball: float,
    E_thread: float,
    R_ball: float,
    R_thread: float,
    preload: str = "spacer",
) -> float:
    """Ball stiffness from Eq 3.42-3.43 through Eq 3.40/3.41 (units of the thesis' ref [39]).

    For two-point preloads this is ``1500 cbrt(F_prd) / C``; for oversize balls half of it
    (Eq 3.42 carries no factor 2, so the Hertz axial stiffness is shared by two springs per ball).
    """
    k_ax = k_axial_hertz(n_ball, alpha, beta, f_preload_daN, E_ball, E_thread, R_ball, R_thread)
    return k_ball_from_axial_stiffness(k_ax, n_ball, alpha, beta, preload)


# ---------------------------------------------------------------------------------------------
# Nut geometry (Eq 3.6, 3.13, B.2-B.4)
# ---------------------------------------------------------------------------------------------
def pitch_angle(p: float, d_p: float) -> float:
    """Pitch angle ``alpha = atan(p / (pi d_p))`` [rad] (Eq 3.6)."""
    return float(np.arctan(p / (np.pi * d_p)))


def gear_ratio(p: float) -> float:
    """Ballscrew gear ratio ``r_g = p / (2 pi)`` [m/rad] (Eq 3.13)."""
    return p / (2.0 * np.pi)


def azimuth_range(L_nut: float, p: float, z_offset: float = 0.0) -> tuple[float, float]:
    """Start/end azimuth of each ball for balls filling the whole nut (Eq B.2) [rad].

    ``phi_st = -L_nut/(2p) 2 pi``, ``phi_end = +L_nut/(2p) 2 pi`` when the node P is at the nut
    centre. ``z_offset`` is the axial position of the nut centre relative to P [m] (0 in the
    thesis), shifting both ends by ``z_offset / r_g``.
    """
    half = L_nut / (2.0 * p) * 2.0 * np.pi
    shift = z_offset / gear_ratio(p)
    return (-half + shift, half + shift)


def helix_arc_length(R_nut: float, p: float, phi_range: tuple[float, float]) -> float:
    """Arc length of the ball path ``s = sqrt(R_nut^2 + r_g^2) (phi_end - phi_st)`` (Eq B.4) [m]."""
    return float(np.hypot(R_nut, gear_ratio(p)) * (phi_range[1] - phi_range[0]))


def n_ball_from_geometry(
    R_nut: float,
    p: float,
    R_ball: float,
    phi_range: tuple[float, float],
    preload: str = "oversize",
    rounding: str | None = None,
) -> float:
    """Number of balls in contact from the nut geometry (Eq B.3, B.4).

    ``N_Ball = s / (4 R_Ball)`` for oversize-ball preload (every second ball is a spacer ball,
    App B.6). For two-point preloads (no spacer balls; an extrapolation, the thesis only
    treats the oversize case) ``N_Ball = s / (2 R_Ball)``.

    Parameters
    ----------
    rounding : {None, 'nearest', 'floor', 'ceil'}
        ``None`` returns the real number. The test bed gives 99.26, which Table B.3 lists as
        100 (i.e. 'ceil').
    """
    s = helix_arc_length(R_nut, p, phi_range)
    n = s / ((4.0 if _check_preload(preload) == "oversize" else 2.0) * R_ball)
    if rounding is None:
        return n
    ops = {"nearest": np.rint, "floor": np.floor, "ceil": np.ceil}
    if rounding not in ops:
        raise ValueError(f"unknown rounding {rounding!r}")
    return int(ops[rounding](n))
