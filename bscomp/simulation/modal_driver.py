r"""``simulate(method="modal")``: exact modal zero-order hold for the linear part, friction, backlash and moving
joints as implicit low-rank corrections (:mod:`~bscomp.simulation.modal_channels`,
:mod:`~bscomp.simulation.modal_parts`, :mod:`~bscomp.simulation.modal_steps`, :mod:`~bscomp.simulation.moving_joints`).

Regimes and references
----------------------
The linear part holds each element in a *regime* -- the slopes of its law on one of its branches (backlash:
gap ``0`` or contact ``c``; friction: sticking ``F_c / v_reg`` or sliding ``0``; the element's tangent at rest
and on its outer branches) -- and each moving joint frozen at a reference position ``z_r``. After every step
the regime nearest to the elements' current tangents is taken (a state is mapped into the new modal
coordinates by projection), so inside a regime the correction is nearly constant (exact for piecewise-linear
laws) and steps are long; the correction is exact in any regime, so the choice affects the step count, not
the equations. The joint's correction touches the potentials of the element holding the contact point and of
the one holding ``z_r``: crossing a node changes only which rows and columns of the modal matrices are used.
When the contact point is more than ``window`` elements from ``z_r``, the reference moves to it (one new modal
part). Every combination of regimes and references is built once and cached.
"""

from __future__ import annotations

import time
import warnings

import casadi as ca
import numpy as np

from bscomp.errors import ModelLimitationWarning
from bscomp.simulation.compiled_time import ELEMENT_BAND
from bscomp.simulation.modal_channels import (
    Channels,
    DefectiveLinearPart,
    LinearPart,
    ModalSimulationError,
    rigid_body_dampers,
)
from bscomp.simulation.modal_kernels import CTL, FORCE_FLOOR, Kernel, NumpyCall
from bscomp.simulation.modal_laws import REGIME_MARGIN, LawSpec, coefficient_patterns, regime_eps
from bscomp.simulation.modal_parts import ModalPart, element_bands
from bscomp.simulation.modal_steps import THETAS, ModalHistory, Stepper, block

__all__ = ["ModalSimulator"]


def _chunk_size(n):
    """Compiled chunk lengths are powers of 4 (1, 4, 16, 64, 256): the smallest one holding n steps."""
    size = 1
    while size < n:
        size *= 4
    return size

NEWTON_ACCEPT = 1e-2   # last Newton update accepted: this fraction of the interpolation tolerance [force]
CHUNK = 256           # most sub-steps per compiled chunk
CHUNK_LEVELS = 2      # chunks run at h, h/4 or h/16
CALM = 1              # clean chunks before the next one tries the coarser level
CHUNK_ITERATIONS = -3  # chunks and batches: three chord iterations (a step that needs more is redone finer)
FINE_ITERATIONS = 3   # the finest level: three Newton iterations
FINE_LEVELS = 3       # refinement levels below a failed chunk's level, then single sub-steps
#: Slope given to a free mass in a defective regime, x the element's largest (its correction carries it back).
#: 1e-6 made the free table's mode nearly critically damped on random beds (eigenvector condition 2e9: each
#: switch's projection moved a 1.9 um clearance's s by 2e-8 m); 1e-8: 50 random moving-nut beds' worst table.a
#: 3.9e-2 -> 1.2e-3, none worse (benchmarks/fuzz_moving_nut.py, docs/nonlinear.md "Limits").
DEFECT_DAMPING = 1e-8


class ModalSimulator:
    """Set-up shared by the runs of one model and parameter vector (cached on the Dae).

    Parameters
    ----------
    dae : Dae
    p : ndarray
    f_keep : float or None
        Highest undamped natural frequency kept dynamically [Hz] (mechanical models).
    window : int
        Elements between the contact point and the reference before the reference moves.
    jit : bool
        Compile the step kernels to C (once per shape, cached on disk).
    f_band : bool
        Raise ``f_keep`` to keep the modes the elements' stiff regimes make (:meth:`_element_band`; the default
        ``f_keep`` does), else warn when it makes them static.
    """

    def __init__(self, dae, p, f_keep=None, window=2, jit=False, f_band=False):
        self.dae, self.p, self.f_keep, self.window, self.jit = dae, p, f_keep, int(window), bool(jit)
        t0 = time.perf_counter()
        self.ch = ch = Channels(dae, p)
        self.cands = [ch.candidate_regimes(i) for i in range(len(ch.elements))]
        self.parts, self.steppers, self.laws, self.kernels = {}, {}, {}, {}
        self._slopes = None
        self._last_stepper = None
        self._pads = []
        self.outputs = {}     # names -> modal.Outputs (rows per modal part)
        self._checked = set()
        self._csets = {}
        self._ctl_buf = np.zeros(CTL)           # the stop rule handed to every kernel call (copied by the call)
        self.stats = {"setup_channels_s": time.perf_counter() - t0, "modal_parts": 0, "modal_part_s": 0.0}
        self._element_band(f_band)
        self._rest_part()

    def _element_band(self, auto):
        """Every mode to an octave above those an element's stiffest regime makes stays dynamic in every regime
        (:func:`~bscomp.simulation.modal_parts.element_bands`): with ``auto`` (the default ``f_keep``) ``f_keep``
        is raised to that band, else a ModelLimitationWarning says what the given one makes static."""
        for path, band in element_bands(self.ch, self.cands) if self.f_keep is not None else ():
            if band > self.f_keep and auto:
                self.f_keep = band
            elif band > self.f_keep:
                warnings.warn(f"'{self.dae.name}': modal_options f_keep={self.f_keep:g} Hz makes modes of '{path}' in "
                              f"its stiffest regime static (up to {band / ELEMENT_BAND:.4g} Hz, the band to {band:.4g} "
                              "Hz): every impact rings them, the static part does not -- leave f_keep at its default "
                              "(which keeps that band) or set None to keep every mode",
                              ModelLimitationWarning, stacklevel=7)   # the caller of simulate
        self.stats["f_keep_used"] = self.f_keep

    def _rest_part(self):
        """Build the rest regime's modal part; when it has a Jordan block that no element can take (an undamped
        rigid-body mode: a free screw, a rotor without motor damping), cut the channels again with a
        :class:`~bscomp.simulation.modal_channels.RigidBodyDamper` on each rigid-body mode (the equations stay
        the model's) and build it from those."""
        rest = tuple(0 for _ in self.ch.elements)
        z0 = [jt.z0 for jt in self.ch.joints]
        try:
            self.part(rest, z0)
        except DefectiveLinearPart:
            dampers = rigid_body_dampers(LinearPart(self.ch, self.slopes(rest), z0))
            if not dampers:
                raise
            self.ch = Channels(self.dae, self.p, rigid=dampers)
            self.cands = [self.ch.candidate_regimes(i) for i in range(len(self.ch.elements))]
            self._csets, self._slopes = {}, None
            self.stats["rigid_body_dampers"] = [d.path for d in dampers]
            self.part(tuple(0 for _ in self.ch.elements), z0)

    # ---- cached pieces ----------------------------------------------------------------------------------
    def part(self, regime, z_ref):
        """The modal part for a regime (indices into the candidates) and joint references."""
        key = (tuple(regime), tuple(round(z, 12) for z in z_ref))
        mp = self.parts.get(key)
        if mp is None:
            t0 = time.perf_counter()
            slopes = self.slopes(regime)
            try:
                mp = ModalPart(LinearPart(self.ch, slopes, z_ref), self.f_keep)
            except DefectiveLinearPart:          # e.g. a mass left free (sliding, clearance open): see damped()
                damped = self.damped(slopes)
                if damped is None:
                    raise
                mp = ModalPart(LinearPart(self.ch, damped, z_ref), self.f_keep)
            mp.regime, mp.z_ref = tuple(regime), tuple(z_ref)
            self.parts[key] = mp
            self.stats["modal_parts"] += 1
            self.stats["modal_part_s"] += time.perf_counter() - t0
        return mp

    def slopes(self, regime):
        return [self.cands[i][r] for i, r in enumerate(regime)]

    def damped(self, slopes):
        """The slopes with every zero damping slope raised to ``DEFECT_DAMPING`` x the element's largest
        candidate one (an element with no damping at all: its zero stiffness slope likewise): a regime that
        leaves a mass free (friction sliding, clearance open) has a Jordan block and no modal coordinates; a
        small slope in the linear part removes it, and the correction of that element carries the difference,
        so the equations stay exact (only the split between linear part and correction changes). None when no
        element has a slope to give."""
        out = []
        for (k, d), cand in zip(slopes, self.cands, strict=True):
            k_max, d_max = (max(abs(c[j]) for c in cand) for j in (0, 1))
            if d == 0.0 and d_max > 0.0:
                d = DEFECT_DAMPING * d_max
            elif k == 0.0 and d == 0.0 and k_max > 0.0:      # an undamped clearance: a weak spring instead
                k = DEFECT_DAMPING * k_max
            out.append((k, d))
        return None if out == list(slopes) else out

    def channel_set(self, z, z_ref):
        """Per joint ``(S, elements)``: the potentials the correction touches with the contact point at ``z``
        (cached by the contact points' and references' elements: the same object for the same set, which the
        stepper cache compares by identity)."""
        elems = tuple(jt.element_of(zj) for jt, zj in zip(self.ch.joints, z, strict=True))
        key = (elems, tuple(jt.element_of(zr) for jt, zr in zip(self.ch.joints, z_ref, strict=True)))
        out = self._csets.get(key)
        if out is None:
            out = self._csets[key] = tuple((jt.dofs_for([e], zr), (e,))
                                           for jt, e, zr in zip(self.ch.joints, elems, z_ref, strict=True))
        return out

    def law(self, cset):
        """The :class:`~bscomp.simulation.modal_laws.LawSpec` of a channel set's shape: its sizes and where the
        joints' polynomial coefficients are nonzero (cached)."""
        sizes = tuple((len(S), len(el)) for S, el in cset)
        pats = coefficient_patterns(self.ch, cset)
        key = (sizes, tuple(tuple(p.tobytes() for p in pj) for pj in pats))
        spec = self.laws.get(key)
        if spec is None:
            spec = LawSpec(self.ch, sizes, self.cands, pats)
            spec.f = spec.function()
            spec.fs = spec.functions()
            self.laws[key] = spec
        return spec

    def stepper(self, mp, cset):
        """The :class:`~bscomp.simulation.modal_steps.Stepper` of a modal part and channel set (cached; the last
        one is returned without building its key)."""
        last = self._last_stepper
        if last is not None and last[0] is mp and last[1] is cset:
            return last[2]
        key = (id(mp), tuple((tuple(S), el) for S, el in cset))
        st = self.steppers.get(key)
        if st is None:
            spec = self.law(cset)
            theta = spec.pack(mp.regime, mp.lin.regime, mp.z_ref, cset)      # the slopes the part was built with
            S_list = [S for S, _ in cset]
            rows, gsel = self.rows(mp, S_list), self.gsel(mp, S_list)
            extrema = tuple(i for i, cand in enumerate(self.cands) if any(c[0] != 0.0 for c in cand))
            shape = (self._padded(mp.lam.size), self.dae.nu, gsel.size, rows[0].shape[0], spec.key, extrema)
            kern = self.kernels.get(shape)
            if kern is None:
                kern = self.kernels[shape] = Kernel(*shape[:4], spec.fs, 2 * len(self.ch.elements), THETAS,
                                                    jit=self.jit, extrema=extrema, law=spec.f)
            st = Stepper(mp, rows, gsel, theta, kern)
            self.steppers[key] = st
        self._last_stepper = (mp, cset, st)
        return st

    def _padded(self, m):
        """Kernel size for a part of m modal coordinates: the smallest padded size already used that holds
        it, else m + 2 rounded up to 4 (parts of nearby sizes share one kernel and its compiled code)."""
        fits = [k for k in self._pads if k >= m]
        if fits:
            return min(fits)
        self._pads.append(-(-(m + 2) // 4) * 4)
        return self._pads[-1]

    def gsel(self, mp, S_list):
        sel = list(range(len(self.ch.elements)))
        for (off, _), S in zip(mp.lin.joint_cols, S_list, strict=True):
            sel += [off + int(i) for i in S]
        return np.array(sel, int)

    def rows(self, mp, S_list):
        """Modal rows of the measured channel coordinates (elements' s, v; joints' d (, ḋ) on S)."""
        ch, dae = self.ch, self.dae
        blocks = []
        if ch.elements:
            y0, Jxd, Jx, Jz, Ju = ch.el_rows
            blocks.append((Jxd, Jx, Jz, Ju, y0))
        for jt, S in zip(ch.joints, S_list, strict=True):
            P = jt.P[S]
            nS = len(S)
            blocks.append((np.zeros((nS, dae.nx)), (P @ ch.Sq_x).toarray(), (P @ ch.Sq_z).toarray(),
                           np.zeros((nS, dae.nu)), np.zeros(nS)))
            if jt.C is not None:
                blocks.append(((P @ ch.Sv_xd).toarray(), (P @ ch.Sv_x).toarray(), np.zeros((nS, dae.nz)),
                               np.zeros((nS, dae.nu)), np.zeros(nS)))
        if not blocks:
            blocks = [(np.zeros((0, dae.nx)), np.zeros((0, dae.nx)), np.zeros((0, dae.nz)), np.zeros((0, dae.nu)),
                       np.zeros(0))]
        cat = [np.vstack([b[i] for b in blocks]) for i in range(4)] + [np.concatenate([b[4] for b in blocks])]
        return mp.rows(*cat)

    # ---- regimes and positions ----------------------------------------------------------------------------
    def regime_of(self, y, current=None):
        """Index of the candidate regime nearest each element's tangent at channel values ``y`` (one call of
        the elements' slope Function; the distance and the margin that keeps ``current`` as in
        :meth:`bscomp.simulation.modal_laws.LawSpec.expr`)."""
        n = len(self.ch.elements)
        if not n:
            return ()
        if self._slopes is None:
            s = ca.SX.sym("s", n)
            v = ca.SX.sym("v", n)
            laws = [el.law(s[i], v[i], ca.DM(el.pvec)) for i, el in enumerate(self.ch.elements)]
            J = ca.vertcat(*[ca.horzcat(ca.jacobian(f, s[i]), ca.jacobian(f, v[i])) for i, f in enumerate(laws)])
            self._slopes = NumpyCall(ca.Function("slopes", [s, v], [ca.densify(J)]))
            self._cand_abs = []
            for cand in self.cands:
                c = np.abs(np.array(cand, float))
                eps = regime_eps(c)
                self._cand_abs.append((np.log(c + eps), eps))
        kd = np.abs(self._slopes(y[0:2 * n:2], y[1:2 * n:2])[0])
        out = []
        for i, (logc, eps) in enumerate(self._cand_abs):
            dist = np.abs(np.log(kd[i] + eps) - logc).sum(axis=1)
            best = int(np.argmin(dist))
            keep = current is not None and dist[current[i]] <= dist[best] + REGIME_MARGIN
            out.append(current[i] if keep else best)
        return tuple(out)

    def positions(self, y, cset):
        """Contact-point positions from channel values ``y`` (the slow potential is last in each S)."""
        z, off = [], 2 * len(self.ch.elements)
        for jt, (S, _) in zip(self.ch.joints, cset, strict=True):
            z.append(jt.position(y[off + len(S) - 1]))
            off += len(S) * (2 if jt.C is not None else 1)
        return z

    # ---- the run ----------------------------------------------------------------------------------------
    def run(self, t, U, xs, tol=1e-3, chunks=True, breaks=(), sample=None, progress=None):
        """Integrate over the grid ``t`` with inputs ``U`` (nt-1, nu) from the state ``xs``.

        Chunks of compiled steps run at a *level* ``L`` (``4^L`` equal sub-steps per grid step, ``L <= 2``):
        a chunk that fails within its first two grid steps sends the level up, a clean chunk brings it
        down. The sub-steps a chunk accepted inside the grid step where it failed are kept; the rest of that grid
        step is done by :meth:`_advance` one level finer.
        ``sample(k, state)`` is called before the step from each grid index in ``breaks`` (sampled
        controllers: it may change ``U[k:]``); chunks end there.
        """
        nt = len(t)
        self.check(U)
        st = _State(self, xs, U[0])
        XI = ModalHistory(nt, st.xi.size)
        G = np.zeros((nt, st.mp.lin.ng))
        XI.put(0, st.xi)
        G[0] = st.g
        segs = [(0, st.mp)]
        self.scale = 1.0
        h_all = np.diff(t)
        k, n_chunk, level, calm = 0, 16, 0, 0
        brk = np.zeros(nt + 1, bool)
        brk[np.asarray(list(breaks), int)] = True
        # a chunk ends before a break or a change of the grid step: the next such index after each k
        cut = brk[1:nt].copy()
        cut[:-1] |= np.abs(h_all[1:] - h_all[:-1]) > 1e-9 * h_all[1:]
        stops = np.r_[np.flatnonzero(cut) + 1, nt - 1]
        last_bar = 0
        while k < nt - 1:
            h = h_all[k]
            if brk[k] and sample is not None:
                sample(k, st)
            if progress is not None and k - last_bar >= 2000:
                progress(k)
                last_bar = k
            if chunks:
                cap = min(n_chunk, CHUNK // 4 ** level)
                n = max(1, min(cap, int(stops[np.searchsorted(stops, k, side="right")]) - k))
                done, part = self._chunk(st, U, k, n, h, tol, XI, G, level)
                per = 4 ** level
                k += done
                if st.mp is not segs[-1][1]:          # the chunk's last step switched the linear part:
                    segs.append((k + 1, st.mp))       # grid point k is stored in the old coordinates
                if done == n:
                    n_chunk = min(4 * n_chunk, CHUNK)
                    calm += 1
                    if calm >= CALM and level:
                        level, calm, n_chunk = level - 1, 0, 4      # probe the coarser level with a short chunk
                    continue
                n_chunk, calm = 4, 0
                if done < 2 and level < CHUNK_LEVELS:
                    level += 1
                if k >= nt - 1:
                    break
                # the rest of grid step k one level finer (its first `part` sub-steps were accepted)
                fine = 4 ** (level + 1) // per
                self._advance(st, U[k], (per - part) * h / per, (per - part) * fine, h, tol, 0)
            else:
                self._advance(st, U[k], h, 4 ** (level + 1), h, tol, 0)
            if st.mp is not segs[-1][1]:
                segs.append((k + 1, st.mp))
            XI.put(k + 1, st.xi)
            G[k + 1] = st.g
            k += 1
        if progress is not None:
            progress(nt - 1)
        self.stats.update(self.counts, force_scale=self.scale)
        return XI, G, segs

    def check(self, U):
        """The decomposition is exact at the run's extreme inputs and at a random state (else a nonlinearity
        outside the channels -- an amplifier's current limit, a nonlinear spring -- would be linearized
        silently): ModalSimulationError naming the equation."""
        key = (U.min(axis=0).tobytes(), U.max(axis=0).tobytes())
        if key in self._checked:
            return
        lin = self.part(tuple(0 for _ in self.ch.elements), [jt.z0 for jt in self.ch.joints]).lin
        bad = lin.outside(U.min(axis=0), U.max(axis=0), U[0])
        if bad is not None:
            origin, err, scale = bad
            raise ModalSimulationError(
                f"'{self.dae.name}': equation '{origin}' is nonlinear outside the friction/backlash elements and "
                f"moving joints method='modal' corrects (residual {err:.2g} of {scale:.2g} at the run's input "
                "extremes; e.g. an amplifier current limit): use method='idas' or 'split'")
        self._checked.add(key)

    def _ctl(self, tol, wanted):
        """The kernel's stop rule (the one of :meth:`_flags`): ``[tol, running force scale, Newton acceptance, steps
        wanted]``; errors are judged against the step's largest force, at least ``FORCE_FLOOR`` (1.0) x the running
        scale."""
        ctl = self._ctl_buf
        ctl[0], ctl[1], ctl[2], ctl[3] = tol, self.scale, NEWTON_ACCEPT * tol, wanted
        return ctl

    def _flags(self, info, aux, tol):
        """``(j, switch, scale_j, scale_c)`` of a block of step infos: the first ``j`` steps are accepted; ``switch``:
        the last of them ended in another regime (the linear part is switched there); ``scale_j`` the running force
        scale after the ``j`` accepted steps, ``scale_c`` after every computed one (``c``: ``j`` or ``j + 1``, what a
        forced acceptance takes). A step is bad if its interpolation error or last Newton update exceeds the
        tolerance times its largest force (at least ``FORCE_FLOOR`` x the running scale) or its contact point left
        the element.

        The kernel applies the same rule and skips every step after the first bad or regime-changing one
        (:data:`~bscomp.simulation.modal_kernels.SKIPPED`) or after the steps wanted; its running numbers ``aux``
        say how many it computed and the scales (:meth:`~bscomp.simulation.modal_kernels.Kernel.chunk`), so only
        the last computed step is tested here."""
        top, _, c, before = aux.tolist()
        c = int(c)
        if c == 0:
            return 0, False, self.scale, self.scale
        err, fmax, okr, oke, upd = info[c - 1].tolist()
        sc = max(fmax, FORCE_FLOOR * top)
        if err > tol * sc or oke < 0.5 or not upd < NEWTON_ACCEPT * tol * sc:
            return c - 1, False, before, top
        return c, bool(okr < 0.5), top, top

    def _chunk(self, st, U, k, n, h, tol, XI, G, level):
        """Up to ``n`` grid steps (``4^level`` sub-steps each) in one compiled call: ``(done, part)``, the grid
        steps accepted (stored in XI, G) and the sub-steps accepted of the next one (the state is left after
        them; the driver finishes that grid step finer)."""
        stp = self.stepper(st.mp, st.cset)
        per = 4 ** level
        tau = h / per
        _, mats = stp.data(tau)
        run = stp.kernel.runner(_chunk_size(n * per), CHUNK_ITERATIONS)
        N = run.n
        Uc = np.repeat(U[k:k + n], per, axis=0)
        if N > len(Uc):
            Uc = np.vstack([Uc, np.repeat(Uc[-1:], N - len(Uc), axis=0)])
        x0 = stp.pack_state(st.xi, st.g[stp.gsel])
        X, info = run(x0, Uc, mats, stp.theta, self._ctl(tol, n * per))
        b, switch, scale, _ = self._flags(info, run.aux, tol)
        done, part = divmod(b, per)
        self.counts["chunks"] += 1
        if not b:
            return 0, 0
        self.scale = scale
        m, mp_ = stp.m, stp.m_part
        if done:
            Xa = X[per - 1:done * per:per]
            xs = Xa[:, :mp_] + 1j * Xa[:, m:m + mp_]
            XI.put_rows(k + 1, xs)
            G[k + 1:k + 1 + done] = 0.0
            G[k + 1:k + 1 + done, stp.gsel] = Xa[:, 2 * m:]
            self.counts["chunk_steps"] += done
        self.counts["substeps"] += part
        xi, g = stp.unpack_state(X[b - 1])
        st.xi = xi
        st.g = np.zeros(st.g.size)
        st.g[stp.gsel] = g
        if switch:                        # the last accepted sub-step ended in another regime
            xi0, g0 = stp.unpack_state(np.asarray(X[b - 2] if b >= 2 else x0))
            uk = U[k + (b - 1) // per]
            st.after(stp.end_values(xi0, g0, g, uk, tau), uk)
        return done, part

    def _advance(self, st, u, T, n, h, tol, depth):
        """Advance the state by ``T`` in compiled batches of ``n`` equal sub-steps, refining every bad sub-step
        (interpolation error, Newton, element change) into 4 one level deeper; a sub-step that ends in another
        regime is accepted and the linear part switched. At the deepest level a bad sub-step is accepted."""
        tau = T / n
        deepest = depth >= FINE_LEVELS
        i = 0
        while i < n:
            stp = self.stepper(st.mp, st.cset)
            sd, mats = stp.data(tau)
            left = n - i
            x0 = stp.pack_state(st.xi, st.g[stp.gsel])
            run = stp.kernel.runner(_chunk_size(left), FINE_ITERATIONS if deepest else CHUNK_ITERATIONS)
            X, info = run(x0, u, mats, stp.theta, self._ctl(tol, left))
            j, switch, scale, scale_c = self._flags(info, run.aux, tol)
            self.counts["batches"] += 1
            forced = deepest and j < left and not switch
            if forced:
                j, scale = j + 1, scale_c             # the finest level: accept the flagged one, follow it
            if j:
                self.scale = scale
                self._accept(st, stp, X, j, u, tau, x0 if j == 1 else X[j - 2], switch or forced)
                i += j
            if i < n and not (deepest or switch):
                self._advance(st, u, tau, 4, h, tol, depth + 1)
                i += 1

    def _accept(self, st, stp, X, j, u, tau, x_before, follow):
        """Take the first j sub-steps of a batch; if the last was flagged, follow the regime or contact point
        it ended in (the others stayed in the current ones)."""
        xi, g = stp.unpack_state(X[j - 1])
        st.xi = xi
        st.g = np.zeros(st.g.size)
        st.g[stp.gsel] = g
        self.counts["substeps"] += j
        if follow:
            xi0, g0 = stp.unpack_state(np.asarray(x_before))
            st.after(stp.end_values(xi0, g0, g, u, tau), u)

    def _switch(self, old, new, xi, u, g, cset, y):
        """Map the state into another modal part and make the channel forces consistent there: the elements'
        total forces are continuous, so ``g`` changes by the change of the slopes times ``(s, v)`` (the start of
        a short Newton on the new part's static feedthrough)."""
        dx = old.state(xi[None, :], u[None, :], g[None, :])[0]
        xi_new = new.project(dx)
        stp = self.stepper(new, cset)
        g = g.copy()
        for i, ((k0, d0), (k1, d1)) in enumerate(zip(old.lin.regime, new.lin.regime, strict=True)):
            g[i] += (k0 - k1) * y[2 * i] + (d0 - d1) * y[2 * i + 1]
        g_act, y, _ = stp.consistent(xi_new, u, g[stp.gsel])
        g_new = np.zeros(new.lin.ng)
        g_new[stp.gsel] = g_act
        self.counts["switches"] += 1
        return xi_new, g_new, y

    def trajectories(self, XI, G, segs, Uh):
        """``(ΔX, Ẋ)`` at the grid points from the modal trajectory (piecewise per modal part)."""
        nt = len(XI)
        dae = self.dae
        X = np.zeros((nt, dae.nx))
        XD = np.zeros((nt, dae.nx))
        bounds = [s for s, _ in segs] + [nt]
        for (k0, mp), k1 in zip(segs, bounds[1:], strict=True):
            if k1 <= k0:
                continue
            xi = block(XI, k0, k1, mp.lam.size)
            u, g = Uh[k0:k1], G[k0:k1]
            X[k0:k1] = mp.state(xi, u, g)
            Vr, Vrd = mp.rate_rows()
            rate = xi * mp.lam + u @ mp.Bu.T + g @ mp.Bg.T + mp.bc
            XD[k0:k1] = (xi @ Vr.T + rate @ Vrd.T).real
        return X, XD


class _State:
    """The running state of a simulation: modal part, coordinates, channel forces, regimes, positions."""

    def __init__(self, sim, xs, u0):
        self.sim = sim
        ch = sim.ch
        self.z_ref = [jt.z0 for jt in ch.joints]
        self.z = list(self.z_ref)
        self.cset = sim.channel_set(self.z, self.z_ref)
        mp = sim.part(tuple(0 for _ in ch.elements), self.z_ref)
        self.mp = mp
        self.xi = mp.W @ (np.asarray(xs, float) - ch.x_a)
        g, y, _ = sim.stepper(mp, self.cset).consistent(self.xi, u0, np.zeros(len(sim.stepper(mp, self.cset).gsel)))
        self.g = np.zeros(mp.lin.ng)
        self.g[sim.stepper(mp, self.cset).gsel] = g
        sim.counts = dict(substeps=0, rejected=0, events=0, switches=0, chunks=0, chunk_steps=0, batches=0)
        self.after(y, u0)

    def after(self, y, u):
        """After an accepted step ending at channel values ``y``: follow the contact points and regimes."""
        sim = self.sim
        ch = sim.ch
        z_new = sim.positions(y, self.cset)
        moved = any(jt.element_of(a) != jt.element_of(b) for jt, a, b in zip(ch.joints, z_new, self.z, strict=True))
        self.z = z_new
        new_ref = list(self.z_ref)
        if moved:
            if any(abs(jt.element_of(a) - jt.element_of(r)) > sim.window
                   for jt, a, r in zip(ch.joints, self.z, self.z_ref, strict=True)):
                new_ref = list(self.z)
            self.cset = sim.channel_set(self.z, new_ref)
        regime = sim.regime_of(y, self.mp.regime)
        if regime != self.mp.regime or new_ref != self.z_ref:
            self.z_ref = new_ref
            self.cset = sim.channel_set(self.z, self.z_ref)
            new = sim.part(regime, self.z_ref)
            self.xi, self.g, y = sim._switch(self.mp, new, self.xi, u, self.g, self.cset, y)
            self.mp = new
        elif moved:
            stp = sim.stepper(self.mp, self.cset)
            g = np.zeros(self.g.size)
            g[stp.gsel] = self.g[stp.gsel]
            self.g = g
