"""Jacobians through the Function's buffer (``Dae.jacobians_at``, :class:`bscomp.kernel.buffer_call.SparseCall`)
are the numbers of ``Dae.jacobians(...)`` bit for bit, with the same structural pattern."""

from concurrent.futures import ThreadPoolExecutor

import casadi as ca
import numpy as np
import pytest

from bscomp import flatten
from bscomp.kernel.buffer_call import SparseCall
from bscomp.kernel.dae import _sp
from bscomp.systems.testbed import testbed as build_testbed
from bscomp.systems.thesis_effects import with_friction_backlash


@pytest.fixture(scope="module")
def dae():
    """The axial + torsional test bed with the moving nut, friction and backlash (nonlinear scalar equations beside
    the structural matrices, a parameter-dependent joint)."""
    return flatten(with_friction_backlash(build_testbed("axial_torsional", "C", nut_joint="moving")))


def _point(dae, seed):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=dae.nx), np.asarray(dae.x_start, float) + 1e-5 * rng.normal(size=dae.nx),
            np.asarray(dae.z_start, float), rng.normal(size=dae.nu), dae.p0)


def test_jacobians_at_equals_the_function_call_bit_for_bit(dae):
    args = _point(dae, 0)
    ref = dae.jacobians(*args)
    got = dae.jacobians_at(*args)
    assert np.array_equal(got[0], np.asarray(ref[0]).ravel())
    for J, R in zip(got[1:], ref[1:], strict=True):
        R = _sp(R)
        assert J.shape == R.shape
        assert np.array_equal(J.indptr, R.indptr) and np.array_equal(J.indices, R.indices)
        assert np.array_equal(J.data, R.data)
    assert got[2].nnz > 0 and got[3].shape == (dae.nx, dae.nz)


def test_results_are_not_overwritten_by_the_next_call_and_threads_get_their_own(dae):
    a, b = _point(dae, 1), _point(dae, 2)
    first = dae.jacobians_at(*a)
    kept = first[2].data.copy()
    dae.jacobians_at(*b)
    assert np.array_equal(first[2].data, kept)
    with ThreadPoolExecutor(4) as ex:
        runs = list(ex.map(lambda s: dae.jacobians_at(*(a if s % 2 else b))[2].data, range(16)))
    ref_a, ref_b = _sp(dae.jacobians(*a)[2]).data, _sp(dae.jacobians(*b)[2]).data
    assert not np.array_equal(ref_a, ref_b)
    for s, d in enumerate(runs):
        assert np.array_equal(d, ref_a if s % 2 else ref_b)


def test_a_wrong_argument_names_it():
    x = ca.SX.sym("x", 2)
    call = SparseCall(ca.Function("f", [x], [ca.sparsify(ca.diag(x))], ["x"], ["J"]))
    assert np.array_equal(call([1.0, 2.0])[0].toarray(), np.diag([1.0, 2.0]))
    with pytest.raises(ValueError, match="argument x has 3 numbers, 2 expected"):
        call([1.0, 2.0, 3.0])
    with pytest.raises(TypeError, match="1 arguments expected"):
        call([1.0, 2.0], [0.0])
