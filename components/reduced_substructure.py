r"""A CMS-reduced substructure whose interior DOF stay reachable through Modal-Acceleration recovery
(thesis Sec 5.2.3, Eq 5.10-5.18; Fig 5.9).

The thesis reduces sub-model 1 (screw, bearings, coupling, rotor; Table 5.1) to ``E + P + 1`` coordinates
``x = [d_e; q]`` (Eq 5.11-5.14) and lets the moving nut load it at *interior* DOF: the nut's force enters
the reduced model as ``Ψ^T F`` and the nut point's displacement is recovered by MA (Eq 5.18), which adds
the static effect of the interior load (``T_3 = K_ii^{-1}``) and of the inertia loads (``T_1``) to the
constraint-mode part (``T_2``):

.. math::
    M^{red} \ddot x + C^{red} \dot x + K^{red} x = \Psi_e^T F_e + \Psi_i^T F_i ,\qquad
    d_i = \varphi_{ie}\, d_e + T_{1,i}\, \ddot x + K_{ii}^{-1} F_i .

Here the interior DOF are **ports** (their potentials are quasi-static unknowns of the DAE), so any joint --
the moving screw-nut interface of Sec 5.2.2.3 (:class:`~components.moving_screw_nut.MovingScrewNut`) or a
fixed point joint -- attaches to them exactly as to the FE model's nodes, and the row ``N(z)`` of the joint
picks the MA-recovered displacement at the contact point: ``N d_i = C_x x + C_a \ddot x + D F`` with
``D = N K_ii^{-1} N^T`` (what :meth:`bscomp.linear.reduction.ReducedModel.port` computes for one row). The
static correction ``μ = K_ii^{-1} F_i`` of the interior loads is an unknown of its own (carried by unconnected
``corr_*`` ports, in the DOF's units), and with ``T_{1,i} = -K_{ii}^{-1} (M\Psi)_i`` (Eq 5.18) the whole
superelement is one sparse block over ``[x; d_i; μ]``:

.. math::
    M^{red} \ddot x + C^{red} \dot x + K^{red} x - \Psi_i^T K_{ii} \mu = F_x ,\qquad
    K_{ii} \mu = F_i ,\qquad
    d_i - \varphi_{ie} d_e - T_{1,i}\, \ddot x - \mu = 0

(``K_ii`` the FE model's banded interior stiffness, factorised once for ``T_1``). The block is *not* symmetric: MA
recovers displacements with ``T_2, T_1, T_3`` but applies forces with ``Ψ^T`` (Eq 5.14 and 5.18 are the
thesis's pair), so the coupled model is not exactly conservative; its static response at any interior DOF
equals the full model's, and its modes converge to the full model's with the number of kept modes
(``tests/components/test_reduced_substructure.py``, ``tests/systems/test_reduced_testbed.py``).

Build one with :meth:`ReducedSubstructure.from_reduction` from the full matrices and a
:class:`bscomp.linear.reduction.ReducedModel` (``cms_reduce``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bscomp.errors import ModelDefinitionError
from bscomp.kernel.component import Component, LinearStructure
from bscomp.kernel.ports import Flange, Generalized, Node6, RotFlange

from ._node_dofs import DOF_NAMES

_KINDS = {"phi": "RotFlange", "s": "Flange"}


def _split(name: str) -> tuple[str, str]:
    """``"screw.n10.w"`` -> port ``"screw_n10"``, potential ``"w"``."""
    prefix, _, pot = name.rpartition(".")
    if not prefix or not pot:
        raise ModelDefinitionError(f"ReducedSubstructure: DOF name '{name}' is not 'port.potential'")
    return prefix.replace(".", "_"), pot


class ReducedSubstructure(Component):
    """CMS superelement with MA-recovered interior ports (thesis Eq 5.10-5.18).

    Parameters
    ----------
    M_r, K_r : (m, m) array_like
        Reduced mass and stiffness ``Ψ^T M Ψ``, ``Ψ^T K Ψ`` (Eq 5.14).
    coordinates : sequence of str
        Names of the ``m`` reduced coordinates: the exterior DOF names first (``"rotor.phi"``,
        ``"screw.n23.tz"``), then the modal coordinates (``"q_rb1"``, ``"q1"``, ...).
    n_exterior : int
        Number ``E`` of exterior DOF (the first ``E`` coordinates).
    interior : sequence of str
        Names of the ``I`` interior DOF (``"screw.n10.w"``...): each becomes a port potential.
    K_ii : (I, I) sparse or array
        Interior stiffness of the unreduced structure (Eq 5.10).
    Psi_i : (I, m) array_like
        Interior rows of ``Ψ`` (``[φ_ie, χ_ip]``, Eq 5.12).
    MPsi_i : (I, m) array_like
        Interior rows of ``M Ψ`` (the inertia loads of Eq 5.16: ``T_{1,i} = -K_ii^{-1} (MΨ)_i``).
    C_r : (m, m) array_like, optional
        Reduced damping ``Ψ^T C Ψ``.
    beam : object, optional
        The FE beam the interior DOF came from (``z_nodes``, shape functions): what a
        :class:`~components.moving_screw_nut.MovingScrewNut` needs to attach to the node ports.

    Attributes
    ----------
    <port> : Node6, RotFlange or Flange
        One port per DOF prefix (``screw.n10`` -> ``screw_n10``; ``rotor`` for ``rotor.phi``); Node6 ports
        keep the potentials named in the DOF lists and pin the others.
    <modal coordinate> : Generalized
        One port per reduced coordinate (``q_rb1``, ``q1``, ...; the exterior ones tied to their physical ports),
        normally left unconnected.
    corr_<interior DOF> : Generalized
        The MA static correction ``μ = K_ii^{-1} F_i`` of each interior DOF (an unknown of the DAE, in the DOF's
        unit); leave unconnected.
    """

    def __init__(self, M_r, K_r, coordinates, n_exterior, interior, K_ii, Psi_i, MPsi_i, C_r=None, beam=None):
        super().__init__()
        self.coordinates = tuple(str(c) for c in coordinates)
        m, E, I = len(self.coordinates), int(n_exterior), len(interior)
        self.interior = tuple(str(c) for c in interior)
        mats = {"M_r": (M_r, (m, m)), "K_r": (K_r, (m, m)), "Psi_i": (Psi_i, (I, m)), "MPsi_i": (MPsi_i, (I, m)),
                "C_r": (C_r, (m, m)), "K_ii": (K_ii, (I, I))}
        self._m = {}
        for key, (A, shape) in mats.items():
            if A is None:
                self._m[key] = None
                continue
            A = A.toarray() if sp.issparse(A) else np.asarray(A, float)
            if A.shape != shape or not np.all(np.isfinite(A)):
                raise ModelDefinitionError(f"ReducedSubstructure: {key} must be a finite {shape} matrix, got "
                                           f"shape {A.shape}")
            self._m[key] = A
        if not 0 < E <= m:
            raise ModelDefinitionError(f"ReducedSubstructure: n_exterior must be in 1..{m}, got {n_exterior}")
        self.n_exterior = E
        self.beam = beam
        self.kept = {}                               # port -> kept potentials
        self.kinds = {}
        self.exterior_ports = [_split(c) for c in self.coordinates[:E]]
        for port, pot in self.exterior_ports + [_split(c) for c in self.interior]:
            self.kept.setdefault(port, [])
            if pot in self.kept[port]:
                raise ModelDefinitionError(f"ReducedSubstructure: DOF '{port}.{pot}' is named twice")
            self.kept[port].append(pot)
            kind = "Node6" if pot in DOF_NAMES else _KINDS.get(pot)
            if kind is None or self.kinds.setdefault(port, kind) != kind:
                raise ModelDefinitionError(f"ReducedSubstructure: cannot make a port of '{port}.{pot}' (Node6 "
                                           f"potentials {DOF_NAMES}, 'phi' or 's', one kind per port)")
        for port, kind in self.kinds.items():
            spec = {"Node6": Node6, "RotFlange": RotFlange, "Flange": Flange}[kind]
            self.add_port(port, spec(f"DOF {', '.join(self.kept[port])}", optional=True) if kind != "Node6"
                          else spec(f"node DOF {', '.join(self.kept[port])}"))
        self.q_ports = [c.replace(".", "_") for c in self.coordinates]
        for k, qp in enumerate(self.q_ports):
            if qp in self.kinds:
                raise ModelDefinitionError(f"ReducedSubstructure: coordinate '{self.coordinates[k]}' clashes with "
                                           "a port name")
            self.add_port(qp, Generalized(f"reduced coordinate {self.coordinates[k]}"))
        self.corr_ports = [f"corr_{c.replace('.', '_')}" for c in self.interior]
        for cp, c in zip(self.corr_ports, self.interior, strict=True):
            self.add_port(cp, Generalized(f"MA static correction of interior DOF {c} (leave unconnected)"))

    @classmethod
    def from_reduction(cls, red, M, K, dof_names, C_r=None, beam=None, M_r=None) -> "ReducedSubstructure":
        """The superelement of a :class:`bscomp.linear.reduction.ReducedModel` of ``(M, K)``.

        Parameters
        ----------
        red : ReducedModel
            From :func:`bscomp.linear.reduction.cms_reduce` of the same ``M, K`` with ``dof_names``.
        M, K : (n, n) array or sparse
            The unreduced structure.
        dof_names : sequence of str
            Names of its ``n`` DOF.
        C_r : (m, m) array_like, optional
            Reduced damping (default the ``red.C`` of the reduction, if any).
        beam : object, optional
            The FE beam of the interior nodes (see the class).
        M_r : (m, m) array_like, optional
            Reduced mass to use instead of ``red.M`` (e.g. less the inertia of a part kept outside at an
            exterior DOF, where ``Ψ`` is the identity).
        """
        Md = M.toarray() if sp.issparse(M) else np.asarray(M, float)
        Ks = sp.csr_matrix(K)
        i = np.asarray(red.interior, int)
        names = list(dof_names)
        return cls(red.M if M_r is None else M_r, red.K, red.names, red.n_exterior, [names[k] for k in i], Ks[i][:, i],
                   red.Psi[i], (Md @ red.Psi)[i], C_r=red.C if C_r is None else C_r, beam=beam)

    def beam_model(self):
        """The FE beam of the interior node ports (for joints that follow shape functions)."""
        if self.beam is None:
            raise ModelDefinitionError("ReducedSubstructure: built without a beam, so no joint can follow shape "
                                       "functions along it (pass beam= to from_reduction)")
        return self.beam

    def template_key(self):
        return (id(self),)

    def _dof(self, name):
        port, pot = _split(name)
        kind = self.kinds[port]
        return f"{port}.{pot}" if kind == "Node6" else f"{port}.{'phi' if kind == 'RotFlange' else 's'}"

    def structure(self):
        """The block of the module docstring over ``[x; d_i; μ]`` (``x``: the Generalized ports; ``μ = K_ii^{-1}
        F_i``: the static correction of MA, carried by the unconnected ``corr_*`` ports, whose balance is their
        defining row)::

            x rows:  M_r x'' + C_r x' + K_r x - Ψ_i^T K_ii μ
            d rows:  K_ii μ                                  (the load each interior port receives)
            μ rows:  d_i - φ_ie d_e - T_1,i x'' - μ           (= 0: MA recovery, Eq 5.18)

        With the correction as an unknown every reduced coordinate keeps its own inertia ``M_r`` and no row
        takes a difference of total displacements times ``K_ii`` (writing the loads as ``K_ii (d_i - φ_ie d_e)``
        left the modal rows without inertia of their own and with that cancellation: IDAS could not converge
        its Newton iterations at rtol <= 1e-8)."""
        a = self._m
        E, I = self.n_exterior, len(self.interior)
        Kii = sp.csc_matrix(a["K_ii"])
        T2 = np.zeros_like(a["Psi_i"])
        T2[:, :E] = a["Psi_i"][:, :E]                      # φ_ie on the exterior columns (Eq 5.18)
        mT1 = spla.splu(Kii).solve(a["MPsi_i"])            # -T_1,i = K_ii^{-1} (M Ψ)_i
        eye = sp.identity(I, format="csr")
        PtK = sp.csr_matrix((Kii.T @ a["Psi_i"]).T)        # Ψ_i^T K_ii
        K = sp.bmat([[a["K_r"], None, -PtK], [None, None, Kii], [-T2, eye, -eye]], format="csr")
        M = sp.bmat([[a["M_r"], None, None], [None, sp.csr_matrix((I, I)), None],
                     [mT1, None, sp.csr_matrix((I, I))]], format="csr")
        C = None
        if a["C_r"] is not None:
            C = sp.bmat([[a["C_r"], None, None], [None, sp.csr_matrix((I, I)), None],
                         [None, None, sp.csr_matrix((I, I))]], format="csr")
        dofs = ([f"{qp}.q" for qp in self.q_ports] + [self._dof(n) for n in self.interior]
                + [f"{cp}.q" for cp in self.corr_ports])
        return LinearStructure(dofs=dofs, M=M, C=C, K=K)

    def constraints(self):
        """Exterior ports move with their reduced coordinates; unused Node6 potentials are pinned."""
        cons = []
        for k, (port, pot) in enumerate(self.exterior_ports):
            p = getattr(self, port)
            cons.append(getattr(p, pot) - getattr(self, self.q_ports[k]).q)
        for port, kind in self.kinds.items():
            if kind == "Node6":
                p = getattr(self, port)
                cons += [getattr(p, d) for d in DOF_NAMES if d not in self.kept[port]]
        return cons
