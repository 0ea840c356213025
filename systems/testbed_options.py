"""Option checks of :func:`systems.testbed.testbed`: the variants and choices it takes, the screw's
geometry options (a root diameter in metres, a positive pitch) and the motor end."""

from __future__ import annotations

from bscomp.errors import ModelDefinitionError, ParameterError, check_number

VARIANTS = ("free_screw", "screw_nut", "no_table", "full", "axial_torsional", "submodel1", "appendix_c")
_CHOICES = {"coupling": ("jaw", "bellows"), "ksn": ("full", "axial_torsional"), "nut_joint": ("point", "moving"),
            "jaw1": ("motor", "screw"), "viscous": ("motor", "guide", "none"), "drive_input": ("voltage", "torque")}


def check_choices(variant, **choices) -> None:
    """Reject an unknown variant or option of :func:`testbed`, naming the allowed values."""
    if variant not in VARIANTS:
        raise ModelDefinitionError(f"testbed: unknown variant {variant!r}; use one of {VARIANTS}")
    for name, value in choices.items():
        if value not in _CHOICES[name]:
            raise ModelDefinitionError(f"testbed: {name} must be one of {_CHOICES[name]}, got {value!r}")
    if choices["nut_joint"] == "moving" and choices["ksn"] != "full":
        raise ModelDefinitionError("testbed: nut_joint='moving' needs ksn='full' (the moving joint carries the "
                                   "whole 12x12 K_SN)")


def check_geometry(v, d_root, pitch, motor_end) -> str:
    """The motor end ("F"/"A", default the file's), checked with ``root_diameter`` in (bore, 1 m) and pitch > 0."""
    motor_end = v("screw.motor_end") if motor_end is None else motor_end
    if motor_end not in ("F", "A"):
        raise ModelDefinitionError(f"testbed: motor_end must be 'F' or 'A', got {motor_end!r}")
    bore = v("screw.sections.C.inner_diameter")
    if d_root is not None and not bore < check_number("testbed: root_diameter", d_root, error=ParameterError) < 1:
        raise ParameterError(f"testbed: root_diameter = {d_root!r} m is outside ({bore:g}, 1) m: give the thread's "
                             f"stiffness diameter in metres, above the {bore:g} m bore (Table B.1: 0.0355)")
    if pitch is not None and not check_number("testbed: pitch", pitch, error=ParameterError) > 0:
        raise ParameterError(f"testbed: pitch (lead [m] of the App C study) must be > 0, got {pitch!r}; e.g. 0.010")
    return motor_end
