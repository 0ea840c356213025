"""The hidden parts of :mod:`bscomp.systems.truths` that are solved for a value: the table part's spring and the
housing's fasteners (a bisection on the truth's undamped modes), the damping truth's dashpots (first-order
perturbation of the drive's first two modes, checked on the complex eigenvalues).

Like the truths, nothing here uses :mod:`bscomp.validate.candidates`.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla

from bscomp.components import Damper, Fixed, Mass, Spring

from .testbed import drive_fraction
from .truth_effects import HeldBodyDamping

__all__ = ["modes_hz", "drive_modes", "joint_stiffness", "bisect_mode", "add_housing", "damping_ratios",
           "add_dashpots"]


def modes_hz(so):

    lam, phi = sla.eigh(so.K.toarray(), so.M.toarray())
    return np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi), phi


def drive_modes(s) -> np.ndarray:
    """Undamped frequencies [Hz] of the first two elastic axial/torsional modes (drive_fraction > 0.5)."""
    from bscomp import flatten, second_order

    so = second_order(flatten(s), inputs=[], outputs=[])
    f, phi = modes_hz(so)
    el = np.flatnonzero(f > 1.0)                   # elastic: rigid-body modes are at 0 Hz
    frac = drive_fraction(phi[:, el], so.M, so.coordinates)
    return f[el][frac > 0.5][:2]


def joint_stiffness(s, m_p, f_target) -> float:
    """Spring constant of the table part that puts an undamped mode of ``s`` at ``f_target`` [Hz].

    ``s`` has the part on a spring ``part_spring``; K is linear in its constant, so one linearization and
    a bisection on the number of modes below the target (monotone: every eigenvalue grows with k) do.
    """

    from bscomp import flatten, second_order

    so = second_order(flatten(s), inputs=[], outputs=[], params={"part_spring.c": 1.0})
    M, K1 = so.M.toarray(), so.K.toarray()
    i = so.coordinates.index("table_part.s")
    row = K1[i].copy()
    row[i] = 0.0
    (j,) = np.flatnonzero(row)                     # the table coordinate the part's spring acts on
    E = np.zeros_like(K1)                          # the unit spring: K(k) = K1 + (k - 1) E
    E[i, i] = E[j, j] = 1.0
    E[i, j] = E[j, i] = K1[i, j]                   # -1 or +1 (the flange's direction on the coordinate)
    return bisect_mode(K1 - E, E, M, f_target, f"table part {m_p:.1f} kg")


def bisect_mode(K0, E, M, f_target, what, own: bool = False) -> float:
    """The ``k`` that puts an undamped mode of ``K0 + k E`` (mass ``M``) at ``f_target`` [Hz]: a bisection on
    the number of modes below the target, monotone in k for ``E`` positive semi-definite.

    More than one mode may cross the target as ``k`` grows. By default the first crossing (the smallest ``k``);
    ``own=True``: the crossing whose mode holds the largest share of its strain energy in ``k E`` -- the new part's
    own mode, not a mode of the drive it lowered. (Housing seed 2204, 59 kg at 896 Hz: the first crossing, k 3.6e6
    N/m, is a drive mode with 30 % of its energy in the fasteners, the drive's axial stiffness cut 90-fold; the
    second, 1.7e9 N/m, the housing's own with 90 %.)"""

    def below(k):
        lam = sla.eigh(K0 + k * E, M, eigvals_only=True)
        return int(np.sum(np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi) < f_target))

    n_lo, n_hi = below(1.0e3), below(1.0e11)
    if n_lo == n_hi:
        raise RuntimeError(f"truths: no spring puts a mode at {f_target:.1f} Hz ({what})")
    best = None
    for n in range(n_lo, n_hi, -1) if own else (n_lo,):   # each crossing: the smallest k with fewer than n below
        lo, hi = 1.0e3, 1.0e11
        for _ in range(80):
            mid = math.sqrt(lo * hi)
            if below(mid) >= n:
                lo = mid
            else:
                hi = mid
            if hi / lo - 1.0 < 1e-12:
                break
        k = math.sqrt(lo * hi)
        share = _energy_share(K0, E, M, k, f_target) if own else 1.0
        if best is None or share > best[0]:
            best = (share, k)
    return best[1]


def _energy_share(K0, E, M, k, f_target) -> float:
    """Share of the strain energy in ``k E`` of the mode of ``K0 + k E`` nearest ``f_target`` [Hz]."""
    lam, phi = sla.eigh(K0 + k * E, M)
    p = phi[:, int(np.argmin(np.abs(np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi) - f_target)))]
    return float(k * (p @ E @ p) / (p @ (K0 + k * E) @ p))


def add_housing(s, h: dict, base_damping) -> dict:
    """Un-ground the thrust bearing ``b1`` and put its outer ring on a two-body housing (module docstring,
    ``housing``); returns the hidden values: ``m`` (seat + block) [kg], ``k`` the fastener stiffness and
    ``k_seat`` [N/m], ``k_static`` (the two in series), the dashpots, ``zeta`` and ``f_target`` [Hz]."""
    from bscomp import flatten, second_order
    from bscomp.components import FixedNode, NodeToFlange

    b1 = s.component("b1")
    s.replace("b1", type(b1)(grounded=False, **{n: getattr(b1, n) for n in ("k_axial", "k_radial", "k_tilt",
                                                                              "c_axial", "c_radial")}))
    m_seat = h["seat_fraction"] * h["m"]
    s.add("housing_hold", FixedNode(dofs=("u", "v", "tx", "ty", "tz")))
    s.add("housing_ring", NodeToFlange())
    s.connect("b1.node_b", "housing_hold.node")
    s.connect("b1.node_b", "housing_ring.node")
    s.add("housing_seat", Mass(m=m_seat))
    s.add("housing_block", Mass(m=h["m"] - m_seat))
    s.add("housing_frame", Fixed())
    s.connect("housing_ring.flange", "housing_seat.flange_a")
    for el, a, b in (("seat", "housing_seat.flange_a", "housing_block.flange_a"),
                     ("fastener", "housing_block.flange_a", "housing_frame.flange")):
        s.add(f"{el}_spring", Spring(c=1.0))
        s.add(f"{el}_damper", Damper(d=0.0))
        for part in (f"{el}_spring", f"{el}_damper"):
            s.connect(a, f"{part}.flange_a")
            s.connect(f"{part}.flange_b", b)
    s.damping = HeldBodyDamping(base_damping, ("b1.node_b.w", "housing_block.s"))
    ratio = h["seat_ratio"]
    dae = flatten(s)
    so = [second_order(dae, inputs=[], outputs=[], params={"fastener_spring.c": k, "seat_spring.c": ratio * k})
          for k in (1.0, 2.0)]                          # K linear in k (a spring's constant must be > 0)
    E = so[1].K.toarray() - so[0].K.toarray()
    f_t = h["f_target"]
    k = bisect_mode(so[0].K.toarray() - E, E, so[0].M.toarray(), f_t, f"housing {h['m']:.1f} kg", own=True)
    d_f = 2.0 * h["zeta"] * math.sqrt(k * h["m"])
    d_s = 2.0 * h["zeta"] * math.sqrt(ratio * k * m_seat)
    for n, v in (("fastener_spring.c", k), ("seat_spring.c", ratio * k), ("fastener_damper.d", d_f),
                 ("seat_damper.d", d_s)):
        s.set(n, v)
    return {"m": h["m"], "m_seat": m_seat, "k": k, "k_seat": ratio * k, "k_static": k * ratio / (1.0 + ratio),
            "d": d_f, "d_seat": d_s, "zeta": h["zeta"], "f_target": f_t}


def damping_ratios(so, C, f_hz) -> np.ndarray:
    """Damping ratios ``-Re(s) / |s|`` of the complex modes of ``M q'' + C q' + K q = 0`` nearest to the
    undamped frequencies ``f_hz`` [Hz]."""
    M, K = so.M.toarray(), so.K.toarray()
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    s = np.linalg.eigvals(A)
    s = s[s.imag > 0.0]
    return np.array([-s[i].real / abs(s[i]) for i in (np.argmin(np.abs(np.abs(s) - 2 * np.pi * f)) for f in f_hz)])


def add_dashpots(s, dd: dict) -> dict:
    """Damp the drive more than the model's modal ratios do, with two dashpots of its own (module docstring,
    ``damping``): ``b1.c_axial`` (the thrust bearing, axial, to the frame) and a :class:`TorsionalDamper`
    across the coupling's insert. Their constants solve the first-order perturbation of the drive's first two
    modes (``Delta zeta_i = phi_i^T C_add phi_i / (2 omega_i)``, ``phi_i`` mass-normalised) for the drawn
    ``mode1`` / ``mode2``; returns the dashpots and the two modes' damping ratios without and with them (from
    the complex eigenvalues, so the realised increments are exact, not the first-order ones)."""
    from bscomp import flatten, second_order
    from bscomp.components import TorsionalDamper

    s.add("coupling_loss", TorsionalDamper(d=0.0))
    s.connect("coupling.flange_a", "coupling_loss.flange_a")
    s.connect("coupling_loss.flange_b", "coupling.flange_b")
    dae = flatten(s)
    so = [second_order(dae, inputs=[], outputs=[], params={"b1.c_axial": a, "coupling_loss.d": b})
          for a, b in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0))]
    C0 = so[0].C.toarray()
    E = [so[1].C.toarray() - C0, so[2].C.toarray() - C0]      # the unit dashpots (C is linear in both)
    f, phi = modes_hz(so[0])
    el = np.flatnonzero(f > 1.0)
    drive = el[drive_fraction(phi[:, el], so[0].M, so[0].coordinates) > 0.5][:2]
    A = np.array([[phi[:, i] @ Ej @ phi[:, i] / (4 * np.pi * f[i]) for Ej in E] for i in drive])
    c = np.linalg.solve(A, [dd["mode1"], dd["mode2"]])
    if np.any(c <= 0.0):
        raise RuntimeError(f"truths: no positive dashpots give the drive modes +{dd['mode1']:.3f} / "
                           f"+{dd['mode2']:.3f} of critical damping (got {c})")
    s.set("b1.c_axial", float(c[0]))
    s.set("coupling_loss.d", float(c[1]))
    before = damping_ratios(so[0], C0, f[drive])
    after = damping_ratios(so[0], C0 + c[0] * E[0] + c[1] * E[1], f[drive])
    return {"c_axial": float(c[0]), "d_torsion": float(c[1]), "f_modes": [float(v) for v in f[drive]],
            "zeta_model": [float(v) for v in before], "zeta_truth": [float(v) for v in after],
            "added_target": [dd["mode1"], dd["mode2"]]}
