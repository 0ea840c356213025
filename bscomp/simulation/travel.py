"""The nut stays on its screw: a run whose moving contact point leaves the screw is refused.

A moving screw-nut joint (thesis Sec 5.2.2.3; :class:`~components.moving_screw_nut.MovingScrewNut`,
:class:`~components.moving_nut_joint.MovingNutJoint`) reaches the screw through the shape functions of the
element holding its contact point ``z = z0 + nut.w`` (Eq 3.27 / A.7). Past the screw's first or last node there
is no element: the components clamp ``ξ`` to the end element, so a run that drives the nut off the screw would
go on with the nut glued to the end node -- a number with no physics behind it. Every simulation method
therefore records each joint's ``z`` and raises :class:`NutOffScrewError` (naming the joint, the time, the
position and the screw's span, and carrying the run up to that time) when it leaves
``[z_nodes[0], z_nodes[-1]]``.
"""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np

from bscomp.errors import SlowMethodWarning
from bscomp.simulation.moving_joints import find_moving_joints
from bscomp.simulation.result import SimulationError, SimulationResult

__all__ = ["NutOffScrewError", "travel_limits", "check_travel", "moving_nuts", "warn_slow_with_moving_nut"]

#: measured cost of a moving nut to the methods that re-linearize it (axial + torsional test bed, friction and
#: backlash, 2026-12-05): what the warning quotes
SLOW_WITH_MOVING_NUT = {
    "split": "every screw coordinate its shape functions reach is nonlinear and the split integrator "
             "re-linearizes densely (~1,000x slower than with the nut frozen: 138 s per 2 ms simulated on the "
             "axial + torsional test bed)",
    "fixed": "every screw coordinate its shape functions reach is a nonlinear row of the fixed-step Newton, whose "
             "exact low-rank correction grows from the friction and backlash rows to the screw's (3 -> 99 rows "
             "and 30x slower than with the nut frozen: 18.5 s per 10 ms simulated on the axial + torsional test "
             "bed)",
}

REL_TOL = 1e-9   # of the screw's length: round-off at a nut parked on an end node


class NutOffScrewError(SimulationError):
    """The contact point of a moving screw-nut joint left the screw.

    Attributes
    ----------
    joint : str
        The joint's component path.
    t, z : float
        First output time at which it was off the screw [s], and its position then [m].
    span : tuple of float
        The screw's first and last node [m].
    partial : SimulationResult
        The run up to the output time before (outputs and states as far as they are physical).
    """


def travel_limits(dae) -> list:
    """``(observable, joint path, first node, last node)`` of every moving joint of ``dae`` whose position is an
    observable (``<path>.z``), and whether that position moves with the state; found once per Dae (cached)."""
    out = dae._cache.get("nut_travel_limits")
    if out is None:
        names = set(dae.output_names())
        out = []
        for path, comp in find_moving_joints(dae.system):
            name = f"{path}.z"
            zn = getattr(comp, "z_nodes", None)
            if name in names and zn is not None and len(zn) >= 2:
                moves = bool(ca.depends_on(dae.output_expr([name]), dae.xs))
                out.append((name, path, float(zn[0]), float(zn[-1]), moves))
        dae._cache["nut_travel_limits"] = out
    return out


def moving_nuts(dae) -> list:
    """Paths of the moving joints whose contact point moves with the state (``<path>.z`` depends on it)."""
    return [path for _, path, _, _, moves in travel_limits(dae) if moves]


def warn_slow_with_moving_nut(dae, method, stacklevel) -> None:
    """A :class:`~bscomp.errors.SlowMethodWarning` before ``method`` runs on a model whose nut moves."""
    nuts = moving_nuts(dae)
    if nuts:
        warnings.warn(f"simulate(method={method!r}) on '{dae.name}': the nut of {nuts} moves along the screw, so "
                      f"{SLOW_WITH_MOVING_NUT[method]}; method='modal' keeps the linear part exact and moves only "
                      "the joint's low-rank part into the correction (docs/nonlinear.md)", SlowMethodWarning,
                      stacklevel=stacklevel + 1)


def check_travel(res, limits, method, model_name) -> None:
    """Raise :class:`NutOffScrewError` at the first output time a joint's ``z`` is outside its screw; else record
    each joint's travel in ``res.stats["nut_travel"]``: ``{path: {"z_min", "z_max", "screw": [first, last]}}`` [m]."""
    for name, path, lo, hi, _ in limits:
        z = np.asarray(res.outputs[name], float)
        res.stats.setdefault("nut_travel", {})[path] = {"z_min": float(z.min()), "z_max": float(z.max()),
                                                        "screw": [lo, hi]}
        tol = REL_TOL * (hi - lo)
        off = np.flatnonzero((z < lo - tol) | (z > hi + tol))
        if not off.size:
            continue
        k = int(off[0])
        side = "last" if z[k] > hi else "first"
        err = NutOffScrewError(
            f"simulate(method={method!r}) on '{model_name}': the nut of '{path}' left the screw at t = "
            f"{res.t[k]:.6g} s ({name} = {z[k]:.6g} m, past the screw's {side} node; it spans "
            f"[{lo:.6g}, {hi:.6g}] m): the joint has no shape functions there, so the run beyond is not physical",
            hint=f"end the run before t = {res.t[k]:.4g} s, lower the input, or start the nut elsewhere "
                 f"({path}.z0)")
        err.joint, err.t, err.z, err.span = path, float(res.t[k]), float(z[k]), (lo, hi)
        err.partial = _truncated(res, k)
        raise err


def _truncated(res, k):
    """The result on its first ``k`` output points (the states of a modal run rebuilt for them)."""
    return SimulationResult(t=res.t[:k], x=res.x[:k], xd=res.xd[:k], z=res.z[:k], u=res.u[:k],
                            x_names=res.x_names, z_names=res.z_names, u_names=res.u_names,
                            outputs={n: v[:k] for n, v in res.outputs.items()},
                            stats=dict(res.stats, truncated_at=float(res.t[k])), units=dict(res.units))
