"""Sensitivities of a :class:`~bscomp.simulation.compiled.CompiledModel`'s matrices to a structural parameter.

``M``, ``K`` and the components' ``C`` are affine in a stiffness, mass or damping parameter; the derivative is taken
from the component's own structural block at three values (exact, no re-flattening), verified once per component
type and parameter against a re-flattened model, and the re-flattening itself where the block is not available. A
parameter at 0 (a damping the model leaves out, which a candidate turns on) is probed at 0 and +-1 (the blocks,
evaluated directly) or at 0, 0.1 and 0.2 (re-flattened: a physical bound forbids a negative value).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bscomp.kernel.flattening import flatten
from bscomp.linear.frf_engine import dense
from bscomp.linear.linearization import second_order

__all__ = ["affine", "probe_values", "dense_sens", "block_sensitivity", "verify", "flatten_sensitivity",
           "damped_beyond_static", "DAMPING_COUPLING"]

#: A mode above the kept band stays dynamic when a component dashpot's force on it, at the band's top frequency, is
#: more than this fraction of its own stiffness (a local dashpot: the static residual would be wrong).
DAMPING_COUPLING = 1e-3


def affine(A0, A1, A2, rtol) -> bool:
    """True if the matrices at ``v0``, ``1.1 v0`` and ``0.9 v0`` (or three equidistant values) lie on a line:
    ``(A1 + A2)/2 = A0`` to ``rtol`` of ``max |A0|``."""
    mid = sp.csr_matrix(0.5 * (sp.csr_matrix(A1) + sp.csr_matrix(A2)) - sp.csr_matrix(A0))
    return not (mid.nnz and abs(mid).max() > rtol * max(abs(sp.csr_matrix(A0)).max(), 1e-300))


def probe_values(v0) -> tuple:
    """Where a structural block is evaluated for its sensitivity: ``v0`` and +-10 %, or for a parameter at 0 (a damping
    the model leaves out) 0 and +-1: the block's matrices are evaluated directly, so a negative value is allowed."""
    return (v0, 1.1 * v0, 0.9 * v0) if v0 else (0.0, 1.0, -1.0)


def dense_sens(sens):
    """``(v0, dM, dK, dC)`` with the matrices dense: :meth:`CompiledModel._modal` sums them densely."""
    v0, dM, dK, dC = sens
    return v0, dense(dM, float), dense(dK, float), dense(dC, float)


def block_sensitivity(cm, name, v0):
    """``(v0, dM, dK, dC)`` on the reduced coordinates from the component's ``structure()`` block."""
    path, _, pname = name.rpartition(".")
    comp = cm.linear_system.component(path)
    m = cm.dae.mech
    blocks = []
    old = comp._values[pname]
    try:
        for val in probe_values(v0):
            comp._values[pname] = val
            blocks.append(comp.structure())
    finally:
        comp._values[pname] = old
    if any(b is None for b in blocks):
        return None
    try:
        rows = [m.port_coordinates[f"{path}.{d}"] for d in blocks[0].dofs]
    except KeyError:
        return None
    P = sp.csr_matrix(m.T)[rows]
    out = []
    for attr in ("M", "K", "C"):
        A0, A1, A2 = (sp.csr_matrix(getattr(b, attr)) if getattr(b, attr) is not None
                      else sp.csr_matrix((len(rows), len(rows))) for b in blocks)
        if not affine(A0, A1, A2, 1e-9):
            return None                                   # not affine in the parameter
        out.append(sp.csr_matrix(P.T @ ((A1 - A2) / (0.2 * v0 if v0 else 2.0)) @ P))
    dM, dK, dC = out
    return (v0, dM, dK, dC)


def verify(cm, name, v0, sens) -> bool:
    ref = flatten_sensitivity(cm, name, v0, steps=(1.1,))
    if ref is None:
        return False
    _, dM, dK, dC = sens
    ok = True
    for a, b in ((dM, ref[1]), (dK, ref[2]), (dC, ref[3])):
        d = (a - b).tocsr()
        scale = max(abs(b).max() if b.nnz else 0.0, abs(a).max() if a.nnz else 0.0, 1e-300)
        ok &= bool(d.nnz == 0 or abs(d).max() <= 1e-6 * scale)
    return ok


def flatten_sensitivity(cm, name, v0, steps=(1.1, 0.9)):
    """Sensitivity by re-flattening at ``v0 * step`` (one step: forward difference, used to verify). A parameter at
    0 is re-flattened at ``step - 0.9`` (0.2 and 0; one step: 0.2), its line checked at 0.1."""
    vals = [v0 * f for f in steps] if v0 else [f - 0.9 for f in steps]
    mats = []
    for val in vals + ([0.1] if not v0 and len(steps) == 2 else []):
        d = flatten(cm.linear_system.with_parameters({name: val}))
        so = second_order(d, refresh_damping=False, **cm._so_args)
        if so.coordinates != cm.so0.coordinates:
            return None
        C = so.C - (sp.csr_matrix(d.system_damping_basis[2]) if cm.damping is not None else 0)
        mats.append((so, sp.csr_matrix(C)))
    C0 = sp.csr_matrix(cm.so0.C - (cm._Cadd0 if cm._Cadd0 is not None else 0))
    if len(steps) == 1:
        (s1, C1), = mats
        dv = (steps[0] - 1.0) * v0 if v0 else vals[0]
        return (v0, sp.csr_matrix((s1.M - cm.so0.M) / dv), sp.csr_matrix((s1.K - cm.so0.K) / dv),
                sp.csr_matrix((C1 - C0) / dv))
    (s1, C1), (s2, C2) = mats[:2]
    dv = (steps[0] - steps[1]) * v0 if v0 else vals[0] - vals[1]
    mid, Cm = (cm.so0, C0) if v0 else mats[2]
    for A0, A1, A2 in ((mid.M, s1.M, s2.M), (mid.K, s1.K, s2.K), (Cm, C1, C2)):
        if not affine(A0, A1, A2, 1e-8):
            return None
    for attr in ("B", "Cq", "Cv", "Ca", "D"):
        diff = sp.csr_matrix(getattr(s1, attr) - getattr(cm.so0, attr))
        if diff.nnz and abs(diff).max() > 1e-10 * max(abs(getattr(cm.so0, attr)).max(), 1e-300):
            return None
    return (v0, sp.csr_matrix((s1.M - s2.M) / dv), sp.csr_matrix((s1.K - s2.K) / dv),
            sp.csr_matrix((C1 - C2) / dv))


def damped_beyond_static(phi, lam, C, keep, w_top) -> np.ndarray:
    """Modes a static residual cannot stand for: elastic modes ``t`` outside ``keep`` that the damping ``C`` (physical
    coordinates) couples to a kept mode ``k`` by more than :data:`DAMPING_COUPLING` of their own stiffness at the band's
    top, ``w_top |phi_t^T C phi_k| > DAMPING_COUPLING lam_t``: the static residual leaves that force out. A local
    dashpot (a bearing's axial damping of 3e4 N s/m on the FE test bed) couples the drive's modes to high ones; with
    them as statics the table FRF was 44 % off near 1 kHz and a 0.6 s square-wave run 1.1e-3 (NRMSE of table.a); with
    those above the threshold kept (9 -> 47 modes) 3.4e-3 at the FRF's worst point and 8.5e-6, at 3x the run's cost
    (1e-4: 66 modes, 1.5e-5 and 4e-8 at 9x). A damping near-diagonal in the modes (the thesis's modal damping, a table
    part's dashpot) couples none; a bearing housing's dashpot one. :class:`CompiledModel` asks only for a model without
    cut elements: a clearance's own contact damping (1e3 N s/m) coupled the nut's mode above the band, and keeping it
    dynamic moved a compliant-backlash fit (seed 2201) from 1.17x the noise floor to a contact at its bound, 32x."""
    el = np.flatnonzero(lam > 0.0)
    el = el[~np.isin(el, keep)]
    if el.size == 0 or not np.any(C):
        return np.zeros(0, int)
    Cm = phi[:, el].T @ C @ phi[:, keep]
    return el[np.max(np.abs(Cm), axis=1) * w_top > DAMPING_COUPLING * lam[el]]
