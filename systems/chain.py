"""A grounded spring-mass chain: the textbook system with closed-form modes, for checking an analysis.

``wall -- k1 -- m1 -- k2 -- m2 -- ... -- m_n <- F``: spring ``k_i`` ties mass ``m_i`` to the previous one (the
first to the wall), a force ``F.f`` [N] acts on the last mass. Its undamped frequencies are the roots of
``det(K - ω² M) = 0`` with the tridiagonal ``K`` of the springs; a chain of ``N`` equal masses and springs has
``ω_j = 2 sqrt(k/m) sin((2j - 1) π / (2 (2N + 1)))``. It lives in ``systems/`` (not the tests) so the tests, the
benchmarks and a user's own checks build the same chain.
"""

from __future__ import annotations

from bscomp import System
from bscomp.components import CoulombFriction, Fixed, Force, Mass, Spring
from bscomp.errors import ParameterError

__all__ = ["mass_spring_chain", "free_chain", "friction_oscillator"]


def mass_spring_chain(masses=(2.0, 3.0), springs=(1.0e4, 2.5e4), *, name: str = "chain", first: int = 1) -> System:
    """Grounded chain of ``len(masses)`` masses [kg] on ``len(springs)`` springs [N/m], force ``F.f`` on the last.

    Parameters
    ----------
    masses, springs : sequence of float
        ``m_i`` and ``k_i`` in chain order (``springs[0]`` ties the first mass to the wall); equal lengths.
    name : str
        The System's name.
    first : int
        Index of the first spring and mass in the component names (``k1``, ``m1`` ... by default; ``0`` gives
        ``k0``, ``m0`` ...).

    Raises
    ------
    ParameterError
        The lengths differ or the chain is empty.
    """
    masses, springs = list(masses), list(springs)
    if not masses or len(masses) != len(springs):
        raise ParameterError(f"mass_spring_chain: give one spring per mass (springs[0] to the wall); got "
                             f"{len(masses)} masses and {len(springs)} springs")
    s = System(name)
    s.add("wall", Fixed())
    prev = "wall.flange"
    for i, (m, k) in enumerate(zip(masses, springs, strict=True), start=first):
        s.add(f"k{i}", Spring(c=k))
        s.add(f"m{i}", Mass(m=m))
        s.connect(prev, f"k{i}.flange_a")
        s.connect(f"k{i}.flange_b", f"m{i}.flange_a")
        prev = f"m{i}.flange_b"
    s.add("F", Force())
    s.connect("F.flange", prev)
    return s


def free_chain(masses=(1.0, 2.0, 3.0), springs=(1.0e4, 3.0e4), *, name: str = "free_chain") -> System:
    """Free chain: ``len(masses)`` masses ``m0, m1, ...`` [kg] joined by ``len(masses) - 1`` springs ``k0, k1, ...``
    [N/m], nothing to ground, force ``F.f`` on the first mass: an undamped rigid-body mode (its centre of mass
    moves as ``F t^2 / (2 sum m)``) beside the elastic ones.

    Raises
    ------
    ParameterError
        Not one spring fewer than masses.
    """
    masses, springs = list(masses), list(springs)
    if len(masses) < 2 or len(springs) != len(masses) - 1:
        raise ParameterError(f"free_chain: give one spring between each pair of masses; got {len(masses)} masses "
                             f"and {len(springs)} springs")
    s = System(name)
    for i, m in enumerate(masses):
        s.add(f"m{i}", Mass(m=m))
    for i, k in enumerate(springs):
        s.add(f"k{i}", Spring(c=k))
        s.connect(f"m{i}.flange_b", f"k{i}.flange_a")
        s.connect(f"k{i}.flange_b", f"m{i + 1}.flange_a")
    s.add("F", Force())
    s.connect("F.flange", "m0.flange_a")
    return s


def friction_oscillator(m: float = 1.0, k: float = 1.0e4, F_c: float | None = 1.0, v_reg: float = 1.0e-4, *,
                        name: str | None = None) -> System:
    """Mass ``m`` [kg] on a spring ``k`` [N/m] to a wall, force ``F.f`` [N] on the mass and Coulomb friction ``fr``
    (``F_c`` [N], regularised over ``v_reg`` [m/s], Eq 5.7) between mass and wall; ``F_c=None`` leaves it out.
    Driven at ``F_0 sin(ω t)`` with ``F_0 > 4 F_c / π`` it slides through every period and its describing
    function gives the closed form ``|X| = sqrt(F_0^2 - (4 F_c / π)^2) / |k - m ω^2|`` (Den Hartog), which the
    stepped-sine and describing-function tests check against."""
    friction = F_c is not None
    s = System(name or ("osc_friction" if friction else "osc"))
    s.add("wall", Fixed())
    s.add("k", Spring(c=k))
    s.add("m", Mass(m=m))
    s.add("F", Force())
    s.connect("k.flange_a", "wall.flange")
    s.connect("k.flange_b", "m.flange_a")
    s.connect("F.flange", "m.flange_b")
    if friction:
        s.add("fr", CoulombFriction(F_c=F_c, v_reg=v_reg))
        s.connect("fr.flange_a", "wall.flange")
        s.connect("fr.flange_b", "m.flange_b")
    return s
