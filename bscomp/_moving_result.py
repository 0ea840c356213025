r"""Driver and results of ``simulate(method="modal")``: sampled controllers, outputs from the modal trajectory,
states reconstructed only when asked for.

Outputs that are affine in ``(x', x, z, u)`` (positions, velocities, accelerations, forces of linear parts) are
rows of the modal coordinates and channel forces (:meth:`bscomp._moving_modal.ModalPart.rows`): one product per
stretch of the run in one modal part. Others (an element's force, the contact point ``sn.z``) are evaluated by
the model's own output function on the few state columns they depend on. The full state history ``x``, ``x'``
(``z``) is rebuilt from the modal trajectory the first time it is read.
"""

from __future__ import annotations

import sys
import time

import casadi as ca
import numpy as np

__all__ = ["simulate_modal"]

DEFAULTS = {"tol": 3e-4, "f_keep": 5e4, "window": 2}


def _simulation_result():
    from .simulate import SimulationResult

    class ModalResult(SimulationResult):
        """A :class:`~bscomp.simulate.SimulationResult` whose state histories are rebuilt when first read."""

        def __init__(self, rebuild, **kw):
            self._rebuild, self._states = rebuild, None
            super().__init__(x=None, xd=None, z=None, **kw)

        def _get(self, i):
            if self._states is None:
                self._states = self._rebuild()
            return self._states[i]

        x = property(lambda self: self._get(0), lambda self, v: None)
        xd = property(lambda self: self._get(1), lambda self, v: None)
        z = property(lambda self: self._get(2), lambda self, v: None)

    return ModalResult


def _sample_indices(t, controllers):
    """Grid indices at which each sampled controller updates (the rule of the other methods)."""
    out = []
    nxt = [t[0] for _ in controllers]
    for k in range(len(t) - 1):
        if any(t[k] + 1e-12 >= n for n in nxt):
            out.append(k)
        for i, c in enumerate(controllers):
            while nxt[i] <= t[k] + 1e-12:
                nxt[i] += c.Ts
    return out


class Outputs:
    """Evaluates named outputs on a modal trajectory (see the module docstring)."""

    def __init__(self, sim, names):
        self.sim, self.names = sim, list(names)
        dae = sim.dae
        e = dae.output_expr(self.names) if self.names else ca.SX(0, 1)
        v = ca.vertcat(dae.xds, dae.xs, dae.zs, dae.us)
        J = ca.jacobian(e, v)
        affine = [not ca.depends_on(J[i, :], v) for i in range(len(self.names))]
        self.affine = [n for n, a in zip(self.names, affine, strict=True) if a]
        self.other = [n for n, a in zip(self.names, affine, strict=True) if not a]
        self._rows = {}
        if self.affine:
            ea = dae.output_expr(self.affine)
            self._jac = ca.Function("yj", [dae.xds, dae.xs, dae.zs, dae.us, dae.ps],
                                    [ea, ca.jacobian(ea, dae.xds), ca.jacobian(ea, dae.xs), ca.jacobian(ea, dae.zs),
                                     ca.jacobian(ea, dae.us)])
        if self.other:
            eo = dae.output_expr(self.other)
            dep = [ca.depends_on(eo, s) for s in (dae.xds, dae.xs, dae.zs, dae.us)]
            sp = [ca.jacobian_sparsity(eo, s) for s in (dae.xds, dae.xs, dae.zs)]
            self.cols = [np.unique(np.asarray(s.get_triplet()[1], int)) for s in sp]
            self._dep = dep

    def rows(self, mp):
        """Modal rows of the affine outputs in one modal part."""
        key = id(mp)
        if key not in self._rows:
            sim, dae = self.sim, self.sim.dae
            ch = sim.ch
            y0, Jxd, Jx, Jz, Ju = (np.asarray(ca.DM(a).full()) for a in
                                   self._jac(np.zeros(dae.nx), ch.x_a, ch.z_a, np.zeros(dae.nu), sim.p))
            y0 = y0.ravel()
            self._rows[key] = mp.rows(Jxd, Jx, Jz, Ju, y0)
        return self._rows[key]

    def evaluate(self, XI, G, segs, Uh):
        """``{name: (nt,) array}``."""
        nt = len(XI)
        out = {n: np.zeros(nt) for n in self.names}
        bounds = [s for s, _ in segs] + [nt]
        for (k0, mp), k1 in zip(segs, bounds[1:], strict=True):
            if k1 <= k0:
                continue
            xi = np.array(XI[k0:k1])
            u, g = Uh[k0:k1], G[k0:k1]
            if self.affine:
                Cxi, Du, Dg, yc = self.rows(mp)
                Y = (xi @ Cxi.T).real + u @ Du.T + g @ Dg.T + yc
                for i, n in enumerate(self.affine):
                    out[n][k0:k1] = Y[:, i]
            if self.other:
                Y = self._nonaffine(mp, xi, u, g)
                for i, n in enumerate(self.other):
                    out[n][k0:k1] = Y[:, i]
        return out

    def _nonaffine(self, mp, xi, u, g):
        from .simulate import _evaluate_outputs

        sim, dae = self.sim, self.sim.dae
        n = len(xi)
        cd, cx, cz = self.cols
        X = np.zeros((n, dae.nx))
        XD = np.zeros((n, dae.nx))
        Z = np.zeros((n, dae.nz))
        if cx.size:
            X[:, cx] = (xi @ mp.Vx[cx].T).real + u @ mp.Xu[cx].T + g @ mp.Xg[cx].T + mp.xc[cx]
        X += sim.ch.x_a
        if cd.size:
            Vr, Vrd = mp.rate_rows()
            rate = xi * mp.lam + u @ mp.Bu.T + g @ mp.Bg.T + mp.bc
            XD[:, cd] = (xi @ Vr[cd].T + rate @ Vrd[cd].T).real
        if cz.size and mp.Z is not None:
            Zx, Zu, Zg, zc = mp.Z
            dx = mp.state(xi, u, g)
            Z[:, cz] = sim.ch.z_a[cz] + dx @ Zx[cz].T + u @ Zu[cz].T + g @ Zg[cz].T + zc[cz]
        Y = _evaluate_outputs(dae, self.other, XD, X, Z, u, sim.p)
        return np.column_stack([Y[o] for o in self.other])


def _states(sim, XI, G, segs, Uh):
    """Full ``(x, x', z)`` histories from the modal trajectory."""
    dae = sim.dae
    X, XD = sim.trajectories(XI, G, segs, Uh)
    Z = np.tile(sim.ch.z_a, (len(XI), 1))
    bounds = [s for s, _ in segs] + [len(XI)]
    for (k0, mp), k1 in zip(segs, bounds[1:], strict=True):
        if k1 > k0 and mp.Z is not None and dae.nz:
            Zx, Zu, Zg, zc = mp.Z
            Z[k0:k1] += X[k0:k1] @ Zx.T + Uh[k0:k1] @ Zu.T + G[k0:k1] @ Zg.T + zc
    return X + sim.ch.x_a, XD, Z


def simulator(dae, p, options):
    """The cached :class:`~bscomp._moving_sim.ModalSimulator` of a Dae, parameter vector and options."""
    from ._moving_sim import ModalSimulator

    key = ("modal", p.tobytes(), options["f_keep"], options["window"])
    cache = dae._cache.setdefault("modal_simulators", {})
    if key not in cache:
        if len(cache) >= 4:
            cache.pop(next(iter(cache)))
        cache[key] = ModalSimulator(dae, p, f_keep=options["f_keep"], window=options["window"])
    return cache[key]


def simulate_modal(dae, t, U, xs, p, outputs, controllers, substeps, progress, options=None):
    """Driver of ``simulate(method="modal")`` (arguments as the other methods' drivers; ``U`` is (nu, nt-1))."""
    from .simulate import _progress_bar

    opts = dict(DEFAULTS, **(options or {}))
    bad = set(opts) - set(DEFAULTS)
    if bad:
        raise ValueError(f"method='modal' options are {sorted(DEFAULTS)}, got {sorted(bad)}")
    t_wall = time.perf_counter()
    if outputs:
        dae.output_function(outputs)                 # unknown names fail before integrating
    sim = simulator(dae, p, opts)
    out = Outputs(sim, outputs)
    nt = len(t)
    if substeps > 1:
        ti = np.concatenate([np.linspace(t[k], t[k + 1], substeps + 1)[:-1] for k in range(nt - 1)] + [t[-1:]])
        Ui = np.repeat(U.T, substeps, axis=0)
    else:
        ti, Ui = t, np.ascontiguousarray(U.T)
    samples = _sample_indices(ti, controllers) if controllers else []
    sampler = _Sampler(dae, sim, controllers, ti, Ui) if controllers else None
    if progress is None:
        progress = nt > 2000 and sys.stderr.isatty()
    bar = (lambda frac, tn: _progress_bar(dae.name, frac, tn)) if progress else None
    XI, G, segs = sim.run(ti, Ui, xs, tol=opts["tol"], breaks=samples, sample=sampler, progress=bar)
    keep = np.arange(0, len(ti), substeps)
    if substeps > 1:
        XI = [XI[k] for k in keep]
        G = G[keep]
        segs = _thin_segments(segs, substeps)
    Uh = np.vstack([Ui[:1], Ui])[keep]
    y = out.evaluate(XI, G, segs, Uh)
    wall = time.perf_counter() - t_wall
    stats = dict(sim.stats, wall_s=wall, method="modal", step=float(np.min(np.diff(ti))), options=opts,
                 real_time_factor=(t[-1] - t[0]) / wall if wall > 0 else np.inf)
    ModalResult = _simulation_result()
    return ModalResult(lambda: _states(sim, XI, G, segs, Uh), t=t, u=Uh, x_names=list(dae.x_names),
                       z_names=list(dae.z_names), u_names=list(dae.u_names), outputs=y, stats=stats)


def _thin_segments(segs, every):
    """Segment starts on the fine grid -> on the output grid (a part that starts inside an interval owns the
    interval's end point)."""
    out = []
    for k, mp in segs:
        kk = -(-k // every)
        if out and out[-1][0] == kk:
            out[-1] = (kk, mp)
        else:
            out.append((kk, mp))
    return out


class _Sampler:
    """Runs the sampled controllers at their grid indices: measures, calls the laws, holds their outputs."""

    def __init__(self, dae, sim, controllers, t, U):
        self.dae, self.sim, self.controllers, self.t, self.U = dae, sim, controllers, t, U
        self.names = [m for c in controllers for m in c.measure]
        self.out = Outputs(sim, self.names)
        self.idx = [[dae.u_names.index(a) for a in c.actuate] for c in controllers]
        self.nxt = [t[0] for _ in controllers]

    def __call__(self, k, st):
        """Called before the step from grid index k with the running state; updates ``U[k:]`` in place."""
        y = self.out.evaluate([st.xi], st.g[None, :], [(0, st.mp)], self.U[k:k + 1])
        off = 0
        for i, c in enumerate(self.controllers):
            if self.t[k] + 1e-12 >= self.nxt[i]:
                meas = np.array([y[n][0] for n in c.measure[:]])
                val = np.atleast_1d(np.asarray(c.law(self.t[k], meas), float))
                self.U[k:, self.idx[i]] = val
                while self.nxt[i] <= self.t[k] + 1e-12:
                    self.nxt[i] += c.Ts
            off += len(c.measure)
