r"""Does a candidate effect do something the parameters already free cannot? Its own share of its action.

An effect fitted together with the uncertain parameters and the effects accepted before can lower the error
without being missing: when what it does to the outputs is almost what a change of those parameters does,
the fit *re-distributes* -- a motor inertia of 2e-5 kg m^2 with 8.9 kg taken off the re-calibrated table
mass, both rigid-body inertia -- and the little that differs absorbs whatever model-form error is left
(there: the shape of a clearance's corner). Whether such a fit passes the error-drop rule then depends on how
far the optimizer gets, not on the data.

The test is collinearity of sensitivities, read off the fit's Jacobian :math:`J` (whitened residuals by
log-parameters, the metric of the fit). With :math:`J_c` the candidate's columns and :math:`P` the projector
onto the span of the other columns (the uncertain parameters and the effects accepted before), the share
of the candidate's action that is its own is that of its most independent direction,

.. math::

    s = \max_{v} \frac{\lVert (I - P) J_c v\rVert^2}{\lVert J_c v\rVert^2} = 1 - \rho_{\min}^2,

:math:`\rho_{\min}` the smallest canonical correlation between the candidate's columns and the others. For a
one-parameter effect :math:`1/s` is its variance inflation factor: how much its variance grows because the
others can do what it does (Marquardt, Technometrics 12, 1970; Kutner et al., *Applied Linear Statistical
Models*, Sec 10.5: above 10, the collinearity unduly influences the estimates). For several parameters the
most independent direction counts: a table sub-assembly's mass alone is almost the table mass
(:math:`|\rho|` 0.998), the sub-assembly with its own mode is not (:math:`s` 0.98).

Measured on the bundled truths (:mod:`bscomp.systems.truths` and the lumped cases of
:mod:`bscomp.validate.synthetic`): every accepted effect has :math:`s` 0.39 to 1.0; ``missing_inertia``
fitted beside a re-calibrated table mass 0.0005 to 0.004 in every case (variance inflation 250 to 2,000),
0.02 once; candidates that only stand in for something else 0.05 to 0.2. An effect is not accepted when
:math:`s <` :data:`MIN_OWN_SHARE` = 0.1 (variance inflation above 10).
"""

from __future__ import annotations

import numpy as np

__all__ = ["own_share", "MIN_OWN_SHARE"]

MIN_OWN_SHARE = 0.1
"""Least share of its action an effect must do on its own (variance inflation at most 10)."""


def _basis(a: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the column space of ``a`` (numerically zero directions dropped)."""
    if a.size == 0:
        return np.zeros((a.shape[0], 0))
    u, s, _ = np.linalg.svd(a, full_matrices=False)
    return u[:, s > rtol * max(float(s[0]) if s.size else 0.0, 1e-300)]


def own_share(jac, mine, labels=None, partners: int = 2) -> tuple:
    """The share of a candidate's action the other free parameters cannot reproduce (module docstring).

    Parameters
    ----------
    jac : array, shape (n_residuals, n_parameters)
        Jacobian of the fit's residuals at its solution.
    mine : sequence of int
        Columns of the candidate's parameters.
    labels : sequence of str, optional
        Names of all columns, to name the partners.
    partners : int
        Most partners named.

    Returns
    -------
    (float, list)
        The share :math:`s` in [0, 1] (0 when the candidate does nothing at all), and
        ``[(label, |cos|)]``: the other parameters most aligned with the candidate's most independent
        direction, best first (those with ``|cos| >= 0.5``).
    """
    jac = np.asarray(jac, float)
    mine = list(mine)
    others = [j for j in range(jac.shape[1]) if j not in mine]
    uc = _basis(jac[:, mine])
    if uc.shape[1] == 0:
        return 0.0, []
    uo = _basis(jac[:, others])
    resid = uc - uo @ (uo.T @ uc)
    _, s, vt = np.linalg.svd(resid, full_matrices=False)
    share = float(min(max(s[0] ** 2, 0.0), 1.0))
    if labels is None or not others:
        return share, []
    u = uc @ vt[0]
    cols = jac[:, others]
    norms = np.linalg.norm(cols, axis=0)
    cos = np.abs(u @ cols) / np.where(norms > 0, norms, np.inf)
    order = np.argsort(-cos)[:partners]
    return share, [(labels[others[j]], float(cos[j])) for j in order if cos[j] >= 0.5]
