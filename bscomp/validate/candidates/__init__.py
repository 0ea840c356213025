"""Candidate effects: the physical effects a model may be missing, each as a system edit with priors.

Thesis Sec 3.5.2.3-3.5.2.4 compares the test-bed model with measured FRFs and guesses what is missing:
bearing-housing mass and compliance, guideway compliance, nut-table (bolted joint) compliance, friction
and backlash "greatly amplified by the addition of the table", and a time delay from the D/A converters.
Each guess is a :class:`Candidate` here: components inserted at an **insertion point of a role** that the
drive declares in its validation interface (``system.validation``, :mod:`bscomp.kernel.interface`), with free
parameters, bounds and a physical prior, and a plain-words *signature* -- what its absence looks like in
the residuals. A drive without a point of the candidate's role (or of a kind the candidate handles)
makes it *not applicable*: :meth:`Candidate.applicable` raises :class:`~bscomp.kernel.interface.NotApplicable`
with the reason; any other failure while inserting it is an error and propagates.

A candidate is applied in two steps: :meth:`Candidate.structure` edits a copy of the system (adds the
components, at prior values) and :meth:`Candidate.overrides` maps the free parameters to component
parameters by dotted name. The fit flattens the structure once and varies only the overrides (they
stay symbolic in the Dae), so a fit costs evaluations, not re-compilations. Two effects that an
evaluation engine applies better outside the model -- an exact input delay and extra modal damping --
also say so through :meth:`Candidate.engine_hooks` (``structure(..., for_engine=True)`` then leaves
the model unchanged). Every edit is recorded (:mod:`bscomp.validate.candidates._edits`), so
:meth:`Candidate.code_lines` writes the same edit as Python lines for a system file.

Nonlinear effects (friction, backlash) are invisible to an FRF measured at large amplitude with
random or stepped-sine excitation as modelled here: their :meth:`Candidate.structure` with
``linear=True`` leaves the system unchanged, and only time series carry their evidence.

Effects at the same place stack: the nut-table joint compliance and the screw-nut backlash share the
nut--table line of the FE test bed; whichever comes second turns the element already there into a
backlash whose contact stiffness is the joint's (see :class:`ScrewNutBacklash`), in either order.
"""

from __future__ import annotations

from bscomp.validate.candidates.base import Candidate, CandidateParameter
from bscomp.validate.candidates.hooks import (
    AddedDampingOnMatrix,
    AddedModalDamping,
    AmplifierDelay,
    DetachedBodyDamping,
    ExtraDamping,
)
from bscomp.validate.candidates.losses import CouplingDamping, SupportDamping
from bscomp.validate.candidates.nonlinear import (
    V_REG,
    CompliantBacklash,
    GuidewayFriction,
    RotorFriction,
    ScrewNutBacklash,
    StribeckGuidewayFriction,
)
from bscomp.validate.candidates.structural import (
    BearingHousing,
    CouplingStiffness,
    MissingInertia,
    MissingMass,
    NutTableJoint,
    ParameterScale,
    TableSubassembly,
)

__all__ = ["CandidateParameter", "Candidate", "NutTableJoint", "TableSubassembly", "BearingHousing",
           "ParameterScale", "CouplingStiffness", "MissingInertia", "MissingMass", "GuidewayFriction",
           "StribeckGuidewayFriction", "ScrewNutBacklash", "CompliantBacklash", "AmplifierDelay", "ExtraDamping",
           "AddedModalDamping", "AddedDampingOnMatrix", "DetachedBodyDamping", "SupportDamping", "CouplingDamping",
           "RotorFriction", "default_candidates", "optional_candidates", "library", "V_REG"]


def default_candidates() -> list:
    """The library of missing effects (the thesis's Sec 3.5 guesses), in a fixed order."""
    return [NutTableJoint(), TableSubassembly(), BearingHousing(), CouplingStiffness(), MissingInertia(),
            MissingMass(), GuidewayFriction(), StribeckGuidewayFriction(), ScrewNutBacklash(), CompliantBacklash(),
            AmplifierDelay(), ExtraDamping(), SupportDamping(), CouplingDamping(), RotorFriction()]


def optional_candidates() -> list:
    """Effects measured but not in :func:`default_candidates` (each class docstring says why); none at present --
    the friction torque at the motor (:class:`RotorFriction`) was one until 2026-12-07 (``docs/validation.md``,
    "Friction that is not at the guideways")."""
    return []


def library() -> dict:
    """Every candidate by name: :func:`default_candidates`, then :func:`optional_candidates`."""
    return {c.name: c for c in default_candidates() + optional_candidates()}
