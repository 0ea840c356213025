"""Helpers shared by the 6-DOF components: DOF names, DOF subsets and rigid-point maps (Eq 3.3-3.4).

Not a component: small pure functions used by :mod:`ballscrew`, :mod:`rigid_body` and the joints.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ModelDefinitionError

__all__ = ["DOF_NAMES", "check_dofs", "pin_unused", "skew", "t_point_com", "as_6x6"]

#: Potentials of a :func:`~bscomp.kernel.ports.Node6` port, in order (thesis Eq 3.27).
DOF_NAMES = ("u", "v", "w", "tx", "ty", "tz")


def check_dofs(dofs, owner: str) -> tuple:
    """Validate a DOF subset; return it in canonical order."""
    dofs = tuple(dofs)
    bad = [d for d in dofs if d not in DOF_NAMES]
    if bad or not dofs or len(set(dofs)) != len(dofs):
        raise ModelDefinitionError(f"{owner}: dofs={dofs!r} must be a non-empty subset of {DOF_NAMES} "
                                   "without repeats")
    return tuple(d for d in DOF_NAMES if d in dofs)


def pin_unused(port, dofs) -> list:
    """Constraints ``port.<d> = 0`` for every potential not in ``dofs``."""
    return [getattr(port, d) for d in DOF_NAMES if d not in dofs]


def skew(r) -> np.ndarray:
    """Cross-product matrix ``S(r)`` of Eq (3.4): ``S(r) a = r x a``."""
    rx, ry, rz = np.asarray(r, dtype=float)
    return np.array([[0.0, -rz, ry], [rz, 0.0, -rx], [-ry, rx, 0.0]])


def t_point_com(r) -> np.ndarray:
    """Small-rotation transform ``T_P-COM = [[I, -S(r)], [0, I]]`` of Eq (3.3), ``r`` from COM to P."""
    T = np.eye(6)
    T[:3, 3:] = -skew(r)
    return T


def as_6x6(value, name: str) -> np.ndarray:
    """A 6x6 matrix from a 6x6 array, a 6-vector (diagonal) or a scalar (isotropic)."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        return a * np.eye(6)
    if a.shape == (6,):
        return np.diag(a)
    if a.shape == (6, 6):
        return a
    raise ModelDefinitionError(f"{name} must be a scalar, a 6-vector (diagonal) or 6x6, got shape {a.shape}")
