"""Checks of an :class:`~bscomp.optimal.Ocp` statement before anything is transcribed.

Bad input is refused where it is given, with the argument named and how to fix it, instead of surfacing
as a CasADi assertion or an Ipopt status much later: collocation degrees CasADi has no Radau points for,
parameters given as signals, bound pairs that exclude every value, tracking references that raise or are
not finite numbers, start or final states outside their own path bounds, Ipopt options Ipopt rejects,
and warm starts from another model.
"""

from __future__ import annotations

import contextlib
import io

import casadi as ca
import numpy as np

from bscomp.errors import ArgumentTypeError, UsageError, check_number
from bscomp.kernel.signal_meta import unit_of, unit_suffix
from bscomp.optimal.result import OcpError, OcpResult

__all__ = ["MAX_DEGREE", "check_count", "check_degree", "check_signal", "check_bound_pair", "reference_values",
           "check_boundary_in_bounds", "check_solver_options", "check_warm_result"]

#: CasADi's ``collocation_points(d, "radau")`` has tables up to this degree
MAX_DEGREE = 9


def check_count(name, value) -> int:
    """A count (``N``) as an int >= 1, else :class:`UsageError`; bools (numpy's too) are not counts."""
    return check_number(name, value, integer=True, minimum=1)


def check_degree(degree) -> int:
    """The Radau collocation degree as an int in ``1..MAX_DEGREE``, else :class:`UsageError`."""
    d = check_count("degree", degree)
    if d > MAX_DEGREE:
        raise UsageError(f"degree must be <= {MAX_DEGREE} (CasADi has Radau collocation points up to degree "
                         f"{MAX_DEGREE}), got {degree!r}; degree 3 (the default) is the usual choice")
    return d


def check_signal(dae, name, what: str) -> None:
    """Refuse an observable ``name`` that is a parameter or a constant (depends on no state, derivative,
    algebraic variable or input): it cannot be bounded, tracked or limited (:meth:`bscomp.Dae.require_signals`,
    the check every response analysis makes). ``what`` is the argument, for the message (e.g. ``"bound"``)."""
    if name not in dae.x_names and name not in dae.u_names:
        dae.require_signals([name], what)


def check_bound_pair(name, lo: float, hi: float) -> None:
    """Refuse a bound pair that admits no finite value: ``lo = +inf`` or ``hi = -inf`` (``lo <= hi`` and
    NaN are checked by :meth:`Ocp.bound`)."""
    if lo == np.inf or hi == -np.inf:
        raise UsageError(f"bound on '{name}': lo={lo}, hi={hi} admits no finite value; use lo=-inf and/or "
                         "hi=inf for a side without a bound")


def reference_values(reference, output, times) -> np.ndarray:
    """``reference(t)`` at ``times`` as finite floats, else :class:`UsageError` / :class:`ArgumentTypeError`
    naming ``reference`` and the time (an exception of the function is chained)."""
    out = np.empty(len(times))
    for k, t in enumerate(times):
        try:
            v = reference(float(t))
        except Exception as exc:  # noqa: BLE001 - any error of the user's function, re-raised with context
            raise UsageError(f"reference (the wanted '{output}' as a function of t) raised "
                             f"{type(exc).__name__}: {exc} at t = {t:.6g} s; it must return a number for every "
                             "t of the horizon") from exc
        a = np.asarray(v) if not isinstance(v, (str, bytes)) else None
        if a is None or a.size != 1 or a.dtype.kind not in "iuf":
            raise ArgumentTypeError(f"reference (the wanted '{output}' as a function of t) must return one real "
                                    f"number, got {type(v).__name__} {v!r} at t = {t:.6g} s"[:300])
        out[k] = float(a.reshape(-1)[0])
        if not np.isfinite(out[k]):
            raise UsageError(f"reference (the wanted '{output}' as a function of t) returned {out[k]} at "
                             f"t = {t:.6g} s; it must be finite")
    return out


def check_boundary_in_bounds(ocp) -> None:
    """:class:`OcpError` if the start state or a final target (values, rest) is outside a path bound on that
    state: Ipopt would only report an invalid problem, blaming some other variable."""
    dae, x0 = ocp.dae, ocp.start_state()
    checks = [(dae.x_names[i], x0[i], "initial", 0.0) for i in range(dae.nx)]
    checks += [(dae.x_names[i], v, "final", ocp.T_fixed) for i, v in ocp.final_targets()]
    for name, v, which, t in checks:
        if name not in ocp.bounds:
            continue
        lo, hi = ocp.bounds[name]
        tol = 1e-12 * max(1.0, abs(lo) if np.isfinite(lo) else 0.0, abs(hi) if np.isfinite(hi) else 0.0)
        side, b = ("lower", lo) if v < lo - tol else ("upper", hi) if v > hi + tol else (None, None)
        if side is None:
            continue
        how = {"initial": "the start state (initial() or the model's start value)",
               "final": "the final target (final() values, 0 for a velocity with rest=True)"}[which]
        u = unit_suffix(unit_of(dae, name))
        err = OcpError(f"the {which} value of '{name}' = {v:.6g}{u} is outside its path bound [{lo:.6g}, {hi:.6g}]{u} "
                       f"(the {side} bound {b:.6g}{u}), so no trajectory can satisfy both: change {how} or the bound "
                       f"(bound('{name}', ...))")
        err.infeasibility = {"worst": {"constraint": f"{which} value", "variable": name, "time": t,
                                       "violation": abs(v - b), "side": side}, "bounds": []}
        raise err


_ACCEPTED: set = set()
"""Option sets Ipopt has accepted in this process (each is tried once, not on every solve)."""


def _ipopt_rejects(options: dict) -> str | None:
    """Why Ipopt refuses ``options`` (None if it accepts them): a 1-variable NLP is built and solved with them,
    Ipopt's own output (CasADi's Python bindings write it to ``sys.stdout``) captured for the message."""
    key = repr(sorted(options.items(), key=lambda kv: kv[0]))
    if key in _ACCEPTED:
        return None
    x = ca.SX.sym("x")
    log = io.StringIO()
    with contextlib.redirect_stdout(log):
        try:
            solver = ca.nlpsol("ipopt_option_check", "ipopt", {"x": x, "f": (x - 1) ** 2},
                               {"ipopt": options, "print_time": False})
            solver(x0=0.0)
            status = solver.stats().get("return_status")
            why = None if status != "Invalid_Option" else f"Ipopt status {status}"
        except RuntimeError as exc:
            why = str(exc).strip().splitlines()[-1].rpartition(".cpp:")[2].lstrip("0123456789: ")
    if why is None:
        _ACCEPTED.add(key)
        return None
    lines = log.getvalue().splitlines()
    said = [ln.strip() for ln in lines if "Setting:" in ln or "<=" in ln or "Unknown option" in ln][:2]
    if "Valid Settings:" in lines:
        valid = [ln.split()[0] for ln in lines[lines.index("Valid Settings:") + 1:] if ln.startswith("\t")]
        said.append(f"valid settings: {valid[:12]}")
    return "; ".join([why] + said)


def check_solver_options(base: dict, options) -> dict:
    """``base`` (``Ocp.ipopt_options``) updated by ``options`` (``solve(solver_options)``), after checking that
    it is a dict of Ipopt options Ipopt accepts; :class:`UsageError` naming the option otherwise."""
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise ArgumentTypeError(f"solver_options must be a dict of Ipopt options, e.g. {{'max_iter': 500}}, got "
                                f"{type(options).__name__} {options!r}"[:300])
    bad_keys = [k for k in options if not isinstance(k, str)]
    if bad_keys:
        raise ArgumentTypeError(f"solver_options: option names must be str, got {bad_keys[0]!r}")
    merged = dict(base, **options)
    if "max_iter" in merged:
        merged["max_iter"] = check_number("solver_options['max_iter']", merged["max_iter"], integer=True,
                                          minimum=0)
    if _ipopt_rejects(merged) is None:
        return merged
    for k, v in merged.items():     # name the culprit: each option alone
        why = _ipopt_rejects({k: v, "print_level": 0} if k != "print_level" else {k: v})
        if why is not None:
            src = "solver_options" if k in options else "Ocp.ipopt_options"
            raise UsageError(f"{src}: Ipopt does not accept option '{k}' = {v!r} ({why})"[:600],
                             hint="see https://coin-or.github.io/Ipopt/OPTIONS.html for Ipopt's option names "
                                  "and ranges")
    raise UsageError(f"solver_options: Ipopt does not accept these options together: {merged}"[:600])


def check_warm_result(result: OcpResult, dae) -> OcpResult:
    """A previous :class:`OcpResult` as a warm start for ``dae``: every state and input of ``dae`` must be in
    it (columns put in ``dae``'s order), else :class:`UsageError` (a solution of another model)."""
    missing = [n for n in dae.x_names if n not in result.x_names] + \
              [n for n in dae.u_names if n not in result.u_names]
    extra = [n for n in result.x_names if n not in dae.x_names] + [n for n in result.u_names if n not in dae.u_names]
    if missing or extra:
        other = getattr(getattr(result, "dae", None), "name", "another model")
        raise UsageError(f"warm_start: the result is of '{other}', not of '{dae.name}' (it lacks {missing[:5]}, "
                         f"has {extra[:5]} it does not know); warm start from a solution of the same model")
    if list(result.x_names) == list(dae.x_names) and list(result.u_names) == list(dae.u_names):
        return result
    xi = [list(result.x_names).index(n) for n in dae.x_names]
    ui = [list(result.u_names).index(n) for n in dae.u_names]
    return OcpResult(T=result.T, t=result.t, x=np.asarray(result.x)[:, xi], u=np.asarray(result.u)[:, ui],
                     outputs={}, x_names=list(dae.x_names), u_names=list(dae.u_names), active={},
                     stats={"source": "reordered warm start"})
