"""Checks of a model while it is flattened (flattening step 6), each failure a named error naming components.

* every parameter has a value (:class:`~bscomp.errors.ParameterError`);
* every physical port is connected (:class:`~bscomp.errors.UnconnectedPortError`) -- Modelica requires
  the same of non-optional connectors;
* every symbol the residual uses is an unknown, an input or a parameter: a coordinate without inertia
  whose acceleration is used, or without inertia and damping whose velocity is used, would need
  differentiation of constraints (:class:`~bscomp.errors.HighIndexError`);
* as many equations as unknowns, Modelica's "balanced model" rule
  (:class:`~bscomp.errors.OverdeterminedError` / :class:`~bscomp.errors.UnderdeterminedError`).

The structural rank of ``[dF/dx', dF/dz]`` (index 1, a maximum matching) and the numeric LU at the start
point are checked by :meth:`bscomp.kernel.dae.Dae.check_index1`.
"""

from __future__ import annotations

import casadi as ca

from bscomp.errors import (
    HighIndexError,
    OverdeterminedError,
    ParameterError,
    UnconnectedPortError,
    UnderdeterminedError,
)

__all__ = ["check_parameters", "check_connected", "check_symbols", "check_counts"]


def check_parameters(leaves):
    """Raise :class:`ParameterError` for the first parameter without a value."""
    for lf in leaves:
        for n, p in lf.comp.parameters().items():
            if lf.comp._values.get(n) is None:
                raise ParameterError(f"parameter {lf.path}.{n} [{p.unit}] has no value ({p.doc}); set it with "
                                     f"system.set('{lf.path}.{n}', value)")


def check_connected(leaves, connected):
    """Raise :class:`UnconnectedPortError` for the first physical, non-optional port not connected."""
    for lf in leaves:
        for pname, spec in lf.comp.ports().items():
            if not spec.kind.is_signal and not spec.optional and (lf.path, pname) not in connected:
                raise UnconnectedPortError(
                    f"port '{lf.path}.{pname}' ({spec.kind.name} of {type(lf.comp).__name__}) is not connected; "
                    f"connect it with system.connect('{lf.path}.{pname}', ...) or fix it to ground with a "
                    "Fixed/FixedRotational component")


def check_symbols(F, known):
    """Raise :class:`HighIndexError` if ``F`` uses a symbol that is not in ``known``."""
    used = ca.symvar(F)
    kset = {s.name() for s in ca.symvar(known)}
    bad = [s.name() for s in used if s.name() not in kset]
    if not bad:
        return
    msgs = []
    for b in bad:
        if b.startswith("der(der("):
            msgs.append(f"the acceleration {b} of a coordinate without inertia is used (an acceleration sensor or "
                        "inertial force on a massless node): add a mass there")
        elif b.startswith("der("):
            msgs.append(f"the velocity {b} of a coordinate with neither inertia nor damping is used: add a mass "
                        "or a damper there")
        else:
            msgs.append(f"symbol {b} is not a variable of the system")
    raise HighIndexError("; ".join(msgs))


def check_counts(n_eq, n_unk, origins, x_names, z_names, leaves):
    """Raise :class:`OverdeterminedError` / :class:`UnderdeterminedError` unless ``n_eq == n_unk``."""
    if n_eq == n_unk:
        return
    comp_lines = []
    for lf in leaves:
        nv = len(lf.comp.variables())
        if nv:
            comp_lines.append(f"{lf.path} ({type(lf.comp).__name__}): {nv} variable(s)")
    detail = "; ".join(comp_lines[:20])
    if n_eq > n_unk:
        raise OverdeterminedError(
            f"{n_eq} equations for {n_unk} unknowns: {n_eq - n_unk} equation(s) too many. Internal equations: "
            f"{[o for o in origins if o.startswith('equation')][:20]}. Components with variables: {detail}. "
            "A component gives one equation per variable plus one per flow/output it defines")
    raise UnderdeterminedError(
        f"{n_eq} equations for {n_unk} unknowns: {n_unk - n_eq} equation(s) missing. Unknowns: "
        f"{(x_names + z_names)[:30]}. Components with variables: {detail}")
