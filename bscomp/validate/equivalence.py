r"""Candidates the data cannot tell apart: one group in diagnose's report instead of a pick by round-off.

On a model of coarse resolution two candidate effects can be the same effect: on the 3-coordinate
``validation_drive`` a spring at the nut-table joint and a spring at the bearing housing are both one
compliance in series in the axial load path. Both then fit the data about equally well, and which one
comes out a hair better is decided by round-off (a modal basis differing by 1e-13 swapped them). Such
candidates are reported as **one group**: each :class:`~bscomp.validate.diagnosis.EffectFit` lists the
others it cannot be told apart from (``equivalent``), with the numbers and what to measure to separate
them.

Two refined candidates ``A`` and ``B`` of one round form a group when both hold:

1. **The data cannot say which fits better**: either their predictions coincide within the noise, or
   they differ but neither fits the data significantly better.

   *Within the noise*: with :math:`\delta` the difference of the two predictions in units of each
   residual block's noise level and :math:`D = \sum \delta_i^2`, data made by ``A`` itself would favour
   ``A`` over ``B`` by :math:`\chi^2_B - \chi^2_A = D + 2 e^T \delta`, of mean ``D`` and standard deviation
   :math:`2 \sqrt{D}`: not at 5 % (two-sided) while :math:`\sqrt{D} / 2 < 1.96`, i.e. :math:`D < 15.4`.

   *Neither better*: Vuong's test for non-nested models (Q. H. Vuong,
   "Likelihood ratio tests for model selection and non-nested hypotheses", *Econometrica* 57 (1989)
   307-333, with his Schwarz-type correction for unequal parameter counts): with
   :math:`r_{A,i}`, :math:`r_{B,i}` the whitened residuals of the two fitted models at every data point
   (FRF blocks and both halves of each time series, each residual in units of its block's noise level,
   so :math:`-2 \ln L = \sum r^2`) and :math:`l_i = r_{B,i}^2 - r_{A,i}^2`,

   .. math:: z = \frac{\sum_i l_i - (k_A - k_B) \ln n}{\sqrt{n}\, \operatorname{sd}(l)},

   and :math:`|z| < 1.96` (5 %, two-sided). It does not assume that either model is right: its scale is
   the spread of the pointwise differences, which a systematic misfit widens, not the noise alone. (Where
   the predictions coincide the spread vanishes and the statistic says nothing: Vuong's own first step,
   the variance test, then declares the models equivalent -- the *within the noise* case above.)
2. **They remove the same error.** Their improvements over the model without either,
   :math:`d_A = r_0 - r_A` and :math:`d_B = r_0 - r_B`, are collinear: more of each lies along the other
   than across it, :math:`\cos^2(d_A, d_B) \ge 1/2`. Two effects that each explain a *different* part of
   the error about equally well pass test 1 but not this one; the greedy rounds then find both.

Neither test needs a model evaluation: both use the outputs of the fits already made.
"""

from __future__ import annotations

import math

import numpy as np

from bscomp.kernel.interface import NotApplicable
from bscomp.validate.evaluation import residual_blocks

__all__ = ["Z_CRIT", "SHARED", "residual_vector", "compare_fits", "mark_equivalent", "simpler_first", "tell_apart"]

Z_CRIT = 1.959963984540054
"""Two-sided 5 % point of the standard normal: Vuong's statistic below it prefers neither model."""

SHARED = 0.5
"""Least share ``cos^2`` of each improvement along the other's for "the same error" (more along than across)."""


def residual_vector(outputs, datasets, sigmas) -> np.ndarray:
    """Every whitened residual of every dataset (FRF blocks, whole time series) as one vector.

    Parameters
    ----------
    outputs : list
        Model outputs per dataset (:meth:`~bscomp.validate.evaluation.Evaluator.outputs`).
    datasets : list of FrfData / TimeData
    sigmas : list
        Noise levels per dataset (:func:`~bscomp.validate.evaluation.noise_levels`).

    Returns
    -------
    ndarray
        Residuals in units of their block's noise level (non-finite ones as 1e6, as the fits see them).
    """
    parts = [np.where(np.isfinite(b), b, 1e6) for y, d, s in zip(outputs, datasets, sigmas)
             for b in residual_blocks(y, d, s)]
    return np.concatenate(parts) if parts else np.zeros(0)


def compare_fits(r_a, r_b, r_0, k_a: int, k_b: int, z_crit: float = Z_CRIT, shared: float = SHARED) -> dict:
    r"""Can the data tell fitted model ``A`` from fitted model ``B``? (the two tests of the module docstring)

    Parameters
    ----------
    r_a, r_b : array
        Whitened residuals of the two fitted models (:func:`residual_vector`).
    r_0 : array
        The same for the model without either effect.
    k_a, k_b : int
        Fitted parameters of each (the Schwarz correction).
    z_crit, shared : float
        Thresholds of the two tests.

    Returns
    -------
    dict
        ``D`` (:math:`\sum \delta_i^2`, the predictions' whitened distance), ``z`` (Vuong's statistic; > 0:
        ``A`` fits better; 0 where the predictions coincide), ``dchi2`` (:math:`\chi^2_B - \chi^2_A`),
        ``shared`` (:math:`\cos^2` of the improvements), ``n`` (data points) and ``indistinguishable`` (both
        tests hold).
    """
    r_a, r_b, r_0 = (np.asarray(v, float) for v in (r_a, r_b, r_0))
    n = r_a.size
    delta = r_a - r_b                                   # = prediction of B minus prediction of A, whitened
    dist = float(delta @ delta)
    lik = r_b * r_b - r_a * r_a
    num = float(np.sum(lik)) - (k_a - k_b) * math.log(max(n, 2))
    sd = float(np.std(lik, ddof=1)) if n > 1 else 0.0
    z = num / (math.sqrt(n) * sd) if sd > 0.0 else 0.0
    d_a, d_b = r_0 - r_a, r_0 - r_b
    na, nb, ab = float(d_a @ d_a), float(d_b @ d_b), float(d_a @ d_b)
    cos2 = ab * ab / (na * nb) if na > 0.0 and nb > 0.0 else float(na == nb)
    same = ab >= 0.0 and cos2 >= shared
    alike = math.sqrt(dist) / 2.0 < z_crit or abs(z) < z_crit
    return {"D": dist, "z": z, "dchi2": float(np.sum(lik)), "shared": cos2, "n": int(n),
            "indistinguishable": bool(alike and same)}


def mark_equivalent(results, current, datasets, sigmas, system=None, z_crit: float = Z_CRIT,
                    shared: float = SHARED) -> None:
    """Fill ``equivalent`` of every refined :class:`~bscomp.validate.diagnosis.EffectFit` of a round.

    Parameters
    ----------
    results : list of EffectFit
        One round's fits (each with its outputs in ``_after``), in ranking order.
    current : dict
        The summary of the model without the round's candidates (its ``outputs``).
    datasets, sigmas
        As :func:`residual_vector`.
    system : System, optional
        The nominal model, to name the insertion points in :func:`tell_apart`.
    z_crit, shared : float
        Thresholds of :func:`compare_fits`.

    Notes
    -----
    ``r.equivalent`` maps each other candidate that ``r`` cannot be told apart from to the test numbers
    (seen from ``r``: ``z > 0`` when ``r`` fits better) and the words of :func:`tell_apart`. The relation is
    symmetric and not transitive: each candidate lists its own. ``r.compared`` holds the numbers of every
    pair, grouped or not (why a candidate is named alone).
    """
    fits = [r for r in results if r.refined and getattr(r, "_after", None) is not None]
    if len(fits) < 2:
        return
    r_0 = residual_vector(current["outputs"], datasets, sigmas)
    vec = {id(r): residual_vector(r._after["outputs"], datasets, sigmas) for r in fits}
    for i, a in enumerate(fits):
        for b in fits[i + 1:]:
            ka, kb = len(a.candidate.parameters), len(b.candidate.parameters)
            st = compare_fits(vec[id(a)], vec[id(b)], r_0, ka, kb, z_crit, shared)
            a.compared[b.name] = dict(st)
            b.compared[a.name] = {**st, "z": -st["z"], "dchi2": -st["dchi2"]}
            if not st.pop("indistinguishable"):
                continue
            how = tell_apart(a.candidate, b.candidate, system)
            a.equivalent[b.name] = {**st, "tell_apart": how}
            b.equivalent[a.name] = {**st, "z": -st["z"], "dchi2": -st["dchi2"], "tell_apart": how}


def simpler_first(results) -> None:
    """Within candidates the data cannot tell apart (``equivalent``, :func:`mark_equivalent`), name the one with
    the lower BIC first: the same fit within noise with fewer parameters (a bearing housing whose fitted mass is
    too light to show its own mode and whose fastener damping is fitted is a damped spring in series, as the
    nut-table joint is; the error alone ordered them by round-off). In place; other candidates keep their order.
    """
    moved = True
    while moved:
        moved = False
        for i in range(len(results) - 1):
            a, b = results[i], results[i + 1]
            if b.name in a.equivalent and b.delta_bic < a.delta_bic:
                results[i], results[i + 1] = b, a
                moved = True


def _where(point) -> str:
    """The sensor that sees an insertion point's own deflection, in words."""
    doc = f" [{point.doc}]" if point.doc else ""
    if point.kind == "connection" and len(point.ports) >= 2:
        return f"the relative motion across {point.ports[0]} - {point.ports[1]}{doc}"
    if point.kind == "parameter":
        return f"{', '.join(point.parameters)} on its own (a static test of that part){doc}"
    if point.kind == "all":
        return f"the damping of each mode (a modal test){doc}"
    if point.ports:
        return f"the motion at {point.ports[0]}{doc}"
    return f"the '{point.role}' point{doc}"


def tell_apart(cand_a, cand_b, system=None) -> str:
    """What to measure to tell two indistinguishable candidates apart, in words.

    Two effects at different insertion points each deflect their own joint and leave the other's rigid: a
    sensor across either point separates them. Two effects at the same point (Coulomb vs Stribeck friction)
    differ only in their law: a record that exercises where the laws differ separates them.

    Parameters
    ----------
    cand_a, cand_b : Candidate
    system : System, optional
        The nominal model (its validation interface names the points); without it, the roles are named.

    Returns
    -------
    str
    """
    points = []
    for c in (cand_a, cand_b):
        try:
            points.append(c.applicable(system) if system is not None else None)
        except NotApplicable:
            points.append(None)
    pa, pb = points
    if pa is not None and pb is not None:
        if (pa.role, pa.ports, pa.parameters) == (pb.role, pb.ports, pb.parameters):
            return (f"both act at the same point ({_where(pa)}): only a test that exercises where their laws "
                    f"differ can separate them")
        return (f"measure {_where(pa)}, which {cand_a.name} deflects, or {_where(pb)}, which {cand_b.name} "
                f"deflects; the measured outputs see both alike")
    if cand_a.role == cand_b.role:
        return (f"both act at the '{cand_a.role}' point: only a test that exercises where their laws differ "
                f"can separate them")
    return (f"measure at the '{cand_a.role}' point ({cand_a.name}) or at the '{cand_b.role}' point ({cand_b.name}); "
            f"the measured outputs see both alike")
