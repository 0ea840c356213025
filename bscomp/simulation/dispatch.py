"""The one entry point of time simulation, :func:`simulate`, and its table of methods.

Every method is a function ``run(problem, options) -> SimulationResult`` of a
:class:`~bscomp.simulation.common.SimulationProblem` (model resolved, grid checked, start point, held
inputs, outputs, controllers) and the :class:`~bscomp.simulation.common.SimulationOptions`, in a file of
its own:

========  =====================================  ==============================================
method    module                                 what
========  =====================================  ==============================================
idas      :mod:`bscomp.simulation.idas`          variable-step BDF (IDAS), error controlled
fixed     :mod:`bscomp.simulation.fixed_step`    fixed-step L-stable SDIRK3, compiled chunks
lti       :mod:`bscomp.simulation.zoh`           exact zero-order hold of the linearized model
split     :mod:`bscomp.simulation.split`         exact ZOH of the linear part + implicit laws
modal     :mod:`bscomp.simulation.modal`         exact modal ZOH + low-rank implicit corrections
                                                 (friction, backlash, moving screw-nut joint)
========  =====================================  ==============================================

A new method is one more entry in :data:`METHODS`.
"""

from __future__ import annotations

import numpy as np

from bscomp.errors import ArgumentTypeError, SolverError, UsageError, check_number
from bscomp.simulation.common import HUGE, SimulationOptions, prepare
from bscomp.simulation.fixed_step import simulate_fixed
from bscomp.simulation.idas import simulate_idas
from bscomp.simulation.modal import ModalResult, check_modal_options, simulate_modal
from bscomp.simulation.result import SimulationError, SimulationResult
from bscomp.simulation.sampled import SampledController
from bscomp.simulation.split import simulate_split
from bscomp.simulation.travel import NutOffScrewError, check_travel, travel_limits
from bscomp.simulation.zoh import simulate_zoh

__all__ = ["simulate", "METHODS", "SimulationResult", "SimulationError", "SampledController", "NutOffScrewError"]

#: method name -> ``run(problem: SimulationProblem, options: SimulationOptions) -> SimulationResult``
METHODS = {
    "idas": simulate_idas,
    "fixed": simulate_fixed,
    "lti": simulate_zoh,
    "split": simulate_split,
    "modal": simulate_modal,
}


def simulate(model, t, inputs: dict | None = None, x0: dict | None = None, params: dict | None = None,
             outputs=None, controllers=None, rtol: float = 1e-6, atol: float = 1e-9, max_order: int = 2,
             progress: bool | None = None, max_num_steps: int = 100000, method: str = "idas", substeps: int = 1,
             newton_iter: int = 2, jit: bool = False, modal_options: dict | None = None) -> SimulationResult:
    """Integrate a model over the time grid ``t`` (IDAS, fixed-step SDIRK3, exact ZOH, split or modal).

    Parameters
    ----------
    model : str, path, callable, System, Dae or ModelSpec
        Anything :func:`bscomp.model.as_dae` takes: a registered system name (``"small_drive"``), a ``.py``
        file defining ``build()``, a build function, a System, a flattened Dae or a ModelSpec.
    t : array
        Output times (increasing); the first is the start time.
    inputs : dict, optional
        Input name -> scalar, array (per time point or per interval) or function of t, held piecewise
        constant on the grid (arrays: value at the interval start; callables: at the interval midpoint).
    x0 : dict, optional
        Initial states by name (others at their start values; (x', z) made consistent).
    params : dict, optional
        Parameter overrides by dotted name (for a name, path, build function or spec also build keywords).
    outputs : list of str, optional
        Observables to record (``"table.a"``...).
    controllers : list of SampledController, optional
        Discrete controllers in the loop, run every ``Ts`` with zero-order hold (their actuated inputs are
        overwritten); :func:`bscomp.simulation.sampled_controller` makes one from sampled blocks.
    rtol, atol : float
        IDAS tolerances.
    max_order : int
        Maximum BDF order (2 keeps A-stability for lightly damped structures).
    progress : bool, optional
        Print a progress bar to stderr (default: when the run has more than 200 intervals and stderr is
        a terminal).
    max_num_steps : int
        IDAS: most internal steps per integrator call.
    method : {"idas", "fixed", "lti", "split", "modal"}
        ``"idas"``: the nonlinear DAE with IDAS (variable step, error controlled by rtol/atol).
        ``"fixed"``: the nonlinear DAE with a fixed-step, L-stable, 3rd-order SDIRK method
        (:mod:`bscomp.simulation.fixed_step`), ``substeps`` steps per output interval, exact Newton on the
        nonlinear equations; no error control (check it by halving the step), no per-step Python.
        Its error on the test bed's table acceleration at a 0.1 ms grid is ~1e-4 of the peak
        (``docs/benchmarks.md``). ``"lti"`` (:mod:`bscomp.simulation.zoh`): for **linear** models only, the
        model is linearized once at the start and stepped by exact zero-order-hold discretisation
        (``expm``, one matrix product per output step): the floor for linear structures driven by
        sampled inputs. It is exact for linear time-invariant models and wrong for nonlinear ones
        (friction, backlash, a moving nut): use "idas" or "fixed" there.
        ``"split"`` (**experimental**, :mod:`bscomp.simulation.split`): partitioned exponential integrator.
        The few variables entering F nonlinearly are found symbolically; the rest of the model is the linear
        part, integrated exactly for zero-order-held inputs and a held nonlinear correction ``g`` (its
        end-of-step value: implicit, damped Newton in the nonlinear unknowns only). The linear part is
        re-linearized per *regime* of the nonlinear laws (the tangent of friction sticking / sliding,
        backlash gap / contact; one cached discretisation per regime), so ``g`` is nearly constant
        inside a regime; steps where the regime changes are redone in 16 re-linearized sub-steps. Linear
        models: "lti" to ~1e-10 (2.4e-11 on the axial+torsional test bed with B). Measured (``docs/nonlinear.md``):
        Coulomb oscillator 5e-3 / 7e-4 of x0 at 2^-12 / 2^-14 s steps; test bed with Table 5.2 friction and
        backlash, 0.4 s vs IDAS rtol 1e-8: table.v 1.3e-4, table.s 8e-6, rotor.w 7e-6 (IDAS default
        tolerances: 4.6e-4, 8e-5, 1.1e-4); 1 s of it in ~1.5 s wall for the first run from a start
        point, ~0.9 s for a repeated one (the set-up is cached on the Dae). Its accuracy is not error
        controlled; check it with ``substeps``.
        ``"modal"`` (:mod:`bscomp.simulation.modal`): the linear part exactly in modal coordinates (zero-order
        hold, any step), friction, backlash and **moving joints** (the nut travelling along the screw,
        :class:`~components.moving_screw_nut.MovingScrewNut`, Sec 5.2.2.3) as low-rank implicit corrections,
        their forces first-order held with the interpolation error checked inside every step
        (``modal_options["tol"]``) and regime changes (gap/contact, stick/slide) refined. Needs a model
        flattened from a System. Measured against IDAS at rtol 1e-9 and for speed in ``docs/nonlinear.md``.
    substeps : int
        ``method="fixed"`` / ``"split"`` / ``"modal"``: integration steps per output interval.
    newton_iter : int
        ``method="split"``: Newton iterations always done per step (up to 4x more while unconverged).
        ``method="fixed"``: Newton iterations per stage when the model has nonlinear equations (one
        is exact for an affine model and used then); a chunk that has not converged is redone with
        four times as many and a backtracking line search, then fails with SimulationError.
    jit : bool
        ``method="fixed"`` / ``"split"`` / ``"modal"``: compile the step to C with the system compiler (cached
        on disk, see :func:`bscomp.simulation.native.native_function`): ~10x faster on small (reduced)
        models, ~1 s to compile once (modal: 5-20 s once per model shape, its kernels take every number as
        an input).
    modal_options : dict, optional
        ``method="modal"``: ``tol`` (interpolation error of the nonlinear forces inside a step, relative to the largest
        of them so far; default 1e-3; a light mass beside much larger impacts, or the acceleration of a mass creeping
        below breakaway, wants 1e-4, see ``docs/nonlinear.md``), ``f_keep`` (highest undamped natural frequency kept
        dynamically [Hz], the others static; default 3e4 Hz, raised to an octave above the modes a stiff contact makes
        in its contact regime -- ``stats["f_keep_used"]`` -- a given value is kept and warned about; None keeps all),
        ``window`` (elements between the moving contact point and the reference position of the linear part before the
        reference follows it; default 2).

    Returns
    -------
    SimulationResult
        Time histories (``result["table.a"]``), with ``stats`` of the run (``wall_s``, ``method``...).

    Raises
    ------
    SimulationError
        With the time window, the largest state (IDAS) or the failing Newton iteration (fixed, split) and
        a hint; :class:`~bscomp.simulation.travel.NutOffScrewError` when a moving nut leaves its screw (the
        time, position and span; ``.partial`` holds the run up to then).
    UnknownNameError
        An unknown model, input, state or output name.
    ValueError
        A bad time grid, input array shape, method or step setting.
    """
    run = METHODS.get(method)
    if run is None:
        raise UsageError(f"method must be one of {', '.join(map(repr, METHODS))}, got {method!r}")
    options = SimulationOptions(rtol=rtol, atol=atol, max_order=max_order, max_num_steps=max_num_steps,
                                substeps=substeps, newton_iter=newton_iter, jit=jit, modal=modal_options)
    _check_options(options, method, progress)
    problem = prepare(model, t, inputs, x0, params, outputs, controllers, progress)
    if problem.dae.nx == 0:
        raise UsageError(f"'{problem.dae.name}' has no states: there is nothing to integrate",
                         hint="evaluate its outputs directly (they are algebraic functions of the inputs), or add "
                              "a component with dynamics (a mass, an inertia, a filter)")
    asked, limits = list(problem.outputs), travel_limits(problem.dae)
    problem.outputs = asked + [n for n, *_ in limits if n not in asked]   # each moving nut's position, checked
    return _travelled(_finite_run(run, problem, options, method), limits, asked, method, problem.dae.name)


def _check_options(o, method, progress) -> None:
    """Each numeric option and switch of :func:`simulate` checked, by its argument name."""
    check_number("rtol", o.rtol, positive=True)
    check_number("atol", o.atol, positive=True)
    if check_number("max_order", o.max_order, integer=True, minimum=1) > 5:
        raise UsageError(f"max_order must be 1 to 5 (the BDF orders IDAS has), got {o.max_order!r}",
                         hint="2 keeps A-stability for lightly damped structures")
    _check_flag("jit", o.jit)
    _check_flag("progress", progress)
    check_number("max_num_steps", o.max_num_steps, integer=True, minimum=1)
    check_number("substeps", o.substeps, integer=True, minimum=1)
    check_number("newton_iter", o.newton_iter, integer=True, minimum=1)
    if method == "modal":
        check_modal_options(o.modal)


def _travelled(res, limits, asked, method, name) -> SimulationResult:
    """``res`` with every moving nut checked to stay on its screw (:mod:`bscomp.simulation.travel`), holding the
    outputs asked for."""
    check_travel(res, limits, method, name)
    for n in set(res.outputs) - set(asked):
        del res.outputs[n]
    return res


def _finite_run(run, problem, options, method) -> SimulationResult:
    """``run(problem, options)`` (the method's simulator); a :class:`SolverError` naming the inputs when its
    states or outputs overflow."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):   # an overflow is reported below, as one named error
            res = run(problem, options)
    except ValueError as exc:              # scipy's check_finite: the run overflowed
        if "infs or NaNs" not in str(exc):
            raise
        raise _overflow(problem, method) from exc
    bad = [k for k, v in res.outputs.items() if not _bounded(v)]
    if bad or (not isinstance(res, ModalResult) and not _bounded(res.x)):  # modal: x rebuilt on demand
        raise _overflow(problem, method, bad)
    return res


def _bounded(v) -> bool:
    """Finite and within :data:`~bscomp.simulation.common.HUGE` (a runaway is no physical answer either)."""
    v = np.asarray(v)
    return bool(np.all(np.isfinite(v)) and np.max(np.abs(v), initial=0.0) <= HUGE)


def _check_flag(name, value) -> None:
    """A switch must be a bool or None (``jit="no"`` would be truthy and switch it on)."""
    if value is not None and not isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(f"{name} must be True or False, got {type(value).__name__} {value!r}")


def _overflow(problem, method, outputs=()) -> SolverError:
    """The error of a run whose states or outputs are not finite, naming the largest inputs."""
    dae, U = problem.dae, problem.U
    peak = {n: float(np.max(np.abs(U[i]))) for i, n in enumerate(dae.u_names)} if U.size else {}
    big = ", ".join(f"|{n}| up to {v:.3g}" for n, v in sorted(peak.items(), key=lambda kv: -kv[1])[:3] if v)
    what = f"outputs {outputs[:5]}" if outputs else "the states"
    return SolverError(f"simulate(method={method!r}) on '{dae.name}': {what} overflowed (not finite or beyond "
                       f"{HUGE:g}) with inputs "
                       f"{big or 'all zero'}", hint="give inputs of a physical size (in SI units) or check the "
                       "model's parameters")
