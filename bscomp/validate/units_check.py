"""A measurement's units against the model's declared ones, where the data meet the model.

The readers (:mod:`bscomp.validate.readers`) convert every value to SI and check what a file alone can tell
(a channel named ``table.a`` is in m/s^2 by the Modelica naming convention). A channel with no such suffix
(``amp.u``) gets its unit from the model: :func:`check_units` compares the SI unit of every FRF pair, time
channel and stated excitation amplitude with the units the model declares for its input and output
(:func:`bscomp.kernel.signal_meta.unit_of`: ``V`` for the amplifier's ``amp.u``). A prefixed unit of the
right dimension (``mm/V`` for a table position per volt) was converted on reading; a unit of another
dimension (``mm/V`` for a motor speed per volt, ``N`` for a voltage) is a
:class:`~bscomp.validate.datasets.MeasurementFileError` naming the file, the line and the unit expected.
"""

from __future__ import annotations

import numpy as np

from bscomp.kernel.signal_meta import unit_of
from bscomp.kernel.units import UnitSyntaxError, parse_unit
from bscomp.validate.datasets import FrfData, MeasurementFileError

__all__ = ["check_units"]


def _model_unit(dae, name):
    """The model's declared unit of signal ``name`` (text, parsed), or None when it declares none."""
    try:
        text = unit_of(dae, name)
    except (AttributeError, KeyError, ValueError, TypeError):
        return None
    if not text:
        return None
    try:
        return text, parse_unit(text)
    except UnitSyntaxError:
        return None


def _dims(text):
    try:
        return np.array(parse_unit(text).dims[:4], float)
    except UnitSyntaxError:
        return None


def _fail(data, key, name, message):
    ln, col = data.locations.get(key, (None, None))
    raise MeasurementFileError(data.label, ln, col, message, name)


def check_units(dae, data) -> None:
    """Every unit of ``data`` must have the dimension the model ``dae`` declares (see the module notes)."""
    model = getattr(dae, "name", "the model")
    if isinstance(data, FrfData):
        for (inp, out), si in (data.units or {}).items():
            mi, mo, have = _model_unit(dae, inp), _model_unit(dae, out), _dims(si)
            if mi is None or mo is None or have is None:
                continue
            want = np.array(mo[1].dims[:4]) - np.array(mi[1].dims[:4])
            if not np.allclose(have, want):
                _fail(data, ("unit", (inp, out)), f"{out}/{inp}",
                      f"unit {si!r} (in SI) of {out}/{inp} does not fit model '{model}': there {out} is in "
                      f"{mo[0]} and {inp} in {mi[0]}, so the response is in {mo[0]}/({mi[0]}) (a prefixed form "
                      "such as mm for m is converted): fix the '# unit' line")
        for inp, si in (getattr(data, "excitation_units", None) or {}).items():
            mi, have = _model_unit(dae, inp), _dims(si)
            if mi is not None and have is not None and not np.allclose(have, mi[1].dims[:4]):
                _fail(data, ("excitation", inp), inp, f"excitation of {inp} in {si!r}, but model '{model}' takes "
                      f"{inp} in {mi[0]}: state the sine's amplitude in {mi[0]} (or a prefixed form, e.g. m{mi[0]})")
        return
    for name, si in (data.units or {}).items():
        m, have = _model_unit(dae, name), _dims(si)
        if m is not None and have is not None and not np.allclose(have, m[1].dims[:4]):
            role = "input" if name in data.inputs else "output"
            _fail(data, ("unit", name), name, f"unit {si!r} (in SI) of the {role} {name} does not fit model "
                  f"'{model}', which has it in {m[0]} (a prefixed form such as m{m[0]} is converted): fix the "
                  f"'# {role}' or '# unit' line")
