"""The one real block-diagonal (modal) form, bscomp.linear.real_form.modal_basis, and its two users: the
modal transcription of bscomp.optimal and the compiled time series of CompiledModel (diagnose's engine).

Exact identities: ``P Λ P^-1 = A``; the blocks carry the eigenvalues of ``A``; a free undamped rigid body is
one nilpotent (Jordan) block; stepping the compiled model in the block form gives the dense stepping's
outputs to round-off.
"""

import numpy as np
import pytest

from bscomp.linear import modal_basis as exported
from bscomp.linear.real_form import ModalError, modal_basis
from bscomp.optimal import coordinates
from bscomp.simulation import compiled_time
from bscomp.simulation.compiled import CompiledModel
from bscomp.systems import get

OUTS = ["rotor.phi", "rotor.w", "table.s", "table.a"]


def _chain(k=(4e6, 9e6), m=(2.0, 3.0, 5.0), c=30.0, free=True):
    """A three-mass chain, first-order form [q; q'], free (rigid body) or grounded through k[0]."""
    n = len(m)
    K = np.zeros((n, n))
    for i, ki in enumerate(k):
        K[i:i + 2, i:i + 2] += ki * np.array([[1.0, -1.0], [-1.0, 1.0]])
    if not free:
        K[0, 0] += 1e6
    C = c / k[0] * K
    Minv = np.diag(1.0 / np.asarray(m))
    return np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])


def test_one_implementation_for_both_users():
    assert coordinates.modal_basis is modal_basis and exported is modal_basis
    assert coordinates.ModalError is ModalError
    assert compiled_time.modal_basis is modal_basis


@pytest.mark.parametrize("free", [True, False])
def test_block_form_reproduces_the_matrix_and_its_eigenvalues(free):
    A = _chain(free=free)
    b = modal_basis(A)
    assert np.max(np.abs(b["P"] @ b["Lam"] @ b["Pinv"] - A)) < 1e-9 * np.max(np.abs(A))
    cols = np.concatenate([idx for idx, _, _ in b["blocks"]])
    assert np.array_equal(cols, np.arange(A.shape[0]))                      # contiguous, in order
    Lam = b["Lam"]
    mask = np.zeros_like(Lam, bool)
    for idx, _, _ in b["blocks"]:
        mask[np.ix_(idx, idx)] = True
    assert np.all(Lam[~mask] == 0.0)                                          # block diagonal
    # the eigenvalues of the blocks are A's (a double zero splits into +-sqrt(eps |A|) ~ 1e-5 numerically)
    lam = np.sort_complex(np.linalg.eigvals(A))
    got = np.sort_complex(np.concatenate([np.linalg.eigvals(Lam[np.ix_(i, i)]) for i, _, _ in b["blocks"]]))
    assert np.allclose(got, lam, rtol=1e-9, atol=1e-7 * np.max(np.abs(lam)))
    kinds = [k for _, k, _ in b["blocks"]]
    if free:   # the undamped rigid body: one 2x2 nilpotent block at the end, not two ill-conditioned vectors
        idx, kind, _ = b["blocks"][-1]
        Z = Lam[np.ix_(idx, idx)]
        assert kind == "zero" and idx.size == 2 and kinds.count("zero") == 1
        assert np.max(np.abs(Z @ Z)) < 1e-6 * np.max(np.abs(Lam)) and np.max(np.abs(Z)) > 0
        assert b["cond"] < 1e6
    else:
        assert "zero" not in kinds and kinds.count("pair") == 3


def test_a_defective_eigenvalue_is_refused():
    """A Jordan block away from zero has no block-diagonal real form: refused, not a wrong diagonal."""
    with pytest.raises(ModalError, match="defective"):
        modal_basis(np.array([[-1.0, 1.0], [0.0, -1.0]]))


@pytest.mark.parametrize("guide_d", [None, 0.0])
def test_compiled_time_series_in_the_block_form_equals_dense_stepping(monkeypatch, guide_d):
    """validation_drive as declared (viscous guideway: the rigid body's eigenvalues 0 and -d/m) and with
    the guideway damping removed (an undamped free rigid body: one 2x2 zero block, which the old
    eigenvector form could not represent and stepped densely). Measured: 2e-14 of each output's peak with
    the declared damping; the free rigid body 4e-13, table.a 1.5e-9 (dense and block form each against the
    exact ZOH of the full model: 7e-11 and 1.6e-9 -- the acceleration's cancellation through the Jordan
    block's basis)."""
    s = get("validation_drive")
    if guide_d is not None:
        s.set("guide.d", guide_d)
    t = np.arange(0.0, 0.2, 5e-4)
    u = 2.125 * np.sign(np.sin(2 * np.pi * 5 * t) + 1e-12)
    cm = CompiledModel(s, ["amp.u"], OUTS)
    mm = cm.modal({})
    n2 = 2 * mm.keep.size
    blocks = cm._discrete(mm, 5e-4, 1, 0.0, OUTS)[1]
    assert blocks is not None and sum(blocks) == n2
    if guide_d == 0.0:
        assert blocks == (2, 2, 2)                     # two modes and the free rigid body's Jordan block
    Y = cm.simulate({}, t, {"amp.u": u})
    monkeypatch.setattr(compiled_time, "real_modal_form", lambda A, *a, **k: None)
    dense = CompiledModel(s, ["amp.u"], OUTS).simulate({}, t, {"amp.u": u})
    for o in OUTS:
        tol = 1e-8 if (guide_d == 0.0 and o == "table.a") else 1e-11
        assert np.max(np.abs(Y[o] - dense[o])) < tol * np.max(np.abs(dense[o])), o
