r"""Driver and results of ``simulate(method="modal")``: sampled controllers, outputs from the modal trajectory,
states reconstructed only when asked for.

Outputs that are affine in ``(x', x, z, u)`` (positions, velocities, accelerations, forces of linear parts) are
rows of the modal coordinates and channel forces (:meth:`bscomp.simulation.modal_parts.ModalPart.rows`): one product per
stretch of the run in one modal part. Others (an element's force, the contact point ``sn.z``) are evaluated by
the model's own output function on the few state columns they depend on. The full state history ``x``, ``x'``
(``z``) is rebuilt from the modal trajectory the first time it is read.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import casadi as ca
import numpy as np

from bscomp.errors import ArgumentTypeError, UsageError, check_number
from bscomp.memo import kept
from bscomp.simulation.common import Progress, SampledLoop, evaluate_mapped, result_units
from bscomp.simulation.modal_driver import ModalSimulator
from bscomp.simulation.modal_steps import block
from bscomp.simulation.result import SimulationResult

__all__ = ["simulate_modal", "check_modal_options", "ModalResult", "DEFAULTS"]

#: ``options`` of ``simulate(method="modal")`` and their defaults
DEFAULTS = {"tol": 1e-3, "f_keep": 3e4, "window": 2}


class ModalResult(SimulationResult):
    """A :class:`~bscomp.simulation.result.SimulationResult` whose state histories ``x``, ``xd``, ``z`` are
    rebuilt from the modal trajectory the first time one is read (outputs are computed at once)."""

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


def sample_indices(t, controllers):
    """Grid indices at which the sampled controllers update (the rule of :class:`SampledLoop`)."""
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
        self._rows = {}
        key = ("modal_outputs", tuple(self.names))    # the model's expressions: built once per Dae and names
        built = sim.dae._cache.get(key)
        if built is None:
            built = sim.dae._cache[key] = self._build(sim.dae, self.names)
        self.affine, self.other, self._jac, self.cols, self._fo = built
        self._fo_key = ("modal_other", tuple(self.other))

    @staticmethod
    def _build(dae, names):
        """``(affine names, other names, Jacobian Function of the affine ones, columns the others read, their
        Function)``."""
        e = dae.output_expr(names) if names else ca.SX(0, 1)
        v = ca.vertcat(dae.xds, dae.xs, dae.zs, dae.us)
        J = ca.jacobian(e, v)
        affine = [not ca.depends_on(J[i, :], v) for i in range(len(names))]
        aff = [n for n, a in zip(names, affine, strict=True) if a]
        other = [n for n, a in zip(names, affine, strict=True) if not a]
        jac = cols = fo = None
        if aff:                  # the affine rows of e and J (one expression and one differentiation for all)
            ia = [i for i, a in enumerate(affine) if a]
            Ja = J[ia, :]
            nx, nz = dae.nx, dae.nz
            cuts = np.cumsum([0, nx, nx, nz, dae.nu])
            jac = ca.Function("yj", [dae.xds, dae.xs, dae.zs, dae.us, dae.ps],
                              [e[ia]] + [Ja[:, int(a):int(b)] for a, b in zip(cuts[:-1], cuts[1:], strict=True)])
        if other:                # evaluated on the few state columns they read (every symbol of the expression)
            eo = e[[i for i, a in enumerate(affine) if not a]]
            used = {v.name() for v in ca.symvar(eo)}
            vecs = (dae.xds, dae.xs, dae.zs)
            cols = [np.array([i for i, sym in enumerate(ca.vertsplit(v)) if sym.name() in used], int) for v in vecs]
            sub = [ca.vertcat(*[v[int(i)] for i in c]) if c.size else ca.SX(0, 1) for v, c in zip(vecs, cols,
                                                                                                strict=True)]
            fo = ca.Function("y_other", [*sub, dae.us, dae.ps], [eo])
        return aff, other, jac, cols, fo

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
        if self.other:        # the columns the other outputs read, filled per segment, evaluated in one call
            cd, cx, cz = self.cols
            ch = self.sim.ch
            X, XD, Z = np.empty((nt, cx.size)), np.zeros((nt, cd.size)), np.empty((nt, cz.size))
            X[:], Z[:] = ch.x_a[cx], ch.z_a[cz]
        active = np.flatnonzero(np.any(G != 0.0, axis=0))       # channel forces ever non-zero in the run
        for (k0, mp), k1 in zip(segs, bounds[1:], strict=True):
            if k1 <= k0:
                continue
            xi = block(XI, k0, k1, mp.lam.size)
            u, g = Uh[k0:k1], G[k0:k1]
            if self.affine:
                Cxi, Du, Dg, yc = self.rows(mp)
                Y = (xi @ Cxi.T).real + u @ Du.T + g[:, active] @ Dg[:, active].T + yc
                for i, n in enumerate(self.affine):
                    out[n][k0:k1] = Y[:, i]
            if self.other:
                self._nonaffine(mp, xi, u, g, X[k0:k1], XD[k0:k1], Z[k0:k1])
        if self.other:
            Y = evaluate_mapped(self.sim.dae, self._fo_key, lambda: self._fo, (XD, X, Z, Uh), self.sim.p)
            for i, n in enumerate(self.other):
                out[n] = Y[:, i].copy()
        return out

    def _nonaffine(self, mp, xi, u, g, X, XD, Z):
        """Fill ``(X, XD, Z)``: views of one segment on the columns the non-affine outputs read (X and Z holding
        the rest point)."""
        cd, cx, cz = self.cols
        if cx.size:
            X += (xi @ mp.Vx[cx].T).real + u @ mp.Xu[cx].T + g @ mp.Xg[cx].T + mp.xc[cx]
        if cd.size:
            Vr, Vrd = mp.rate_rows()
            rate = xi * mp.lam + u @ mp.Bu.T + g @ mp.Bg.T + mp.bc
            XD[:] = (xi @ Vr[cd].T + rate @ Vrd[cd].T).real
        if cz.size and mp.Z is not None:
            Zx, Zu, Zg, zc = mp.Z
            dx = mp.state(xi, u, g)
            Z += dx @ Zx[cz].T + u @ Zu[cz].T + g @ Zg[cz].T + zc[cz]


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


def simulator(dae, p, options, jit=False, f_band=False):
    """The cached :class:`~bscomp.simulation.modal_driver.ModalSimulator` of a Dae, parameter vector and
    options (up to four per Dae: a repeated run skips the set-up). ``f_band``: ``f_keep`` is the default and may
    be raised to keep the modes of the elements' stiff regimes."""
    key = ("modal", p.tobytes(), options["f_keep"], options["window"], bool(jit), bool(f_band))
    return kept(dae._cache.setdefault("modal_simulators", {}), key,
                lambda: ModalSimulator(dae, p, f_keep=options["f_keep"], window=options["window"], jit=jit,
                                       f_band=f_band), 4)


def check_modal_options(modal_options) -> dict:
    """``modal_options`` with the defaults filled in (:data:`DEFAULTS`), each checked: ``tol`` > 0, ``f_keep`` > 0
    [Hz] or None, ``window`` an integer >= 0; an unknown key is a :class:`UsageError` with the nearest name."""
    import difflib

    if modal_options is not None and not isinstance(modal_options, Mapping):
        raise ArgumentTypeError(f"modal_options must be a dict such as {{'tol': 1e-3}}, got "
                                f"{type(modal_options).__name__} {modal_options!r}"[:200])
    given = dict(modal_options or {})
    for k in given:
        if k not in DEFAULTS:
            near = difflib.get_close_matches(str(k), list(DEFAULTS), n=1)
            raise UsageError(f"modal_options: unknown option {k!r}" + (f" (did you mean {near[0]!r}?)" if near else "")
                             + f"; options: {sorted(DEFAULTS)}")
    opts = dict(DEFAULTS, **given)
    opts["tol"] = check_number("modal_options['tol']", opts["tol"], positive=True)
    if opts["f_keep"] is not None:                   # inf keeps every mode, like None
        f_keep = opts["f_keep"]
        if not isinstance(f_keep, (int, float, np.number)) or isinstance(f_keep, bool) or not f_keep > 0:
            raise UsageError(f"modal_options['f_keep'] must be a frequency > 0 [Hz] (or None: keep every mode), got "
                             f"{f_keep!r}", hint="the default 3e4 Hz keeps the modes of a feed drive's band")
        opts["f_keep"] = float(f_keep)
    opts["window"] = check_number("modal_options['window']", opts["window"], integer=True, nonnegative=True)
    return opts


def simulate_modal(problem, options):
    """``simulate(method="modal")``: the driver (:class:`~bscomp.simulation.modal_driver.ModalSimulator`).

    Parameters
    ----------
    problem : SimulationProblem
    options : SimulationOptions
        ``substeps`` (steps per output interval), ``jit`` (the step kernels compiled to C, cached on disk) and
        ``modal`` (a dict: ``tol``, ``f_keep``, ``window``; :data:`DEFAULTS`).

    Returns
    -------
    ModalResult
        ``stats``: the counters of :class:`ModalSimulator` (modal parts built, chunks, batches, sub-steps,
        regime switches) and ``wall_s``, ``real_time_factor``.
    """
    opts = check_modal_options(options.modal)
    substeps = int(options.substeps)
    if substeps < 1:
        raise UsageError(f"substeps must be >= 1, got {substeps}")
    dae, t, U, xs, p = problem.dae, problem.t, problem.U, problem.x0, problem.p
    t_wall = time.perf_counter()
    sim = simulator(dae, p, opts, options.jit, f_band="f_keep" not in (options.modal or {}))
    out = sim.outputs.get(tuple(problem.outputs))
    if out is None:
        out = sim.outputs[tuple(problem.outputs)] = Outputs(sim, problem.outputs)
    nt = len(t)
    if substeps > 1:
        ti = np.concatenate([np.linspace(t[k], t[k + 1], substeps + 1)[:-1] for k in range(nt - 1)] + [t[-1:]])
        Ui = np.repeat(U.T, substeps, axis=0)
    else:
        ti, Ui = t, np.array(U.T)
    controllers = problem.controllers
    samples = sample_indices(ti, controllers) if controllers else []
    sampler = _Sampler(dae, sim, controllers, ti, Ui) if controllers else None
    bar = Progress(dae.name, ti, problem.progress, every=1)
    XI, G, segs = sim.run(ti, Ui, xs, tol=opts["tol"], breaks=samples, sample=sampler,
                          progress=(lambda k: bar.update(0, k)) if problem.progress else None)
    keep = np.arange(0, len(ti), substeps)
    if substeps > 1:
        XI = XI.thinned(keep)
        G = G[keep]
        segs = _thin_segments(segs, substeps)
    Uh = np.vstack([Ui[:1], Ui])[keep]
    y = out.evaluate(XI, G, segs, Uh)
    wall = time.perf_counter() - t_wall
    stats = dict(sim.stats, wall_s=wall, method="modal", step=float(np.min(np.diff(ti))), options=opts,
                 real_time_factor=(t[-1] - t[0]) / wall if wall > 0 else np.inf)
    return ModalResult(lambda: _states(sim, XI, G, segs, Uh), t=t, u=Uh, x_names=list(dae.x_names),
                       z_names=list(dae.z_names), u_names=list(dae.u_names), outputs=y, stats=stats,
                       units=result_units(dae, y))


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
    """Runs the sampled controllers (:class:`~bscomp.simulation.common.SampledLoop`) at their grid indices: the
    measured outputs from the modal state, the held values written into ``U[k:]``."""

    def __init__(self, dae, sim, controllers, t, U):
        self.t, self.U = t, U
        self.loop = SampledLoop(dae, controllers, t[0])
        self.out = Outputs(sim, [m for c in controllers for m in c.measure])
        self.cols = sorted({c for cols in self.loop.columns for c in cols})

    def __call__(self, k, st):
        """Called before the step from grid index k with the running state; updates ``U[k:]`` in place."""
        def y_of(u_k):
            Uk = u_k[None, :]
            y = self.out.evaluate([st.xi], st.g[None, :], [(0, st.mp)], Uk)
            return np.array([y[n][0] for n in self.out.names])

        u_k = self.loop.sample(self.t[k], self.U[k].copy(), y_of)
        self.U[k:, self.cols] = u_k[self.cols]
