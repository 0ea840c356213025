"""Optimal-control trajectory studies (Ipopt): problem statement, transcription, result."""

from bscomp.optimal.problem import Ocp, OcpError, OcpResult

__all__ = ["Ocp", "OcpResult", "OcpError"]
