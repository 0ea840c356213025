"""Optimal-control trajectory studies (Ipopt).

* :mod:`~bscomp.optimal.problem`: the statement, :class:`Ocp` (variables, bounds, objectives, final conditions);
* :mod:`~bscomp.optimal.checks`: bad statements refused up front (parameters as signals, empty bounds, Ipopt
  options, tracking references, boundary values outside bounds, warm starts of another model);
* :mod:`~bscomp.optimal.guess`: where a solve starts (reference motion, nominals, warm starts, from a simulation);
* :mod:`~bscomp.optimal.collocation`: direct collocation (Radau IIA from ``casadi.collocation_coeff``);
* :mod:`~bscomp.optimal.coordinates` and :mod:`~bscomp.optimal.modal`: real modal coordinates of a linear
  model, the residual-vibration bound, and the modal transcription;
* :mod:`~bscomp.optimal.result`: :class:`OcpResult`, :class:`OcpError`.
"""

from bscomp.optimal.collocation import RadauScheme, radau
from bscomp.optimal.coordinates import ModalDae, ModalError
from bscomp.optimal.guess import from_simulation
from bscomp.optimal.modal import SPARSE_MODAL_NX
from bscomp.optimal.problem import Ocp
from bscomp.optimal.result import OcpError, OcpResult

__all__ = ["Ocp", "OcpResult", "OcpError", "ModalDae", "ModalError", "RadauScheme", "radau", "from_simulation",
           "SPARSE_MODAL_NX"]
