"""Signals: system inputs, constant inputs and the substitution of signal definitions (flattening step 2).

A signal connection set (Modelica ``RealInput``/``RealOutput`` connected by ``connect``) is either
defined by the output that drives it (an explicit expression from its component's template), held at
the ``default`` of an input port, or left free: then it is a **system input** ``u`` of the DAE. Output
definitions are substituted in dependency order (a causal block diagram becomes expressions of the
states); definitions that depend on each other in a cycle form an **algebraic loop**, whose signals
stay algebraic unknowns ``z`` with the equation ``s - def(s) = 0`` (Modelica's algebraic loops, solved
by the index-1 Newton iteration instead of tearing).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

__all__ = ["Signals", "resolve_signals"]


@dataclass
class Signals:
    """Inputs and signal substitutions of a flattened system.

    Attributes
    ----------
    u_syms, u_names, u_units : list
        Free signals: the DAE inputs.
    sig_from, sig_to : list of SX
        Substitution signal -> expression (definitions in dependency order, then constant inputs).
    sig_loop : list of int
        Signals in algebraic loops (become algebraic unknowns).
    """

    u_syms: list
    u_names: list
    u_units: list
    sig_from: list
    sig_to: list
    sig_loop: list


def _order_signal_definitions(sig_def, sig_syms):
    """Topologically order signal definitions; members of cycles become algebraic variables."""
    keys = list(sig_def)
    deps = {}
    for k in keys:
        e = sig_def[k]
        deps[k] = [j for j in keys if j != k and ca.depends_on(e, sig_syms[j])]
        if ca.depends_on(e, sig_syms[k]):
            deps[k].append(k)
    order, state = [], {}
    loop = set()

    def visit(k, stack):
        st = state.get(k)
        if st == 2:
            return
        if st == 1:
            loop.update(stack[stack.index(k):])
            return
        state[k] = 1
        stack.append(k)
        for j in deps[k]:
            visit(j, stack)
        stack.pop()
        state[k] = 2
        order.append(k)

    for k in keys:
        visit(k, [])
    # resolve in dependency order (dependencies first)
    resolved = {}
    for k in order:
        if k in loop:
            continue
        e = sig_def[k]
        dd = [j for j in deps[k] if j in resolved]
        if dd:
            e = ca.substitute(e, ca.vertcat(*[sig_syms[j] for j in dd]), ca.vertcat(*[resolved[j] for j in dd]))
        resolved[k] = e
    return [sig_syms[k] for k in resolved], [resolved[k] for k in resolved], sorted(loop)


def resolve_signals(sets, sig_syms, sig_def) -> Signals:
    """Classify every signal (defined, constant input, free input) and order the definitions.

    Parameters
    ----------
    sets : ConnectionSets
    sig_syms : list of SX
        One symbol per signal.
    sig_def : dict
        Signal index -> defining expression (from the outputs of the instances).
    """
    u_syms, u_names, u_units = [], [], []
    const_from, const_to = [], []
    for k in range(len(sets.sig_names)):
        if k in sig_def:
            continue
        ins = sets.sig_inputs[k]
        defaults = [spec.default for _, _, spec in ins if spec.default is not None]
        if defaults:
            const_from.append(sig_syms[k])
            const_to.append(ca.SX(float(defaults[0])))
        else:
            u_syms.append(sig_syms[k])
            u_names.append(sets.sig_names[k])
            u_units.append(sets.sig_units[k])
    sig_from, sig_to, sig_loop = _order_signal_definitions(sig_def, sig_syms)
    return Signals(u_syms, u_names, u_units, sig_from + const_from, sig_to + const_to, sig_loop)
