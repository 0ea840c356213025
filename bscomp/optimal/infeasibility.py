"""Where a failed Ipopt run stands: the constraint violated most and the bounds it pushes against.

Both transcriptions (:mod:`bscomp.optimal.collocation`, :mod:`bscomp.optimal.modal`) record every block of
constraint rows and of bounded unknowns in a :class:`Ledger`: what it is (a bound on a named signal, a
final value, the model's residual, a collocation equation...), the name and the time of each row (as a
fraction of the horizon T), the factor from the scaled row back to physical units and, for bounds, the
physical bounds. When Ipopt fails, :func:`describe` reads the last iterate's constraint values ``g``
against ``lbg``/``ubg`` (and unknowns ``x`` against ``lbx``/``ubx``) through the ledger: the largest
infeasibility in the model's names and units, and the bounds that are violated or at their limit, with
their times. Ipopt keeps simple bounds satisfied (interior point), so an infeasible problem usually shows
as a bound held on much of the horizon while an equality (a final value, the dynamics) is missed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bscomp.kernel.signal_meta import unit_suffix

__all__ = ["Block", "Ledger", "describe"]

#: the rows whose numbers are in their signal's unit (the others: residuals, scaled or modal rows)
UNIT_LABELS = {"bound", "rate limit", "final value", "initial value", "continuity", "collocation equation", "horizon"}

#: a bounded value within this fraction of its bound's magnitude counts as at the bound (an interior-point
#: iterate stopped early stays a little inside its bounds)
ACTIVE_TOL = 1e-2


@dataclass
class Block:
    """Rows ``start:stop`` of ``g`` (or of the unknowns ``x``) added together.

    ``label`` says what they are (``"final value"``, ``"bound"``, ``"model residual"``...), ``names`` and
    ``tfrac`` the name and the time (fraction of T) of each row, ``scale`` the factor from a scaled row to
    physical units; a bound block (``bound``) has the physical bounds ``lo``/``hi`` of each row. ``rate``
    marks a rate limit, whose scaled excess times ``scale`` is the excess of the change over one interval.
    """

    space: str
    start: int
    stop: int
    label: str
    names: list
    tfrac: np.ndarray
    scale: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    bound: bool = False
    rate: bool = False


class Ledger:
    """The blocks of rows of one NLP, in the order they were added (see the module docstring)."""

    def __init__(self):
        self.blocks: list[Block] = []
        self.size = {"g": 0, "x": 0}

    def add(self, n: int, label: str, names, tfrac, scale=1.0, lo=None, hi=None, space="g", start=None,
            rate=False) -> None:
        """Record ``n`` rows (appended at the end of ``space`` unless ``start`` is given); ``names``,
        ``tfrac``, ``scale`` and the physical bounds ``lo``/``hi`` (given for a bound) are one per row or
        broadcast."""
        n = int(n)
        if n <= 0:
            return

        def per_row(a, fill):
            return np.broadcast_to(np.asarray(fill if a is None else a, float), (n,)).copy()

        names = list(np.broadcast_to(np.asarray(names, dtype=object), (n,)))
        s0 = self.size[space] if start is None else int(start)
        self.blocks.append(Block(space, s0, s0 + n, label, names, per_row(tfrac, 0.0), per_row(scale, 1.0),
                                 per_row(lo, -np.inf), per_row(hi, np.inf), lo is not None or hi is not None, rate))
        self.size[space] = max(self.size[space], s0 + n)


def _violations(v, lo, hi):
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    with np.errstate(invalid="ignore"):
        return np.maximum(0.0, np.maximum(np.nan_to_num(lo - v, nan=0.0), np.nan_to_num(v - hi, nan=0.0)))


def _span(t):
    t = np.asarray(t, float)
    return f"t = {t.min():.4g} s" if t.min() == t.max() else f"t = {t.min():.4g} s to {t.max():.4g} s"


def _unit(units, label, name) -> str:
    """`` unit`` (with its space) of a row's numbers, or ``""``: the horizon in s, a signal's by ``units``."""
    if label == "horizon":
        return " s"
    return unit_suffix(units(name) if units is not None and label in UNIT_LABELS else "")


def _worst(ledger, values, T, units=None):
    """The row with the largest scaled violation over all spaces: a sentence, and the row as a dict."""
    best = None
    for b in ledger.blocks:
        v, lo, hi = values[b.space]
        if v is None or b.stop > len(v):
            continue
        viol = _violations(v[b.start:b.stop], lo[b.start:b.stop], hi[b.start:b.stop])
        if viol.size and (best is None or viol.max() > best[0]):
            k = int(np.argmax(viol))
            best = (float(viol[k]), b, k)
    if best is None or not best[0] > 0:
        return None, None
    viol, b, k = best
    t = float(b.tfrac[k] * T)
    name = b.names[k]
    phys = viol * float(b.scale[k])
    u = _unit(units, b.label, name)
    if b.bound:
        v = values[b.space][0][b.start + k] * float(b.scale[k])
        side, bound = ("lower", float(b.lo[k])) if v < b.lo[k] else ("upper", float(b.hi[k]))
        text = (f"'{name}' = {v:.6g}{u} violates its {side} bound {bound:.6g}{u} by {phys:.3g}{u} at t = {t:.4g} s "
                f"(scaled violation {viol:.3g})")
        row = {"constraint": b.label, "variable": name, "side": side, "bound": bound, "value": v, "time": t,
               "violation": phys, "scaled": viol, "unit": u.strip()}
    elif b.rate:
        text = (f"{b.label} on '{name}' exceeded by {phys:.3g}{u} over the interval ending at t = {t:.4g} s "
                f"(scaled violation {viol:.3g})")
        row = {"constraint": b.label, "variable": name, "time": t, "violation": phys, "scaled": viol,
               "unit": u.strip()}
    else:
        text = f"{b.label} of '{name}' at t = {t:.4g} s is off by {phys:.3g}{u} (scaled violation {viol:.3g})"
        row = {"constraint": b.label, "variable": name, "time": t, "violation": phys, "scaled": viol,
               "unit": u.strip()}
    return text, row


def _bounds(ledger, values, T, limit=4, units=None):
    """Bounds at their limit (or beyond) at the last iterate, by name: sentences, most pressed first."""
    by_name: dict = {}
    for b in ledger.blocks:
        v = values[b.space][0]
        if not b.bound or v is None or b.stop > len(v):
            continue
        x = v[b.start:b.stop] * b.scale
        span = np.maximum.reduce([np.where(np.isfinite(b.lo), np.abs(b.lo), 0.0),
                                  np.where(np.isfinite(b.hi), np.abs(b.hi), 0.0), np.full(b.lo.shape, 1e-300)])
        names = np.asarray(b.names, dtype=object)
        t = b.tfrac * T
        for side, bound in (("lower", b.lo), ("upper", b.hi)):
            fin = np.isfinite(bound)
            at = fin & ((x <= bound + ACTIVE_TOL * span) if side == "lower" else (x >= bound - ACTIVE_TOL * span))
            for n in dict.fromkeys(names):
                mine = names == n
                sel = at & mine
                if np.any(sel):
                    e = by_name.setdefault((n, side), [float(bound[sel][0]), [], 0, _unit(units, b.label, n)])
                    e[1].extend(t[sel])
                    e[2] += int(np.count_nonzero(mine & fin))
    items = sorted(by_name.items(), key=lambda kv: -len(kv[1][1]) / max(kv[1][2], 1))
    out, rows = [], []
    for (n, side), (bound, times, total, u) in items[:limit]:
        frac = len(times) / max(total, 1)
        out.append(f"'{n}' at its {side} bound {bound:.6g}{u} (within {100 * ACTIVE_TOL:g}%) on {100 * frac:.0f}% of "
                   f"the points ({_span(times)})")
        rows.append({"variable": n, "side": side, "bound": bound, "fraction": frac,
                     "t_first": float(np.min(times)), "t_last": float(np.max(times))})
    return out, rows


def describe(ledger: Ledger, T: float, g=None, lbg=None, ubg=None, x=None, lbx=None, ubx=None, units=None):
    """The last iterate read through ``ledger``: ``(text, info)``.

    ``units(name) -> str`` gives a signal's unit (:func:`bscomp.kernel.signal_meta.unit_of`); the values of
    bounds, rate limits, initial/final values and the dynamics' rows are printed with it.

    ``text`` is a sentence for :class:`~bscomp.optimal.OcpError` (the largest infeasibility, in the model's
    names and units at its time; the bounds at their limits with their share of the points and times);
    ``info`` the same as a dict (``"worst"``: constraint, variable, time, violation...; ``"bounds"``).
    """
    def arr(a):
        return None if a is None else np.asarray(a, float).ravel()

    values = {"g": (arr(g), arr(lbg), arr(ubg)), "x": (arr(x), arr(lbx), arr(ubx))}
    T = float(T) if T is not None and np.isfinite(T) else float("nan")
    worst, row = _worst(ledger, values, T, units)
    bounds, brows = _bounds(ledger, values, T, units=units)
    parts = []
    parts.append(f"Largest infeasibility at the last iterate: {worst}." if worst else
                 "At the last iterate every constraint holds (to Ipopt's tolerance): the solver stopped for "
                 "another reason (iteration limit, a restoration failure, an objective it could not decrease).")
    if bounds:
        parts.append("Bounds at their limit: " + "; ".join(bounds) + ".")
    return " ".join(parts), {"worst": row, "bounds": brows}
