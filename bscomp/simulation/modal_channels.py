r"""The linear part of ``simulate(method="modal")`` and the force channels that correct it, from one flattened
model (no re-flattening): Jacobian surgery at rest, the index-1 explicit form, and its modal coordinates.

Channels
--------
The nonlinear two-flange elements (friction, backlash: components with ``force_law`` and
``linear_equivalent``, Eq 5.6-5.9) and the position-dependent joints (:mod:`bscomp._moving_joint`) are the
model's only nonlinear parts. An element's force ``f(s, v)`` acts on its flange coordinates through
``D^T f`` (``s = s_rel = D q + s_0``, virtual work); a joint's port forces through ``P^T f``. In a *regime*
the element's slopes ``(k_R, d_R)`` are put into the linear part, the joint's tangent at rest at the
reference position ``z_r`` too, so that with ``v = (x', x, z, u)``

.. math:: F(v) = F_L(v) + \sum_{el} G_{el}\, g_{el}(s, v) + \sum_{j} G_j\, g_j(d, \dot d), \qquad
          g_{el} = f - k_R s - d_R v, \quad g_j = f_j - K_r d - C_r \dot d

holds *exactly* for the affine ``F_L`` (the Jacobian at rest with each element's tangent at rest swapped for
its regime slopes and the joint's ``z_0`` set to ``z_r``; ``G`` place the channel forces in the balance
rows). The index-1 explicit form of ``F_L`` gives

.. math:: \dot x = A\,\Delta x + B u + E g + c, \qquad z = z_a + Z_x \Delta x + Z_u u + Z_g g + z_c,

and every channel coordinate (``s``, ``v`` of the elements; ``d``, ``ḋ`` of the joints) and every affine
output is a row ``y = C_x \Delta x + D_u u + D_g g + y_c``.

Modal coordinates
-----------------
``A = V \Lambda V^{-1}`` (complex, one coordinate per real eigenvalue and per conjugate pair:
``\Delta x = \mathrm{Re}(V_2 \xi)`` with ``V_2`` the eigenvectors times 1 or 2) for models with internal
states; for purely mechanical ones the undamped modes of ``(K, M)`` come first (Eq A.10; a symmetric
``eigh``), the modes above ``f_keep`` enter statically (residual flexibility, the modal-acceleration idea
of Eq 5.16-5.18) and the kept ones, coupled by the (non-proportional) damping, are diagonalised as above.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from bscomp.errors import BscompError
from bscomp.linear.frf_engine import dense
from bscomp.linear.linearization import explicit_form
from bscomp.simulation.compiled import _Element, nonlinear_elements
from bscomp.simulation.moving_joints import MovingJoint, find_moving_joints

__all__ = ["ModalSimulationError", "Channels", "LinearPart", "RigidBodyDamper", "rigid_body_dampers"]


class ModalSimulationError(BscompError):
    """The model cannot be simulated by ``method="modal"``: what is unsupported and what to use instead."""


class DefectiveLinearPart(ModalSimulationError):
    """A regime's linear part has a Jordan block (e.g. a mass left free by a sliding friction and an open
    clearance): no modal coordinates for it."""



class RigidBodyDamper:
    """A virtual channel: a grounded viscous damper ``eps`` on one coordinate of an undamped rigid-body mode.

    An undamped rigid-body motion (a free screw, a rotor with no motor damping) is a Jordan block of the linear
    part (``q'' = f/m``: the eigenvalue 0 twice with one eigenvector), which has no modal coordinates. The damper's
    slope ``eps`` goes into the linear part (the block splits into 0 and ``-eps/m``) and its law is zero force,
    so its correction ``g = 0 - eps v`` takes it out again: the equations are the model's, exactly (the same
    exchange as :meth:`bscomp.simulation.modal_driver.ModalSimulator.damped` makes for a mass left free by a
    sliding friction, here without an element to carry it)."""

    def __init__(self, coordinate: int, name: str, eps: float):
        self.coordinate, self.eps = int(coordinate), float(eps)
        self.path = f"rigid-body damper at {name}"
        self.pnames, self.values, self.pvec = [], {}, np.zeros(0)
        s, v, p = ca.SX.sym("s"), ca.SX.sym("v"), ca.SX.sym("p", 0)
        self.law = ca.Function("law_rigid_body_damper", [s, v, p], [ca.SX(1, 1)])


def rigid_body_dampers(lin) -> list:
    """A :class:`RigidBodyDamper` on one coordinate of each rigid-body mode of the linear part ``lin``: the null
    space of its stiffness block ``d v'/d q`` (the accelerations' dependence on the positions that are states,
    ``M^-1 K`` condensed), each on the coordinate that moves most in it (pivoted QR, so that several modes get
    distinct coordinates), with a slope that makes the mode decay at 1e-6 of the model's fastest rate
    ``sqrt(max |A|)`` -- slow against every run, yet far from the double eigenvalue 0 in the eigenvector
    condition. Empty when there is no such mode."""
    dae = lin.ch.dae
    m = dae.mech
    A = lin.explicit()[0]
    coords = [j for j in range(lin.ch.nr) if j in m.q_in_x and j in m.v_in_x]
    if not A.size or not coords:
        return []
    Kq = A[np.ix_([m.v_in_x[j] for j in coords], [m.q_in_x[j] for j in coords])]
    _, sv, Vt = np.linalg.svd(Kq)
    if not sv.size or sv[0] == 0.0:
        return []
    Nq = Vt[sv <= 1e-12 * sv[0]].T
    if not Nq.size:
        return []
    _, R, piv = sla.qr(Nq.T, pivoting=True, mode="economic")
    rank = int(np.sum(np.abs(np.diag(R)) > 1e-6 * max(np.abs(R).max(), 1e-300)))
    rate = 1e-6 * np.sqrt(np.abs(A).max())
    out = []
    for k in piv[:rank]:
        j = coords[int(k)]
        mass = abs(float(lin.Jxd[m.balance_rows[j], m.v_in_x[j]]))      # dF/da of the coordinate's balance
        if mass > 0.0:
            out.append(RigidBodyDamper(j, m.coordinate_names[j], rate * mass))
    return out


class Channels:
    """The nonlinear force channels of a flattened model: cut elements and moving joints.

    Parameters
    ----------
    dae : Dae
    p : ndarray
        Parameter vector of the run.
    rigid : sequence of RigidBodyDamper
        Virtual dampers on undamped rigid-body modes (:func:`rigid_body_dampers`), after the elements.
    """

    def __init__(self, dae, p, rigid=()):
        if dae.system is None:
            raise ModalSimulationError(f"'{dae.name}' was not flattened from a System: method='modal' needs the "
                                       "components (pass the System, or use method='split')")
        self.dae, self.p = dae, p
        self.elements = [_Element(path, c) for path, c in nonlinear_elements(dae.system)]
        for el in self.elements:          # the run's parameter values, not the component's defaults
            el.values = {n: float(p[dae.p_names.index(f"{el.path}.{n}")]) if f"{el.path}.{n}" in dae.p_names
                         else el.values[n] for n in el.pnames}
            el.pvec = np.array([el.values[n] for n in el.pnames], float)
        self.elements += list(rigid)
        joints = [MovingJoint(dae, path, c, p) for path, c in find_moving_joints(dae.system)]
        self.joints = [j for j in joints if not j.is_linear]
        self.z0_index = [dae.p_names.index(f"{j.path}.z0") for j in self.joints]
        m = dae.mech
        self.nr = len(m.coordinate_names)
        nF = dae.F_sx.numel()
        self.Sbal = sp.csr_matrix((np.ones(self.nr), (m.balance_rows, np.arange(self.nr))), shape=(nF, self.nr))

        def sel(where, n):
            keys = list(where)
            return sp.csr_matrix((np.ones(len(keys)), (keys, [where[k] for k in keys])), shape=(self.nr, n))

        self.Sq_x, self.Sq_z = sel(m.q_in_x, dae.nx), sel(m.q_in_z, dae.nz)
        self.Sv_x, self.Sv_xd = sel(m.v_in_x, dae.nx), sel(m.v_in_xd, dae.nx)
        self._rest = {}
        self.x_a = np.asarray(dae.x_start, float).copy()
        self.z_a = np.asarray(dae.z_start, float).copy()
        self._element_rows()

    def _element_rows(self):
        """Rows of every element's ``s_rel``, ``v_rel`` (a rotational one's ``phi_rel``, ``w_rel``) at rest, its
        coordinate row ``D`` and rest slopes."""
        dae = self.dae
        m = dae.mech
        real = [el for el in self.elements if not isinstance(el, RigidBodyDamper)]
        names = [f"{el.path}.{q}" for el in real for q in el.coords]
        self.el_rows = None
        if not self.elements:
            return
        shapes = (dae.nx, dae.nx, dae.nz, dae.nu)
        if names:
            y = dae.output_expr(names)
            f = ca.Function("rows", [dae.xds, dae.xs, dae.zs, dae.us, dae.ps],
                            [y, ca.jacobian(y, dae.xds), ca.jacobian(y, dae.xs), ca.jacobian(y, dae.zs),
                             ca.jacobian(y, dae.us)])
            y0, Jxd, Jx, Jz, Ju = (dense(np.asarray(ca.DM(v)), float) for v in
                                   f(np.zeros(dae.nx), self.x_a, self.z_a, np.zeros(dae.nu), self.p))
            y0 = y0.ravel()
        else:
            y0, (Jxd, Jx, Jz, Ju) = np.zeros(0), (np.zeros((0, n)) for n in shapes)
        for el in self.elements[len(real):]:            # a virtual damper: s, v = the coordinate's q, v states
            iq, iv = m.q_in_x[el.coordinate], m.v_in_x[el.coordinate]
            rows = np.zeros((2, dae.nx))
            rows[0, iq] = rows[1, iv] = 1.0
            y0 = np.r_[y0, self.x_a[iq], self.x_a[iv]]
            Jx = np.vstack([Jx, rows])
            Jxd, Jz, Ju = (np.vstack([J, np.zeros((2, n))]) for J, n in ((Jxd, dae.nx), (Jz, dae.nz), (Ju, dae.nu)))
        self.el_rows = (y0, Jxd, Jx, Jz, Ju)
        D = np.zeros((len(self.elements), self.nr))
        for i in range(len(self.elements)):
            for j in range(self.nr):
                D[i, j] = Jx[2 * i, m.q_in_x[j]] if j in m.q_in_x else (Jz[2 * i, m.q_in_z[j]] if j in m.q_in_z else 0)
        self.D = D
        self.rest = []
        for i in range(len(self.elements)):
            s0, v0 = y0[2 * i], y0[2 * i + 1]
            self.rest.append((s0, v0) + self.slopes(i, s0, v0))
        self.rest_force = np.array([float(el.law(r[0], r[1], el.pvec)) for el, r in zip(self.elements, self.rest,
                                                                                        strict=True)])

    def element_columns(self):
        """``G_el = S_bal D^T`` (dense, one column per element): where the elements' forces enter the balances."""
        if getattr(self, "_Gel", None) is None:
            self._Gel = np.asarray(self.Sbal @ self.D.T)
        return self._Gel

    def joint_columns(self):
        """``S_bal P^T`` per joint (dense): where the joints' port forces enter the balances."""
        if getattr(self, "_Gj", None) is None:
            self._Gj = [dense(self.Sbal @ j.P.T, float) for j in self.joints]
        return self._Gj

    def rest_jacobians(self, p):
        """``(F, Jxd, Jx, Jz, Ju)`` at rest for parameter vector ``p`` (cached: regimes share them)."""
        key = p.tobytes()
        if key not in self._rest:
            dae = self.dae
            F, Jxd, Jx, Jz, Ju = dae.jacobians_at(np.zeros(dae.nx), self.x_a, self.z_a, np.zeros(dae.nu), p)
            self._rest[key] = (F, *(sp.csr_matrix(J) for J in (Jxd, Jx, Jz, Ju)))
        return self._rest[key]

    def rest_dense(self, p):
        """``(dF/dxd, dF/dx)`` of :meth:`rest_jacobians` as dense arrays (cached: every regime's modal part slices
        its mass, damping and stiffness blocks from them)."""
        key = ("dense", p.tobytes())
        if key not in self._rest:
            _, Jxd, Jx, _, _ = self.rest_jacobians(p)
            self._rest[key] = (Jxd.toarray(), Jx.toarray())
        return self._rest[key]

    def slopes(self, i, s, v):
        """``(∂f/∂s, ∂f/∂v)`` of element i's law at ``(s, v)``."""
        el = self.elements[i]
        if not hasattr(el, "_jac"):
            ss, vv = ca.SX.sym("s"), ca.SX.sym("v")
            pp = ca.SX.sym("p", len(el.pnames))
            law = el.law(ss, vv, pp)
            el._jac = ca.Function("dlaw", [ss, vv, pp], [ca.jacobian(law, ss), ca.jacobian(law, vv)])
        ks, kv = el._jac(s, v, el.pvec)
        return float(ks), float(kv)

    def candidate_regimes(self, i):
        """Slopes ``(k, d)`` element i takes: its tangent at rest and on its outer branches (far points); a
        :class:`RigidBodyDamper` its one slope."""
        if isinstance(self.elements[i], RigidBodyDamper):
            return [(0.0, self.elements[i].eps)]
        s0, v0 = self.rest[i][:2]
        out = [tuple(self.rest[i][2:])]
        for ds, dv in ((1e6, 1e6), (-1e6, -1e6), (1e6, 0.0), (0.0, 1e6)):
            k = self.slopes(i, s0 + ds, v0 + dv)
            if not any(np.allclose(k, o, rtol=1e-6, atol=1e-12) for o in out):
                out.append(k)
        return out


class LinearPart:
    """``ẋ = A Δx + B u + E g + c`` of the model in one regime and joint reference (module docstring).

    Parameters
    ----------
    ch : Channels
    regime : tuple of (k, d)
        The slopes put into the linear part, one pair per element.
    z_ref : tuple of float
        Reference position of each moving joint.
    """

    def __init__(self, ch: Channels, regime, z_ref):
        dae, p = ch.dae, ch.p.copy()
        self.ch, self.regime, self.z_ref = ch, tuple(regime), tuple(z_ref)
        for i, z in zip(ch.z0_index, z_ref, strict=True):
            p[i] = z
        self.p_ref = p
        F, Jxd, Jx, Jz, Ju = ch.rest_jacobians(p)
        cols, F_L = [], F.copy()
        self._rest_J, self._upd, self._sparse = (Jxd, Jx, Jz), {}, {}
        if ch.elements:
            _, Rxd, Rx, Rz, _ = ch.el_rows
            Gel = ch.element_columns()
            k_d = np.asarray(regime, float).reshape(-1, 2)
            rest = np.asarray([r[:4] for r in ch.rest], float)           # s0, v0, k0, d0 per element
            dk, dd = k_d[:, 0] - rest[:, 2], k_d[:, 1] - rest[:, 3]
            # each element's slopes swapped: J + sum_i G_i (dk_i R_s,i + dd_i R_v,i), kept as the dense product
            for name, R in (("xd", Rxd), ("x", Rx), ("z", Rz)):
                D = dk[:, None] * R[0::2] + dd[:, None] * R[1::2]
                if np.any(D) and (name != "z" or dae.nz):
                    self._upd[name] = Gel @ D
            g0 = ch.rest_force - k_d[:, 0] * rest[:, 0] - k_d[:, 1] * rest[:, 1]
            F_L = F_L - Gel @ g0
            cols.append(Gel)
        self.n_el = len(ch.elements)
        self.joint_cols = []
        for Gj in ch.joint_columns():
            self.joint_cols.append((sum(c.shape[1] for c in cols), Gj.shape[1]))
            cols.append(Gj)
        self.G = np.hstack(cols) if cols else np.zeros((F.size, 0))
        self.F0 = F_L
        self.Ju = Ju.tocsc()
        self.ng = self.G.shape[1]
        self._explicit = None

    def _jac(self, name):
        """The regime's sparse ``dF/d(name)`` (built on first use: the second-order route reads dense blocks)."""
        J = self._sparse.get(name)
        if J is None:
            J = self._rest_J[("xd", "x", "z").index(name)]
            if name in self._upd:
                J = J + sp.csr_matrix(self._upd[name])
            J = self._sparse[name] = J.tocsc()
        return J

    Jxd = property(lambda self: self._jac("xd"), doc="``dF/dẋ`` of the regime (csc).")
    Jx = property(lambda self: self._jac("x"), doc="``dF/dx`` of the regime (csc).")
    Jz = property(lambda self: self._jac("z"), doc="``dF/dz`` of the regime (csc).")

    def dense_jacobians(self):
        """``(dF/dẋ, dF/dx)`` of the regime, dense: the rest ones plus the slopes' product (entry for entry the
        sum the sparse :attr:`Jxd`, :attr:`Jx` hold)."""
        Jxd, Jx = self.ch.rest_dense(self.p_ref)
        return tuple(J + self._upd[n] if n in self._upd else J.copy() for n, J in (("xd", Jxd), ("x", Jx)))

    def explicit(self):
        """``(A, B, E, c, Zx, Zu, Zg, zc)`` of the index-1 explicit form (dense, computed once)."""
        if self._explicit is None:
            dae, nu, ng = self.ch.dae, self.Ju.shape[1], self.ng
            Ju_aug = sp.hstack([self.Ju, sp.csr_matrix(self.G), sp.csr_matrix(self.F0[:, None])]).tocsc()
            A, Baug, Zx, Zaug = explicit_form(dae, self.Jxd, self.Jx, self.Jz, Ju_aug)
            self._explicit = (A, Baug[:, :nu], Baug[:, nu:nu + ng], Baug[:, -1], Zx, Zaug[:, :nu],
                              Zaug[:, nu:nu + ng], Zaug[:, -1])
        return self._explicit

    def outside(self, u_low, u_high, u_mid):
        """The first equation the decomposition does not reproduce -- at rest with the inputs ``u_low`` and
        ``u_high``, and at a random state near rest with ``u_mid`` -- as ``(origin, residual, scale)``, or None
        when every nonlinearity of the model is a channel (a current limit, a nonlinear spring would be linearized
        silently by whoever uses this decomposition)."""
        dae = self.ch.dae
        dx = np.random.default_rng(0).normal(size=dae.nx) * 1e-6
        for dxi, u in ((0.0 * dx, u_low), (0.0 * dx, u_high), (dx, u_mid)):
            err, scale, row = self.mismatch(dxi, u)
            if err > 1e-7 * scale:
                return (dae.eq_origin[row] if row < len(dae.eq_origin) else f"row {row}"), err, scale
        return None

    def mismatch(self, dx, u):
        """``(max |F - F_L - G g|, scale, row)`` at the state ``x_a + dx`` (``x' = 0``, ``z = z_a``) and input
        ``u``: zero (round-off) when every nonlinearity of the model is a channel (the decomposition of the
        module docstring holds at any point); ``row`` the worst equation."""
        ch, dae = self.ch, self.ch.dae
        g = np.zeros(self.ng)
        if ch.elements:
            y0, _, Jx, _, _ = ch.el_rows
            for i, el in enumerate(ch.elements):
                s, v = y0[2 * i] + Jx[2 * i] @ dx, y0[2 * i + 1] + Jx[2 * i + 1] @ dx
                k, d = self.regime[i]
                g[i] = float(el.law(s, v, el.pvec)) - k * s - d * v
        for (off, n), jt, zr in zip(self.joint_cols, ch.joints, self.z_ref, strict=True):
            d, dd = jt.P @ (ch.Sq_x @ dx), jt.P @ (ch.Sv_x @ dx)
            Kr, Cr = jt.tangent(zr)
            g[off:off + n] = jt.force(d, dd) - Kr @ d - (Cr @ dd if Cr is not None else 0.0)
        F = np.asarray(dae.F(np.zeros(dae.nx), ch.x_a + dx, ch.z_a, u, ch.p)).ravel()
        Gg = self.G @ g
        Jx_dx = self.dense_jacobians()[1] @ dx        # a check: no need for the sparse Jacobian's assembly
        model = self.F0 + Jx_dx + self.Ju @ u + Gg
        scale = max(np.abs(Jx_dx).max(initial=0.0), np.abs(self.Ju @ u).max(initial=0.0),
                    np.abs(Gg).max(initial=0.0), np.abs(self.F0).max(initial=0.0), 1e-300)
        diff = np.abs(F - model)
        row = int(np.argmax(diff)) if diff.size else 0
        return float(diff.max(initial=0.0)), scale, row


