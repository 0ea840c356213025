"""FMU export: a flattened drive as an FMI 3.0 model-exchange FMU (CasADi ``DaeBuilder``).

The FMU is an ODE ``x' = f(x, u, p)`` with outputs ``y = g(x, u, p)``, because an FMI importer (FMPy,
Simulink's FMU Import block, OpenModelica, Dymola) integrates the states it is given and solves no
algebraic equations. The bscomp DAE ``F(x', x, z, u, p) = 0`` is index 1 with ``w = (x', z)`` entering
it affinely for every drive bscomp builds (linear structures, friction and backlash act through
positions and velocities, which are states), so

.. math:: F(w) = F(0) + W w, \\qquad w = -W^{-1} F(0, x, 0, u, p), \\qquad W = [\\partial F/\\partial x',
   \\partial F/\\partial z]

is exact. ``W`` depends on the tunable parameters only (masses and inertias), so the generated C code
factorises the sparse ``W`` (CasADi's ``qr`` linear solver, code-generated) at each call: changing a
tunable mass in the importer acts like :meth:`bscomp.System.set`. Parameters that are not exported are
folded in as constants; structural ones (baked into FE or constraint matrices) cannot be tunable.

Pipeline: ``DaeBuilder.export_fmu`` (C sources and a ``modelDescription.xml``) -> the description is
rewritten (:mod:`bscomp._fmu_xml`: structured names, units, descriptions, model structure) ->
``compile_fmu`` (gcc, ``-O2``, the FMI 3.0 headers pinned in ``bscomp/fmi3/``) -> ``pack_fmu`` to a
temporary file renamed onto the target (never a half-written ``.fmu``). See ``docs/fmu.md``.
"""

from __future__ import annotations

import ctypes
import os
import re
import shlex
import shutil
import sys
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from bscomp import __version__
from bscomp._fmu_damping import check_damping_parameters, rayleigh_term
from bscomp._fmu_wrap import TIME_VR, patch_wrapper, state_nominals
from bscomp._fmu_xml import FmuVariable, derivative_name, derivative_unit, structured_name, write_model_description
from bscomp.errors import (
    ArgumentTypeError,
    CompilerNotFoundError,
    FmuExportError,
    UnknownNameError,
    check_names,
)
from bscomp.files import atomic_path, writable_path
from bscomp.kernel.signal_meta import input_meta, measured_outputs, output_meta, parameter_meta, state_meta
from bscomp.model import as_dae, run_overrides

__all__ = ["export_fmu", "FMI3_HEADERS"]

#: Folder with the FMI 3.0 headers (2-Clause BSD, Modelica Association) the FMU is compiled against.
FMI3_HEADERS = Path(__file__).with_name("fmi3")


def export_fmu(system, path, inputs=None, outputs=None, parameters=(), *, overrides: dict | None = None,
               compiler: str | None = None, flags=("-O2",), nominal=None) -> Path:
    """Write a drive as an FMI 3.0 model-exchange FMU.

    Parameters
    ----------
    system : str, path, ModelSpec, build function, System or Dae
        Anything :func:`bscomp.model.as_dae` takes: a registered system name
        (``"testbed_axial_torsional"``), a ``.py`` file defining ``build()``, a System or a flattened Dae.
    path : path-like
        Target file, ending in ``.fmu``. Written to a temporary file first and renamed.
    inputs : str or list of str, optional
        System inputs exposed as FMU inputs (default: all); the others are held at zero. One string is one
        name; a name listed twice is refused (an FMU needs unique variable names).
    outputs : str or list of str, optional
        Observables exposed as FMU outputs (``"table.a"``...). Default: the system's declared measured
        outputs (``system.validation.outputs``), else every state.
    parameters : str, list of str or "all"
        Parameters exposed as tunable FMU parameters (dotted names); the rest are constants of the FMU at
        their current values. ``"all"``: every non-structural parameter.
    overrides : dict, optional
        Parameter / build overrides applied before flattening (``{"coupling.k_T": 45940}``).
    compiler : str, optional
        C compiler executable (default ``gcc``; ``cl.exe`` on Windows).
    flags : str or sequence of str
        Compiler flags (default ``-O2``: ~5x faster derivatives than CasADi's default ``-O0``); a string is
        split like a shell command line (``"-O2 -march=native"``).
    nominal : float or dict, optional
        Nominal of the continuous states (``modelDescription.xml`` and ``fmi3GetNominalsOfContinuousStates``),
        which importers scale their absolute tolerance by (FMPy: ``atol = rtol * nominal``). Default: 1e-3 for
        every state, the ``atol / rtol`` ratio of :func:`bscomp.simulate`'s defaults, so an importer at
        ``rtol = r`` controls the error as ``bscomp.simulate(rtol=r)`` does; a dict sets chosen states
        (``{"table.s": 1e-4}``), the others keep the default. See :mod:`bscomp._fmu_wrap`.

    Returns
    -------
    Path
        The written FMU.

    Raises
    ------
    OutputFileError
        ``path`` does not end in ``.fmu``, is a folder, or its folder does not exist.
    FmuExportError
        A structural (or damping-dependent) tunable parameter, an output name clash, a DAE the explicit
        form does not cover, or a failed compilation (also: a compiler that reports success but leaves no
        shared library exporting the FMI 3.0 functions).
    CompilerNotFoundError
        No C compiler on PATH.
    UsageError, ArgumentTypeError
        A name listed twice in ``inputs``, ``outputs`` or ``parameters``; arguments of the wrong type.
    UnknownNameError
        An input or output that the model does not have.
    """
    path = writable_path(path, "export_fmu: path", (".fmu",)).absolute()
    flags = _check_flags(flags)
    inputs = check_names("export_fmu: inputs", inputs, unique=True)
    outputs = check_names("export_fmu: outputs", outputs, unique=True)
    if not (isinstance(parameters, str) and parameters == "all"):
        parameters = check_names("export_fmu: parameters", parameters, unique=True)
    cc = _find_compiler(compiler)
    dae = as_dae(system, overrides)
    p_start = dae.parameter_vector(run_overrides(system, dae, overrides))   # a Dae keeps its p0: the overrides
    inputs = _check_inputs(dae, inputs)
    outputs = measured_outputs(dae) if outputs is None else outputs
    dae.output_expr(outputs)  # unknown names raise UnknownNameError here
    tunable = _check_parameters(dae, parameters)
    nominals = state_nominals(dae.x_names, nominal)
    ident = re.sub(r"\W", "_", dae.name) or "model"
    ident = ident if not ident[0].isdigit() else "m_" + ident
    rayleigh = check_damping_parameters(dae, tunable)
    builder, plan = _builder(dae, ident, inputs, outputs, tunable, p_start, rayleigh)
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="bscomp_fmu_") as tmp, atomic_path(path) as target:
        try:
            os.chdir(tmp)                    # DaeBuilder writes and compiles in the current directory
            files = builder.export_fmu({"no_warning": True, "with_serialization": False})
            x_vr = _describe(dae, builder, plan, nominals, Path(tmp) / "modelDescription.xml")
            patch_wrapper(Path(tmp) / f"{ident}_wrap.c", x_vr, nominals)   # files: local name -> FMU path
            opts = {"include_dirs": [str(FMI3_HEADERS)],
                    "compiler_options": {"compiler": cc, "compiler_flags": flags}}
            try:
                files = builder.compile_fmu(files, opts)
            except RuntimeError as exc:
                raise FmuExportError(f"export_fmu: compiling the FMU of '{dae.name}' with {cc} failed: "
                                     f"{str(exc).strip().splitlines()[-1]}") from exc
            _check_binary(files, cc, dae.name)
            target.unlink()
            packed = Path(builder.pack_fmu(files, {"path": str(target)}))
            if packed.resolve() != target.resolve():
                os.replace(packed, target)
        finally:
            os.chdir(cwd)
    return path


def _find_compiler(compiler):
    cc = compiler or ("cl.exe" if sys.platform == "win32" else "gcc")
    if shutil.which(cc) is None:
        raise CompilerNotFoundError(
            f"export_fmu needs a C compiler to build the FMU binary and '{cc}' is not on PATH: install one "
            "(Debian/Ubuntu: apt-get install gcc; macOS: xcode-select --install; Windows: Visual Studio Build "
            "Tools) or pass compiler='/path/to/cc'")
    return cc


def _check_flags(flags):
    """Compiler flags as a list of str: a string is split like a shell command line (``"-O2 -g"``)."""
    if isinstance(flags, str):
        return shlex.split(flags)
    if flags is None:
        return []
    if not hasattr(flags, "__iter__") or isinstance(flags, (bytes, dict)) \
            or not all(isinstance(f, str) for f in flags):
        raise ArgumentTypeError(f"export_fmu: flags must be a string ('-O2 -g') or a list of strings "
                                f"(['-O2', '-g']), got {flags!r}"[:300])
    return list(flags)


#: a function every FMI 3.0 model-exchange binary exports (checked after compiling)
_FMI3_SYMBOL = "fmi3InstantiateModelExchange"


def _check_binary(files, cc, name):
    """The compiled shared library exists, is not empty and exports the FMI 3.0 functions, else
    :class:`FmuExportError` naming the compiler (a program that exits 0 without compiling passes otherwise)."""
    libs = [Path(local) for local, inside in files.items() if str(inside).startswith("binaries/")]
    why = None
    if not libs:
        why = "no shared library was listed for the FMU"
    for lib in libs:
        if not lib.is_file() or lib.stat().st_size == 0:
            why = f"it left no shared library {lib.name!r} (or an empty one)"
        elif sys.platform == "win32":               # a DLL loaded into this process could not be deleted
            if _FMI3_SYMBOL.encode() not in lib.read_bytes():
                why = f"{lib.name!r} does not export {_FMI3_SYMBOL}"
        else:
            try:
                ok = hasattr(ctypes.CDLL(str(lib.absolute())), _FMI3_SYMBOL)
            except OSError as exc:
                ok, why = False, f"{lib.name!r} is not a loadable shared library ({exc})"
            if not ok and why is None:
                why = f"{lib.name!r} does not export {_FMI3_SYMBOL}"
        if why:
            break
    if why:
        raise FmuExportError(f"export_fmu: compiling the FMU of '{name}' with {cc!r} reported success but {why}; "
                             "nothing was written: pass compiler= a C compiler (gcc, clang, cl.exe)")


def _check_inputs(dae, inputs):
    if inputs is None:
        return list(dae.u_names)
    bad = [n for n in inputs if n not in dae.u_names]
    if bad:
        raise UnknownNameError(f"export_fmu: '{bad[0]}' is not an input of '{dae.name}'; inputs: {dae.u_names}")
    return inputs


def _check_parameters(dae, parameters):
    if isinstance(parameters, str):            # "all" (one name arrives as a list)
        return [n for n in dae.p_names if n not in dae.structural_parameters]
    names = list(parameters or ())
    for n in names:
        if n in dae.structural_parameters:
            raise FmuExportError(
                f"export_fmu: parameter '{n}' is structural in '{dae.name}' (baked into the FE or constraint "
                f"matrices), so the FMU cannot make it tunable: fix its value at export instead (overrides="
                f"{{'{n}': value}}, CLI --set {n}=VALUE)")
        if n not in dae.p_names:
            close = [p for p in dae.p_names if p.split(".")[0] == n.split(".")[0]][:12]
            raise UnknownNameError(f"export_fmu: '{dae.name}' has no parameter '{n}' (parameters of that "
                                   f"component: {close})")
    return names


def _builder(dae, ident, inputs, outputs, tunable, p_start, rayleigh=False):
    """The DaeBuilder of the explicit ODE (internal names ``x3``, ``u0``, ``p1``, ``y2``) and the naming plan;
    ``rayleigh``: the system's Rayleigh damping evaluated from the tunable parameters (:mod:`bscomp._fmu_damping`)."""
    w_all = ca.vertcat(dae.xds, dae.zs)
    if w_all.numel() and ca.depends_on(ca.jacobian(dae.F_sx, w_all), w_all):
        rows = [dae.eq_origin[i] for i in range(dae.F_sx.numel())
                if ca.depends_on(ca.jacobian(dae.F_sx[i], w_all), w_all)][:6]
        raise FmuExportError(
            f"export_fmu: '{dae.name}' enters its derivatives or algebraic variables nonlinearly (equations of "
            f"{rows}), e.g. a nonlinear law on a massless coordinate; the FMU needs the explicit form x' = f(x, u, "
            "p), exact only for an affine dependence. Give that coordinate a (small) mass or damper")
    b = ca.DaeBuilder(ident)
    X = [b.add(f"x{i}", {"start": float(dae.x_start[i])}) for i in range(dae.nx)]
    U = {n: b.add(f"u{k}", "input", {"start": 0.0}) for k, n in enumerate(inputs)}
    T = {n: b.add(f"p{k}", "parameter", "tunable", {"start": float(p_start[dae.p_names.index(n)])})
         for k, n in enumerate(tunable)}
    x = ca.vertcat(*X) if X else ca.MX(0, 1)
    u = ca.vertcat(*[U.get(n, ca.MX(0.0)) for n in dae.u_names]) if dae.nu else ca.MX(0, 1)
    p = ca.vertcat(*[T.get(n, ca.MX(float(v))) for n, v in zip(dae.p_names, p_start)]) if dae.np else ca.MX(0, 1)
    res, Jxd, _, Jz, _ = dae.jacobians(ca.MX.zeros(dae.nx), x, ca.MX.zeros(dae.nz), u, p)
    if rayleigh:
        res = res + rayleigh_term(dae, x, p)
    w = -ca.solve(ca.horzcat(Jxd, Jz), res, "qr") if dae.nx + dae.nz else ca.MX(0, 1)
    xd, z = w[:dae.nx], w[dae.nx:]
    y = dae.output_function(outputs)(xd, x, z, u, p) if outputs else ca.MX(0, 1)
    for i in range(dae.nx):
        b.eq(b.der(X[i]), xd[i])
    Y = []
    for j in range(len(outputs)):
        Y.append(b.add(f"y{j}", "output"))
        b.eq(Y[j], y[j])
    known = ca.vertcat(x, *U.values()) if U else x
    plan = {"inputs": inputs, "outputs": outputs, "tunable": tunable, "p_start": p_start,
            "dep_xd": _dependencies(xd, known), "dep_y": _dependencies(y, known),
            "out_syms": [dae.output_expr([o]) for o in outputs]}
    return b, plan


def _dependencies(expr, known):
    """Row -> columns of ``known`` (states, then inputs) that ``expr`` depends on (structural)."""
    if expr.numel() == 0:
        return []
    S = ca.jacobian_sparsity(expr, known)
    cols = [[] for _ in range(S.size1())]
    for r, c in zip(*S.get_triplet()):
        cols[r].append(c)
    return cols


def _describe(dae, b, plan, nominals, xml_path):
    """Rewrite CasADi's model description with public names, units and the model structure."""
    system = dae.system
    vr = b.value_reference
    x_vr = [vr(f"x{i}") for i in range(dae.nx)]
    u_vr = [vr(f"u{k}") for k in range(len(plan["inputs"]))]
    names = {n: i for i, n in enumerate(dae.x_names)}
    public = {}                                           # public name -> kind, for clash checks
    variables, derivs, initial = [], [], []
    state_vars = []
    for i, n in enumerate(dae.x_names):
        unit, desc = state_meta(dae, i)
        v = FmuVariable(structured_name(n), x_vr[i], initial="exact", start=float(dae.x_start[i]), unit=unit,
                        description=desc, nominal=float(nominals[i]))
        state_vars.append(v)
        public[v.name] = "state"
    for i, n in enumerate(dae.x_names):
        dn = derivative_name(n)
        if dn in names:                                   # the velocity state is this state's derivative
            state_vars[names[dn]].derivative = x_vr[i]
            derivs.append((x_vr[names[dn]], i))
            continue
        unit, _ = state_meta(dae, i)
        v = FmuVariable(structured_name(dn), vr(f"der(x{i})"), initial="calculated", derivative=x_vr[i],
                        unit=derivative_unit(unit), description=f"time derivative of {n}")
        variables.append(v)
        derivs.append((v.vr, i))
        public[v.name] = "derivative"
    for k, n in enumerate(plan["inputs"]):
        unit, desc = input_meta(dae, n)
        variables.append(FmuVariable(structured_name(n), u_vr[k], causality="input", start=0.0, unit=unit,
                                     description=desc))
        public[structured_name(n)] = "input"
    for k, n in enumerate(plan["tunable"]):
        unit, desc, lo, hi = parameter_meta(system, n)
        variables.append(FmuVariable(structured_name(n), vr(f"p{k}"), causality="parameter", variability="tunable",
                                     initial="exact", start=float(plan["p_start"][dae.p_names.index(n)]), unit=unit,
                                     description=desc, min=lo, max=hi))
        public[structured_name(n)] = "parameter"
    outputs = []
    for j, n in enumerate(plan["outputs"]):
        sn, e = structured_name(n), plan["out_syms"][j]
        if public.get(sn) == "state" and e.is_symbolic() and e.name() == n:
            st = state_vars[names[n]]                     # the state itself is the output
            st.causality = "output"
            outputs.append((st.vr, [names[n]]))
            continue
        if sn in public:
            raise FmuExportError(f"export_fmu: output '{n}' has the name of an FMU {public[sn]}; leave it out of "
                                 "outputs (the importer reads it there already) or rename the observable")
        unit, desc = output_meta(dae, n, e)
        v = FmuVariable(sn, vr(f"y{j}"), causality="output", initial="calculated", unit=unit, description=desc)
        variables.append(v)
        outputs.append((v.vr, plan["dep_y"][j]))
        public[sn] = "output"
    known_vr = x_vr + u_vr
    out_entries = [(v, sorted({known_vr[c] for c in cols})) for v, cols in outputs]
    der_entries = [(v, sorted({known_vr[c] for c in plan["dep_xd"][i]})) for v, i in derivs]
    initial = sorted(v.vr for v in variables if v.initial == "calculated")
    write_model_description(xml_path, state_vars + variables, out_entries, der_entries, initial,
                            description=getattr(system, "description", "") or dae.name, time_vr=TIME_VR,
                            generation_tool=f"bscomp {__version__} (CasADi {ca.__version__} DaeBuilder)")
    return np.asarray(x_vr)
