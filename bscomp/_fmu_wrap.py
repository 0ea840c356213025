"""Patches to CasADi's generated FMI 3.0 wrapper: state nominals, checked value references, restarts.

CasADi 3.8.2 writes the FMU's C wrapper (``sources/<id>_wrap.c``) from a template. Four things in it stand
between a bscomp FMU and an importer that follows the standard to the letter; :func:`patch_wrapper`
rewrites them before the source is compiled.

* **Nominals.** ``fmi3GetNominalsOfContinuousStates`` answers 1 for every state, whatever ``nominal`` the
  builder was given. Importers scale their error control by it (FMPy's and ``fmusim``'s CVode: ``atol_i =
  rtol * nominal_i``; FMI 3.0 suggests ``0.01 rtol nominal_i``), so at ``rtol = 1e-8`` they allowed 1e-8 m
  of error on micrometre elastic deflections. The patched function returns the nominals of
  :func:`state_nominals`. **Principle:** every state's nominal is the ratio ``atol / rtol`` of
  :func:`bscomp.simulate`'s defaults (1e-9 / 1e-6 = 1e-3, in the state's SI unit), so that an importer at
  relative tolerance ``r`` controls each state's error as ``bscomp.simulate(rtol=r)`` does.
* **Value references.** ``fmi3Get/SetFloat64`` and the directional derivatives index CasADi's
  ``var_offset`` table with any value reference they are given; the independent variable ``time``
  (value reference 4294967295, CasADi's) is not in it. The Modelica Association's reference importer
  ``fmusim`` samples every variable, ``time`` included, and crashed with a segmentation fault. Every
  lookup is now bounds-checked (``fmi3Error``), and ``fmi3GetFloat64`` of ``time`` returns the time set.
* **Restart at an input jump.** ``fmi3UpdateDiscreteStates`` reports ``valuesOfContinuousStatesChanged``
  only after a state event. An importer that restarts its integrator only on that flag (``fmusim``) then
  carries CVODE's history, integrated past the event with the old input, across a jump of a square-wave
  input: it applied the new input ~0.1 ms late, 10-20 % errors on the small drive. The patched FMU reports
  the flag after an Event Mode in which an input or a tunable parameter changed its value (the states
  read back are unchanged), so such importers restart there, as FMPy always does.
* ``fmi3CompletedIntegratorStep`` left its two output flags unwritten; they are set to false.

Each edit is anchored on the exact template text and counted: a wrapper that does not look like the
CasADi 3.8 template is refused with :class:`~bscomp.errors.FmuExportError` instead of patched by guess.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from bscomp.errors import FmuExportError, UnknownNameError
from bscomp.simulation.common import SimulationOptions

__all__ = ["DEFAULT_NOMINAL", "TIME_VR", "state_nominals", "patch_wrapper"]

#: The nominal of every state unless told otherwise: ``atol / rtol`` of ``bscomp.simulate``'s defaults.
DEFAULT_NOMINAL = SimulationOptions.atol / SimulationOptions.rtol
#: Value reference of the independent variable ``time`` (the one CasADi's description gives it).
TIME_VR = 4294967295

_NOMINALS = re.compile(r"(FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates\(fmi3Instance instance,\s*"
                       r"fmi3Float64 nominals\[\], size_t nContinuousStates\) \{\n)(?P<body>.*?)(\n\}\n)", re.S)
_ALL_ONES = "for (i = 0; i < nContinuousStates; ++i) nominals[i] = 1;"
_XVR = re.compile(r"fmi3ValueReference x_vr\[N_X\] = \{(?P<list>[^}]*)\};")
_GET64 = re.compile(r"FMI3_Export fmi3Status fmi3GetFloat64\(.*?\n\}\n", re.S)
_LOOKUP = "\n    var_off = var_offset[vr];\n"
_CHECK = "\n    if (vr >= N_VAR) return fmi3Error;  /* bscomp: unknown value reference */"
_TIME = (f"\n    if (vr == {TIME_VR}u) {{  /* bscomp: the independent variable */\n"
         "      if (val_ind >= nValues) return fmi3Fatal;\n      values[val_ind++] = m->t;\n      continue;\n    }")
_SET_COPY = "    for (j = 0; j < var_sz; ++j) m->v[var_off + j] = values[val_ind++];\n"
_KNOB = """/* bscomp: a value the importer may change in Event Mode (an input or a tunable parameter)? */
static int bscomp_is_knob(fmi3ValueReference vr) {
  size_t k;
  for (k = 0; k < N_U; ++k) if (u_vr[k] == vr) return 1;
  for (k = 0; k < N_P; ++k) if (p_vr[k] == vr) return 1;
  return 0;
}
"""
#: (what, template text, replacement): each template text must occur exactly once
_EDITS = (
    ("the memory struct's continuous_states_changed", "  int continuous_states_changed;\n",
     "  int continuous_states_changed;\n  int bscomp_event_mode;  /* bscomp: in Event Mode */\n"
     "  int bscomp_input_changed;  /* bscomp: an input or parameter changed its value in Event Mode */\n"),
    ("the reset of continuous_states_changed", "  m->continuous_states_changed = 0;\n  // Do not permit",
     "  m->continuous_states_changed = 0;\n  m->bscomp_event_mode = 0;\n  m->bscomp_input_changed = 0;\n"
     "  // Do not permit"),
    ("fmi3EnterEventMode", "FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {\n",
     "FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {\n"
     "  ((casadi_fmi_memory*)instance)->bscomp_event_mode = 1;  /* bscomp */\n"),
    ("fmi3EnterContinuousTimeMode", "FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {\n",
     "FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {\n"
     "  ((casadi_fmi_memory*)instance)->bscomp_event_mode = 0;  /* bscomp */\n"),
    ("fmi3UpdateDiscreteStates' valuesOfContinuousStatesChanged",
     "  *valuesOfContinuousStatesChanged = m->continuous_states_changed ? fmi3True : fmi3False;\n",
     "  /* bscomp: also after an input jump, so that the importer restarts its integrator there */\n"
     "  *valuesOfContinuousStatesChanged = (m->continuous_states_changed || m->bscomp_input_changed) ? fmi3True"
     " : fmi3False;\n  m->bscomp_input_changed = 0;\n"),
    ("fmi3CompletedIntegratorStep",
     "  // We should not need this as there are no internal iterations\n  return fmi3OK;",
     "  (void)instance;\n  (void)noSetFMUStatePriorToCurrentPoint;\n"
     "  if (enterEventMode) *enterEventMode = fmi3False;  /* bscomp: outputs set */\n"
     "  if (terminateSimulation) *terminateSimulation = fmi3False;\n  return fmi3OK;"),
    ("fmi3SetFloat64", "FMI3_Export fmi3Status fmi3SetFloat64(\n", _KNOB + "FMI3_Export fmi3Status fmi3SetFloat64(\n"),
    ("fmi3SetFloat64's copy loop", _SET_COPY,
     "    if (m->bscomp_event_mode && bscomp_is_knob(vr)) for (j = 0; j < var_sz; ++j)\n"
     "      if (m->v[var_off + j] != values[val_ind + j]) m->bscomp_input_changed = 1;  /* bscomp */\n" + _SET_COPY),
)


def state_nominals(x_names, nominal=None) -> np.ndarray:
    """The nominal of each state: ``nominal`` a positive float (every state), a dict ``{state name: value}``
    (the others at :data:`DEFAULT_NOMINAL`), or None (all at :data:`DEFAULT_NOMINAL`).

    Raises
    ------
    FmuExportError
        A value that is not a positive finite number.
    UnknownNameError
        A dict key that is not a state.
    """
    x_names = list(x_names)
    values = dict(nominal) if isinstance(nominal, dict) else {}
    scalar = DEFAULT_NOMINAL if nominal is None or isinstance(nominal, dict) else nominal
    out = np.full(len(x_names), _positive("nominal", scalar))
    index = {n: i for i, n in enumerate(x_names)}
    for name, v in values.items():
        if name not in index:
            raise UnknownNameError(f"export_fmu: nominal given for '{name}', which is not a state; states: "
                                   f"{x_names[:8]}...")
        out[index[name]] = _positive(f"nominal['{name}']", v)
    return out


def _positive(what, v) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        f = float("nan")
    if not (np.isfinite(f) and f > 0):
        raise FmuExportError(f"export_fmu: {what} must be a positive finite number, got {v!r}")
    return f


def patch_wrapper(wrap_c: Path, x_vr, nominals) -> None:
    """Patch CasADi's wrapper source ``wrap_c`` in place (see the module docstring).

    ``x_vr`` are the value references of the states in the order of ``nominals``; they must be the
    wrapper's own state order (its ``x_vr`` array), which is checked.

    Raises
    ------
    FmuExportError
        The wrapper is not the CasADi 3.8 template these patches were written for (a piece of template text
        missing or repeated, or another state order).
    """
    wrap_c = Path(wrap_c)

    def changed(what):
        return FmuExportError(f"export_fmu: CasADi's generated FMU wrapper ({wrap_c.name}) is not the template "
                              f"bscomp patches ({what} not found as expected); bscomp's patches are written for "
                              "CasADi 3.8.x: pin casadi==3.8.2 or report the CasADi version")

    if not wrap_c.is_file():
        raise changed("the wrapper source file")
    text = _patch_nominals(wrap_c.read_text(), x_vr, nominals, changed)
    for what, old, new in _EDITS:
        if text.count(old) != 1:
            raise changed(what)
        text = text.replace(old, new)
    wrap_c.write_text(_patch_lookups(text, changed))


def _patch_lookups(text, changed):
    """Bounds-check every ``var_offset[vr]``; ``fmi3GetFloat64`` returns the time for :data:`TIME_VR`."""
    get64 = _GET64.findall(text)
    if len(get64) != 1 or get64[0].count(_LOOKUP) != 1 or text.count(_LOOKUP) < 2:
        raise changed("the value-reference lookups 'var_off = var_offset[vr];' of fmi3Get/SetFloat64")
    start = text.index(get64[0])
    before, after = text[:start], text[start + len(get64[0]):]
    body = get64[0].replace(_LOOKUP, _TIME + _CHECK + _LOOKUP)
    return before.replace(_LOOKUP, _CHECK + _LOOKUP) + body + after.replace(_LOOKUP, _CHECK + _LOOKUP)


def _patch_nominals(text, x_vr, nominals, changed):
    funcs = _NOMINALS.findall(text)
    m_vr = _XVR.search(text)
    if len(funcs) != 1 or _ALL_ONES not in funcs[0][1]:
        raise changed("fmi3GetNominalsOfContinuousStates with a body setting every nominal to 1")
    if m_vr is None:
        raise changed("the x_vr array of the states")
    wrapper_vr = [int(s) for s in m_vr["list"].replace(" ", "").split(",") if s]
    if wrapper_vr != [int(v) for v in x_vr] or len(nominals) != len(wrapper_vr):
        raise changed("the states in the order they were added")
    if not len(nominals):
        return text
    values = ", ".join(f"{float(v):.17e}" for v in nominals)
    body = (f"  /* patched by bscomp: nominals of the states, in x_vr order (bscomp/_fmu_wrap.py) */\n"
            f"  static const fmi3Float64 bscomp_x_nominal[N_X] = {{{values}}};\n"
            "  size_t i;\n"
            "  (void)instance;\n"
            "  if (nContinuousStates > N_X) return fmi3Error;\n"
            "  for (i = 0; i < nContinuousStates; ++i) nominals[i] = bscomp_x_nominal[i];\n"
            "  return fmi3OK;")
    return _NOMINALS.sub(lambda m: m.group(1) + body + m.group(3), text, count=1)
