"""The inertia tensor's six entries and its physically consistent parametrisation.

The entries in :data:`~rig_identification.io.verdict.KEYS` order (ixx, ixy, ixz, iyy, iyz, izz; off-diagonals as
geometry_msgs/Inertia, the negated products of inertia), the symmetric basis that maps them
to the (3,3) tensor, and the log-Cholesky parametrisation of Wensing, Kim & Slotine (IEEE
RA-L 2017) under which every tensor is positive definite and obeys the triangle
inequalities; and the parallel-axis arithmetic (Steiner's theorem) of joining two bodies and
taking one from another.  Used by the fits (:mod:`rig_identification.estimation.gyro_fit`,
:mod:`rig_identification.estimation.rig_fit`).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

# index pairs of the six independent tensor entries
PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def basis() -> np.ndarray:
    """(6, 3, 3) symmetric basis: tensor = sum_k theta_k E_k, theta in
    :data:`~rig_identification.io.verdict.KEYS` order."""
    E = np.zeros((6, 3, 3))
    for k, (i, j) in enumerate(PAIRS):
        E[k, i, j] = E[k, j, i] = 1.0
    return E


def to_tensor(theta: ArrayLike) -> np.ndarray:
    """(6,) entries (ixx, ixy, ixz, iyy, iyz, izz) -> (3,3) symmetric tensor."""
    J: np.ndarray = np.einsum("k,kij->ij", np.asarray(theta, float), basis())
    return J


def from_tensor(J: np.ndarray) -> np.ndarray:
    """(3,3) -> (6,) entries in :data:`~rig_identification.io.verdict.KEYS` order."""
    return np.array([J[i, j] for i, j in PAIRS])


def entry_scales(theta: ArrayLike) -> np.ndarray:
    """(6,) kg·m², the order of :func:`from_tensor` (ixx, ixy, ixz, iyy, iyz, izz): the scale
    an entry's error or σ is judged on — a moment's own magnitude, the largest moment's for a
    product (issue 17: "products: of the largest diagonal").  theta: (6,) kg·m²."""
    th = np.abs(np.asarray(theta, float))
    big = max(th[0], th[3], th[5])
    return np.array([th[0], big, big, th[3], big, th[5]])


def physically_consistent(J: np.ndarray) -> bool:
    """Positive definite and obeying the triangle inequalities of the principal moments."""
    ev = np.linalg.eigvalsh(0.5 * (J + J.T))
    return bool(ev[0] > 0 and ev[0] + ev[1] >= ev[2] * (1 - 1e-9))


def consistent_from_params(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Physically consistent tensor from 6 free parameters, and d(entries)/d(theta).

    J = tr(Σ) I − Σ with the second-moment matrix Σ = ∫ρρᵀ dm = L Lᵀ (log-Cholesky: L
    lower triangular, positive diagonal exp(θ)); every J of this form is positive
    definite and obeys the triangle inequalities, and every such J has this form
    (Wensing, Kim & Slotine, "Linear matrix inequalities for physically consistent
    inertial parameter identification", IEEE RA-L 2017).  theta order: L00, L10, L11,
    L20, L21, L22.  Returns entries (6,) in :data:`~rig_identification.io.verdict.KEYS` order and the (6,6) Jacobian.
    """
    idx = ((0, 0), (1, 0), (1, 1), (2, 0), (2, 1), (2, 2))
    L = np.zeros((3, 3))
    dL = np.zeros((6, 3, 3))
    for k, (i, j) in enumerate(idx):
        if i == j:
            L[i, j] = np.exp(np.clip(theta[k], -30.0, 30.0))  # a wild LM trial step must not overflow
            dL[k, i, j] = L[i, j]
        else:
            L[i, j] = theta[k]
            dL[k, i, j] = 1.0
    S = L @ L.T
    J = np.trace(S) * np.eye(3) - S
    dS = dL @ L.T + L @ dL.transpose(0, 2, 1)
    dJ = np.trace(dS, axis1=1, axis2=2)[:, None, None] * np.eye(3) - dS
    return from_tensor(J), np.array([from_tensor(d) for d in dJ]).T


def params_from_consistent(J: np.ndarray) -> np.ndarray:
    """Inverse of :func:`consistent_from_params`; a J that is not consistent is first
    projected (eigenvalues of Σ = ½ tr(J) I − J clipped to ≥ 1e-6 of their largest)."""
    S = 0.5 * np.trace(J) * np.eye(3) - J
    ev, V = np.linalg.eigh(0.5 * (S + S.T))
    ev = np.maximum(ev, 1e-6 * max(ev.max(), 1e-12))
    L = np.linalg.cholesky(V @ np.diag(ev) @ V.T)
    return np.array([np.log(L[0, 0]), L[1, 0], np.log(L[1, 1]), L[2, 0], L[2, 1], np.log(L[2, 2])])


def parallel_axis(mass: float, offset: ArrayLike) -> np.ndarray:
    """The parallel-axis term (3, 3) kg·m² of ``mass`` kg whose CG is ``offset`` (3,) m from the
    reference point: m (|d|² I − d dᵀ) (Steiner's theorem)."""
    d = np.asarray(offset, float)
    term: np.ndarray = mass * (d @ d * np.eye(3) - np.outer(d, d))
    return term


def joined(mass: float, cg: ArrayLike, inertia: ArrayLike, part: float, part_cg: ArrayLike,
           part_inertia: ArrayLike | None = None) -> tuple[float, np.ndarray, np.ndarray]:
    """Two bodies as one: a body (``mass`` kg, ``cg`` (3,) m, ``inertia`` (3, 3) kg·m² about its CG)
    and a part (``part`` kg at ``part_cg``, its own tensor ``part_inertia`` about its CG; a point
    mass where None), in one frame.  Returns the mass, the CG c = (m c₁ + m_p c_p)/(m + m_p) and
    the tensor about c, J₁ + P(m, c₁ − c) + J_p + P(m_p, c_p − c) (:func:`parallel_axis`)."""
    c1, cp = np.asarray(cg, float), np.asarray(part_cg, float)
    m = mass + part
    c = (mass * c1 + part * cp) / m
    Jp = np.zeros((3, 3)) if part_inertia is None else np.asarray(part_inertia, float)
    return m, c, np.asarray(inertia, float) + parallel_axis(mass, c1 - c) + Jp + parallel_axis(part, cp - c)


def parted(mass: float, cg: ArrayLike, inertia: ArrayLike, part: float, part_cg: ArrayLike,
           part_inertia: ArrayLike | None = None) -> tuple[float, np.ndarray, np.ndarray]:
    """A body (``mass`` kg, ``cg`` (3,) m, ``inertia`` (3, 3) kg·m² about its CG) less a part
    (``part`` kg at ``part_cg``, its tensor ``part_inertia`` about its own CG; a point mass where
    None), in one frame: the inverse of :func:`joined`.  Returns the mass m − m_p, the CG
    c' = (m c − m_p c_p)/(m − m_p) and the tensor about c', J − J_p − P(m_p, c_p − c) − P(m − m_p, c' − c)
    (:func:`parallel_axis`, each part about the whole's CG).  Raises ValueError where m_p is not
    below m."""
    if not part < mass:
        raise ValueError(f"a part of {part} kg cannot be taken from a body of {mass} kg")
    c, p = np.asarray(cg, float), np.asarray(part_cg, float)
    rest = mass - part
    c_rest = (mass * c - part * p) / rest
    Jp = np.zeros((3, 3)) if part_inertia is None else np.asarray(part_inertia, float)
    return rest, c_rest, np.asarray(inertia, float) - Jp - parallel_axis(part, p - c) - parallel_axis(rest, c_rest - c)


def without_point_mass(mass: float, cg: ArrayLike, theta: ArrayLike, part: float, position: ArrayLike
                       ) -> tuple[float, np.ndarray, np.ndarray]:
    """A body (``mass`` kg, ``cg`` (3,) m, tensor entries ``theta`` (6,) kg·m² about it, one frame)
    less a point mass ``part`` kg at ``position`` (3,) m: :func:`parted` on the entries (6,).
    Raises ValueError where m_p is not below m."""
    rest, c_rest, J = parted(mass, cg, to_tensor(theta), part, position)
    return rest, c_rest, from_tensor(J)
