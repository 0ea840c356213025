"""A system damping inside an exported FMU when tunable parameters change the mass or stiffness.

A drive's system damping (:mod:`bscomp.kernel.system_damping`) is a matrix ``C_add(M, K)`` computed at
flattening from the undamped ``M, K`` at the start point; :meth:`bscomp.System.set` re-flattens and so
recomputes it. An FMU parameter that changes ``M`` or ``K`` can only do the same if the FMU evaluates
``C_add`` from its parameters:

* **Rayleigh** (:class:`~bscomp.kernel.damping.RayleighDamping`), ``C_add = alpha M + beta K`` with
  ``alpha, beta`` fixed (given, or from ratios at two given frequencies): exact. The FMU evaluates
  ``C_add(p) v = alpha M(p) v + beta K(p) v`` from the Jacobians of the residual's force balances at the
  start point, as :func:`bscomp.kernel.mechanics.start_matrices` reads ``M`` and ``K`` -- a few sparse
  products per call, no eigenvalue problem. A drive whose ``M, K`` need internal algebraic variables
  eliminated (a Schur complement; none of the shipped drives, whose signals flattening substitutes) is
  refused rather than handled by an untested path.
* **Modal** (:class:`~bscomp.kernel.damping.ModalDamping`, the test bed's ``DriveModalDamping``),
  ``C_add = M Phi diag(2 zeta_k omega_k) Phi^T M``: needs the modes ``Phi, omega`` of ``(K, M)``. With one
  ratio for every elastic mode it is ``2 zeta M (M^-1 K)^(1/2)``, still a matrix square root; with ratios by
  mode character (``DriveModalDamping``: 6 % axial, 10 % torsional, by kinetic-energy fraction) it needs
  the eigenvectors themselves. The generated C code has no eigensolver (CasADi cannot code-generate one),
  and a fixed-iteration square root of a dense 98 x 98 matrix per derivative call would cost ~10^7
  flops, 100x the model. Refused, with the alternatives in the message.
"""

from __future__ import annotations

import casadi as ca

from bscomp.errors import FmuExportError
from bscomp.kernel.dae import dm_sparse
from bscomp.kernel.damping import RayleighDamping

__all__ = ["check_damping_parameters", "rayleigh_term"]


def _mk_dependent(dae, names):
    """The names among ``names`` that enter the mass or stiffness (``dF/dx'`` or ``dF/dq``)."""
    q = [dae.xs[i] for i in dae.mech.q_in_x.values()]
    J = ca.jacobian(dae.F_sx, ca.vertcat(dae.xds, *q)) if q else ca.jacobian(dae.F_sx, dae.xds)
    return [n for n in names if ca.depends_on(J, dae.ps[dae.p_names.index(n)])]


def check_damping_parameters(dae, names) -> bool:
    """Whether the FMU must evaluate the system damping from its parameters (a Rayleigh damping and a tunable
    parameter in M or K); refuse a modal damping with such a parameter.

    Raises
    ------
    FmuExportError
        A tunable parameter enters M or K and the damping is not Rayleigh, or the drive has internal
        differential states (no second-order form to evaluate the Rayleigh matrix on).
    """
    damping = getattr(dae, "system_damping", None) or getattr(dae.system, "damping", None)
    if damping is None or not names:
        return False
    hit = _mk_dependent(dae, names)
    if not hit:
        return False
    if not isinstance(damping, RayleighDamping):
        raise FmuExportError(
            f"export_fmu: parameter '{hit[0]}' enters the mass or stiffness of '{dae.name}', whose damping matrix "
            f"({type(damping).__name__}) is computed from its modes at flattening: System.set would recompute it, "
            "and an FMU cannot (the modes need an eigensolver the generated code does not have; docs/fmu.md). "
            "Fix the value at export instead (overrides=, CLI --set), or give the drive RayleighDamping (C = "
            "alpha M + beta K), which the FMU evaluates exactly from its parameters")
    internal = [dae.z_names[i] for i in range(dae.nz) if i not in set(dae.mech.q_in_z.values())]
    if dae.mech.has_internal_states or internal:
        raise FmuExportError(
            f"export_fmu: parameter '{hit[0]}' enters the mass or stiffness of '{dae.name}', which has internal "
            f"{'differential states' if dae.mech.has_internal_states else 'algebraic variables ' + str(internal[:4])} "
            "besides its mechanical coordinates: the FMU does not evaluate its Rayleigh damping from the parameters "
            "there; fix the value at export instead (overrides=, CLI --set)")
    return True


def rayleigh_term(dae, x, p):
    """``P (C_add(p) - C_add(p0)) v``: what turns the flattening's Rayleigh damping into the one at ``p``.

    ``x, p`` are the FMU's symbols (``p`` with the tunable entries symbolic). The Jacobians are taken where
    :func:`~bscomp.kernel.mechanics.start_matrices` takes them: at the start state with zero input and its
    consistent ``(x', z)`` -- which matter only when the Jacobians depend on them (none of the shipped drives),
    and are then solved for (``w = -W^-1 F(0)``, exact for the affine ``w`` the FMU requires).
    """
    m = dae.mech
    damping = dae.system_damping
    nr, nx, nz = len(m.coordinate_names), dae.nx, dae.nz
    x0, u0 = ca.DM(dae.x_start), ca.DM.zeros(dae.nu)
    xd_s, z_s = ca.MX.sym("xd", nx), ca.MX.sym("z", nz)
    jac = dae.jacobians(xd_s, x0, z_s, u0, p)
    if ca.depends_on(ca.veccat(*jac[1:4]), ca.vertcat(xd_s, z_s)):
        res0, Jxd0, _, Jz0, _ = dae.jacobians(ca.MX.zeros(nx), x0, ca.MX.zeros(nz), u0, p)
        w = -ca.solve(ca.horzcat(Jxd0, Jz0), res0, "qr")
        jac = dae.jacobians(w[:nx], x0, w[nx:], u0, p)
    else:
        jac = dae.jacobians(ca.MX.zeros(nx), x0, ca.MX.zeros(nz), u0, p)
    _, Jxd, Jx, _, _ = jac
    Sq = _selector(m.q_in_x, nx, nr)
    Sa = _selector(m.a_in_xd, nx, nr)
    v = ca.mtimes(_selector(m.v_in_x, nx, nr).T, x)
    R = list(m.balance_rows)                     # no internal algebraic variables (check_damping_parameters)
    Cv = damping.alpha * ca.mtimes(ca.mtimes(Jxd[R, :], Sa), v) + damping.beta * ca.mtimes(ca.mtimes(Jx[R, :], Sq), v)
    Cv0 = ca.mtimes(dm_sparse(dae.system_damping_basis[2]), v)
    place = ca.DM(ca.Sparsity.triplet(dae.F_sx.numel(), nr, R, list(range(nr))), 1.0)
    return ca.mtimes(place, Cv - Cv0)


def _selector(where, n, nr):
    """``(n, nr)`` 0/1 matrix: column ``r`` picks the entry ``where[r]`` of a length-``n`` vector."""
    rows = [where[r] for r in range(nr)]
    return ca.DM(ca.Sparsity.triplet(n, nr, rows, list(range(nr))), 1.0)
