"""Compiled Functions (bscomp.simulation.native): the matrix product's loop order and the compiler flags."""

import shutil

import casadi as ca
import numpy as np
import pytest

from bscomp.simulation import native

pytestmark = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc")), reason="needs a C compiler")


def _products():
    """Dense products of the shapes the modal steps use (rows 4-35, columns 2-98), chained so the sums carry."""
    x = ca.MX.sym("x", 98)
    A, B, C = ca.MX.sym("A", 35, 98), ca.MX.sym("B", 9, 7), ca.MX.sym("C", 88, 17)
    y = ca.mtimes(A, x)
    w = ca.mtimes(B, y[:7]) + y[7:16]
    z = ca.mtimes(C, ca.vertcat(w, y[16:24]))
    return ca.Function("products", [x, A, B, C], [ca.vertcat(y, w, z)])


def test_casadi_still_writes_the_product_native_reorders():
    """The generated C holds the row-by-row loop ``_axpy_order`` swaps (a CasADi that writes it differently would
    silently lose the speed, not the numbers: this says so)."""
    cg = ca.CodeGenerator("p.c", {"with_header": False})
    cg.add(_products())
    src = cg.dump()
    assert native._DOT_ORDER in src
    assert native._AXPY_ORDER in native._axpy_order(src) and native._DOT_ORDER not in native._axpy_order(src)


def test_compiled_products_equal_the_virtual_machine_to_the_bit(tmp_path):
    """Each ``z_j`` sums its terms in the same order after the loop swap: the compiled products equal CasADi's
    virtual machine exactly (no reassociation, no fused multiply-add under the default flags)."""
    f = _products()
    rng = np.random.default_rng(3)
    args = [rng.standard_normal(f.size_in(i)) * 10.0 ** rng.uniform(-6, 6, f.size_in(i)) for i in range(4)]
    ref = np.asarray(f(*args))
    got = np.asarray(native.native_function(f, cache_dir=tmp_path)(*args))
    assert np.array_equal(got, ref)


def test_every_product_gets_a_copy_of_its_own_sizes():
    """``_fixed_products`` leaves no call of CasADi's run-time-sized product in the generated C of the modal steps'
    shapes: each is a copy with its sizes written in (a CasADi that writes the call differently would silently lose
    the speed: this says so)."""
    cg = ca.CodeGenerator("p.c", {"with_header": False})
    cg.add(_products())
    src = native._fixed_products(native._axpy_order(cg.dump()))
    calls = [line for line in src.splitlines() if "casadi_mtimes_dense(" in line and "void" not in line]
    assert calls == []
    for a, b in ((35, 98), (9, 7), (88, 17)):
        assert f"bscomp_mv_{a}_{b}_1(" in src


def test_sized_matrix_products_equal_the_virtual_machine_to_the_bit(tmp_path):
    """A product of two matrices (several columns) through its sized copy: the virtual machine's numbers."""
    A, B = ca.MX.sym("A", 13, 6), ca.MX.sym("B", 6, 5)
    f = ca.Function("matmat", [A, B], [ca.mtimes(A, B) + 1.0])
    rng = np.random.default_rng(5)
    args = [rng.standard_normal(f.size_in(i)) * 10.0 ** rng.uniform(-6, 6, f.size_in(i)) for i in range(2)]
    got = np.asarray(native.native_function(f, cache_dir=tmp_path)(*args))
    assert np.array_equal(got, np.asarray(f(*args)))


def test_flags_are_part_of_the_cache_key(tmp_path, monkeypatch):
    """Other compiler flags build another library: a cached -O3 one is never loaded for ``-O1``."""
    f = _products()
    native.native_function(f, cache_dir=tmp_path)
    monkeypatch.setenv("BSCOMP_JIT_CFLAGS", "-O1")
    native.native_function(f, cache_dir=tmp_path)
    assert len(list((tmp_path / "jit").glob("products_*.so"))) == 2


def test_a_library_for_another_cpu_is_not_loaded(tmp_path, monkeypatch):
    """With ``-march=native`` the CPU is part of the key: another CPU (a shared home directory on a cluster) builds
    its own library instead of loading one that may not run there."""
    monkeypatch.delenv("BSCOMP_JIT_CFLAGS", raising=False)
    monkeypatch.setattr(native, "_CPU", "cpu-a")
    f = _products()
    native.native_function(f, cache_dir=tmp_path)
    monkeypatch.setattr(native, "_CPU", "cpu-b")
    native.native_function(f, cache_dir=tmp_path)
    assert len(list((tmp_path / "jit").glob("products_*.so"))) == 2


def test_flags_the_compiler_refuses_fall_back(tmp_path, monkeypatch):
    """A compiler that does not know the CPU flags still compiles the library (with :data:`CFLAGS` alone), and the
    numbers are the virtual machine's."""
    monkeypatch.delenv("BSCOMP_JIT_CFLAGS", raising=False)
    monkeypatch.setattr(native, "_CPU", "cpu-x")
    monkeypatch.setattr(native, "NATIVE_CFLAGS", "-mno-such-flag-bscomp")
    f = _products()
    args = [np.linspace(-1.0, 1.0, f.nnz_in(i)).reshape(f.size_in(i), order="F") for i in range(4)]
    got = np.asarray(native.native_function(f, cache_dir=tmp_path)(*args))
    assert np.array_equal(got, np.asarray(f(*args)))


def test_a_bad_flag_of_the_user_is_a_named_error(tmp_path, monkeypatch):
    """``$BSCOMP_JIT_CFLAGS`` is used as given: a flag the compiler refuses is an error that quotes the compiler."""
    monkeypatch.setenv("BSCOMP_JIT_CFLAGS", "-O2 -mno-such-flag-bscomp")
    with pytest.raises(native.BscompError, match="compiling products failed"):
        native.native_function(_products(), cache_dir=tmp_path)


def test_numpy_call_passes_a_matrix_column_by_column():
    """NumpyCall hands a numpy matrix to CasADi column by column (CasADi's storage): ``A b`` for a non-symmetric
    ``A`` is numpy's ``A @ b``, not ``A.T @ b``."""
    from bscomp.simulation.modal_kernels import NumpyCall

    A, b = ca.SX.sym("A", 3, 2), ca.SX.sym("b", 2)
    call = NumpyCall(ca.Function("Ab", [A, b], [ca.mtimes(A, b)]))
    An = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    np.testing.assert_array_equal(call(An, np.array([1.0, -1.0]))[0].ravel(), An @ np.array([1.0, -1.0]))
