r"""The channel laws of ``simulate(method="modal")`` as one CasADi expression with numeric inputs.

For channel coordinates ``y`` (per element ``s, v``; per moving joint the potentials ``d_S`` and, when it is
damped, ``ḋ_S``) the law returns the correction forces ``g`` (:mod:`bscomp._moving_linear`: element
``g = f(s, v) - k_R s - d_R v``; joint ``g = f(d, ḋ) - K_r d - C_r ḋ`` of :mod:`bscomp._moving_joint`), the
largest force magnitude (the error scale) and two indicators the driver acts on: whether every element is
still nearest its current regime (the log-distance of its tangent to each candidate slope pair, with a margin
against flapping at a branch boundary), and whether
every contact point is still inside the element(s) the expression covers.

Everything numeric -- law parameters, regime slopes and candidates, the joints' element polynomials on the
chosen potentials ``S``, ``K``, ``K_r`` and positions -- is one input vector (:meth:`LawSpec.pack`), so one
Function serves every regime, reference and element of a given shape.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["LawSpec", "regime_eps", "joint_coefficients", "coefficient_patterns"]

_EPS_REGIME = 1e-3   # slopes below this fraction of an element's steepest candidate count as zero
REGIME_MARGIN = 2.3  # hysteresis: another regime is taken when its slopes are 10x closer (log-distance)


def _flat(a) -> np.ndarray:
    """Column-major flattening; a 3-D piece as its leading-index slices one after the other."""
    a = np.asarray(a, float)
    if a.ndim == 3:
        return np.concatenate([a[k].reshape(-1, order="F") for k in range(a.shape[0])])
    return a.reshape(-1, order="F")


def regime_eps(cands) -> np.ndarray:
    """``(eps_k, eps_d)`` of the regime distance: ``_EPS_REGIME`` x an element's steepest candidate slopes (packed
    numbers, not constants of the expression: a new parameter value must not change the compiled laws)."""
    c = np.abs(np.asarray(cands, float))
    return _EPS_REGIME * np.maximum(c.max(axis=0), 1e-300)


def joint_coefficients(jt, S, e) -> np.ndarray:
    """``(4, m_eff, |S|)``: the coefficients of the joint's ``E(ξ) = Σ_k c_k ξ^k`` (Eq 3.27 / A.7) for element
    ``e``, on the potentials ``S`` (columns of ``S`` outside the element: zero)."""
    cols, coef = jt.elements[e]
    full = np.zeros((4, jt.m_eff, len(S)))
    where = {int(c): i for i, c in enumerate(S)}
    full[:, :, [where[int(c)] for c in cols]] = coef[:, jt.eff_rows, :]
    return full


def coefficient_patterns(ch, cset) -> tuple:
    """Per joint and covered element of a channel set, where :func:`joint_coefficients` is nonzero: the law
    is built on these (a bar element's linear shape functions fill 11 of the 60 coefficients of the
    axial + torsional joint; the others would be multiplied by zero at every evaluation)."""
    return tuple(tuple(joint_coefficients(jt, S, e) != 0 for e in elems)
                 for jt, (S, elems) in zip(ch.joints, cset, strict=True))


def _sparse_powers(piece, pat) -> list:
    """The packed nonzeros (C order of ``pat``) as one sparse SX matrix per power of ``ξ``."""
    out, off = [], 0
    for k in range(pat.shape[0]):
        r, c = np.nonzero(pat[k])
        out.append(ca.SX.triplet(r.tolist(), c.tolist(), piece[off:off + r.size], pat.shape[1], pat.shape[2]))
        off += r.size
    return out


class LawSpec:
    """Shape and packing of the channel laws for one channel set.

    Parameters
    ----------
    ch : Channels
    sizes : tuple of (int, int)
        Per joint: number of potentials ``|S|`` and number of elements the expression covers.
    candidates : list of list of (k, d)
        Candidate regimes per element.
    """

    def __init__(self, ch, sizes, candidates, patterns=None):
        self.ch, self.sizes, self.cands = ch, tuple(sizes), [list(c) for c in candidates]
        if patterns is None:                  # every coefficient a number (dense polynomials)
            patterns = tuple(tuple(np.ones((4, jt.m_eff, nS), bool) for _ in range(ne))
                             for jt, (nS, ne) in zip(ch.joints, self.sizes, strict=True))
        self.patterns = patterns
        self.key = (self.sizes, tuple(tuple(pat.tobytes() for pat in pj) for pj in patterns))
        self.layout = []                      # (name, shape) of every packed piece, in order
        for i, el in enumerate(ch.elements):
            self.layout += [(f"p{i}", (len(el.pnames),)), (f"reg{i}", (2,)), (f"cand{i}", (len(self.cands[i]), 2)),
                            (f"eps{i}", (2,)), (f"cur{i}", (1,))]
        for j, (jt, (nS, ne)) in enumerate(zip(ch.joints, sizes, strict=True)):
            m = jt.m_eff
            self.layout += [(f"K{j}", (m, m)), (f"Kr{j}", (nS, nS)), (f"z{j}", (3,))]
            if jt.C is not None:
                self.layout += [(f"C{j}", (m, m)), (f"Cr{j}", (nS, nS))]
            for e in range(ne):
                self.layout += [(f"coef{j}_{e}", (int(patterns[j][e].sum()),)), (f"zab{j}_{e}", (2,))]
        self.n_theta = sum(int(np.prod(s)) for _, s in self.layout)
        self.ny = 2 * len(ch.elements) + sum(nS * (2 if jt.C is not None else 1)
                                             for jt, (nS, _) in zip(ch.joints, sizes, strict=True))
        self.ng = len(ch.elements) + sum(nS for nS, _ in sizes)

    # ---- numbers ------------------------------------------------------------------------------------------
    def pack(self, regime, slopes, z_ref, cset) -> np.ndarray:
        """The input vector for a regime (candidate indices and their slopes), references and channel set."""
        ch = self.ch
        vals = {}
        for i, el in enumerate(ch.elements):
            vals[f"p{i}"] = el.pvec
            vals[f"reg{i}"] = np.asarray(slopes[i], float)
            vals[f"cand{i}"] = np.asarray(self.cands[i], float)
            vals[f"eps{i}"] = regime_eps(self.cands[i])
            vals[f"cur{i}"] = np.array([regime[i]], float)
        for j, (jt, (S, elems)) in enumerate(zip(ch.joints, cset, strict=True)):
            Kr, Cr = jt.tangent(z_ref[j])
            rows = jt.eff_rows
            vals[f"K{j}"] = jt.K[np.ix_(rows, rows)]
            vals[f"Kr{j}"] = Kr[np.ix_(S, S)]
            vals[f"z{j}"] = np.array([jt.z0, jt.z_nodes[0], jt.z_nodes[-1]])
            if jt.C is not None:
                vals[f"C{j}"] = jt.C[np.ix_(rows, rows)]
                vals[f"Cr{j}"] = Cr[np.ix_(S, S)]
            for k, e in enumerate(elems):
                full, pat = joint_coefficients(jt, S, e), self.patterns[j][k]
                if np.any(full[~pat]):
                    raise ValueError(f"{jt.path}: element {e}'s polynomial has a coefficient outside the pattern "
                                     "this law was built for (build the law from this channel set)")
                vals[f"coef{j}_{k}"] = full[pat]
                vals[f"zab{j}_{k}"] = np.array([jt.z_nodes[e], jt.z_nodes[e + 1]])
        return np.concatenate([_flat(vals[n]) for n, _ in self.layout]) if self.layout else np.zeros(0)

    # ---- expressions --------------------------------------------------------------------------------------
    def unpack(self, theta):
        out, off = {}, 0
        for n, shape in self.layout:
            size = int(np.prod(shape))
            piece = theta[off:off + size]
            if n.startswith("coef"):          # the polynomial's nonzeros: sparse matrices, one per power
                j, e = (int(a) for a in n[4:].split("_"))
                piece = _sparse_powers(piece, self.patterns[j][e])
            elif len(shape) == 2:
                piece = ca.reshape(piece, shape[0], shape[1])
            elif len(shape) == 3:
                piece = [ca.reshape(piece[k * shape[1] * shape[2]:(k + 1) * shape[1] * shape[2]], shape[1],
                                    shape[2]) for k in range(shape[0])]
            out[n] = piece
            off += size
        return out

    def expr(self, y, theta, check=True, joints=True):
        """``(g, fmax, regime_ok, element_ok)`` as SX for channel values ``y`` and packed numbers ``theta``
        (``check=False``: without the regime test; ``joints=False``: the elements only, ``y`` their rows)."""
        ch, P = self.ch, self.unpack(theta)
        g, fabs, ok_reg, ok_el = [], [], ca.SX(1), ca.SX(1)
        for i, el in enumerate(ch.elements):
            s, v = y[2 * i], y[2 * i + 1]
            f = el.law(s, v, P[f"p{i}"])
            reg = P[f"reg{i}"]
            g.append(f - reg[0] * s - reg[1] * v)
            fabs.append(ca.fabs(f))
            if check:
                ok_reg = ok_reg * self._nearest_is_current(el, s, v, P, i)
        off = 2 * len(ch.elements)
        for j, (jt, (nS, ne)) in enumerate(zip(ch.joints, self.sizes, strict=True)):
            if not joints:
                break
            dS = y[off:off + nS]
            ddS = y[off + nS:off + 2 * nS] if jt.C is not None else None
            off += nS * (2 if jt.C is not None else 1)
            z0, zlo, zhi = P[f"z{j}"][0], P[f"z{j}"][1], P[f"z{j}"][2]
            z = z0 + dS[nS - 1]
            gj = fj = None
            inside_any = ca.SX(0)
            for e in range(ne - 1, -1, -1):
                za, zb = P[f"zab{j}_{e}"][0], P[f"zab{j}_{e}"][1]
                ge, fe = self._joint(jt, dS, ddS, z, P, j, e, za, zb, zlo, zhi)
                inside = ca.logic_and(ca.logic_or(z >= za, za <= zlo), ca.logic_or(z <= zb, zb >= zhi))
                inside_any = ca.logic_or(inside_any, inside)
                gj = ge if gj is None else ca.if_else(inside, ge, gj)
                fj = fe if fj is None else ca.if_else(inside, fe, fj)
            g.append(gj)
            fabs.append(ca.norm_inf(fj))
            ok_el = ok_el * inside_any
        fmax = ca.mmax(ca.vertcat(*fabs)) if fabs else ca.SX(0)
        return (ca.vertcat(*g) if g else ca.SX(0, 1)), fmax, ok_reg, ok_el

    def _nearest_is_current(self, el, s, v, P, i):
        """1 if the candidate nearest the law's tangent at (s, v) is the current regime."""
        law = el.law(s, v, P[f"p{i}"])
        k, d = ca.jacobian(law, s), ca.jacobian(law, v)
        n_cand = len(self.cands[i])
        ek, ed = P[f"eps{i}"][0], P[f"eps{i}"][1]
        C = P[f"cand{i}"]
        dist = [ca.fabs(ca.log((ca.fabs(k) + ek) / (ca.fabs(C[c, 0]) + ek)))
                + ca.fabs(ca.log((ca.fabs(d) + ed) / (ca.fabs(C[c, 1]) + ed))) for c in range(n_cand)]
        cur = P[f"cur{i}"][0]
        dcur = sum(ca.if_else(cur == c, dist[c], 0) for c in range(n_cand))
        best = dist[0]
        for dd in dist[1:]:
            best = ca.fmin(best, dd)
        return dcur <= best + REGIME_MARGIN

    @staticmethod
    def _joint(jt, dS, ddS, z, P, j, e, za, zb, zlo, zhi):
        """Correction and port forces of joint j with the contact point in its e-th covered element."""
        nS = dS.numel()
        xi = ca.fmin(ca.fmax((z - za) / (zb - za), 0), 1)   # a step that crosses a node is flagged
        coef = P[f"coef{j}_{e}"]
        E = coef[0] + xi * coef[1] + xi ** 2 * coef[2] + xi ** 3 * coef[3]
        dE = (coef[1] + 2 * xi * coef[2] + 3 * xi ** 2 * coef[3]) / (zb - za)
        moving = ca.logic_and(z >= ca.fmax(za, zlo), z <= ca.fmin(zb, zhi))
        ev = ca.mtimes(E, dS)
        col = ca.if_else(moving, ca.mtimes(dE, dS), ca.SX.zeros(jt.m_eff))
        F = ca.mtimes(P[f"K{j}"], ev)
        if ddS is not None:
            F = F + ca.mtimes(P[f"C{j}"], ca.mtimes(E, ddS) + col * ddS[nS - 1])
        f = ca.mtimes(E.T, F)
        f = f + ca.vertcat(ca.SX.zeros(nS - 1), ca.dot(col, F))
        g = f - ca.mtimes(P[f"Kr{j}"], dS)
        if ddS is not None:
            g = g - ca.mtimes(P[f"Cr{j}"], ddS)
        return g, f

    def function(self):
        """``(y, theta) -> (g, dg/dy, fmax, regime_ok, element_ok)`` (SX Function)."""
        return self._build()[0]

    def functions(self):
        """The four the compiled step uses: Newton ``(y, θ) -> (g, dg/dy)``, value ``(y, θ) -> (g, fmax,
        element_ok)``, check ``(y, θ) -> (g, fmax, regime_ok, element_ok)`` (at a step's end) and the elements'
        value on their rows ``(y_el, θ) -> (g_el, fmax)``."""
        return self._build()[1:]

    def _build(self):
        """Every Function of :meth:`function` and :meth:`functions` from one expression of the laws (the regime
        test is the only part the others leave out), built once."""
        if getattr(self, "_built", None) is None:
            y = ca.SX.sym("y", self.ny)
            th = ca.SX.sym("theta", self.n_theta)
            g, fmax, okr, oke = self.expr(y, th)
            J = ca.jacobian(g, y)
            full = ca.Function("law", [y, th], [g, J, fmax, okr, oke])
            newton = ca.Function("law_newton", [y, th], [g, J])
            value = ca.Function("law_value", [y, th], [g, fmax, oke])
            check = ca.Function("law_check", [y, th], [g, fmax, okr, oke])
            ne = 2 * len(self.ch.elements)
            ye = ca.SX.sym("y_el", ne)
            ge, fe, _, _ = self.expr(ye, th, check=False, joints=False)
            elements = ca.Function("law_elements", [ye, th], [ge if ne else ca.SX(0, 1), fe])
            self._built = (full, newton, value, check, elements)
        return self._built
