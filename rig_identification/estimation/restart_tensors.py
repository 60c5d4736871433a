"""The tensors from which a whole-record fit's minimum is checked by restarts
(:func:`~.rig_fit.restarted`): a small shift of every entry either way (:func:`shifted`), steps
along the tensor's most weakly determined direction (:func:`along_weakest`) and per cents along
each moment of inertia where the data see it coarsely enough for a rippled valley
(:func:`along_moments`); :func:`along_valleys` gives the last two.  Each is a (6,) kg·m² tensor
about the CG, body frame, KEYS order."""
from __future__ import annotations

import numpy as np

from ..io.verdict import entry_determined
from ..model.parametrisation import entry_scales, physically_consistent, to_tensor
from .rig_problem import JointProblem, RigProblem

#: The restarts that check a fit's minimum (:func:`~.rig_fit.restarted`) move each tensor entry by this
#: share of its scale (:func:`~rig_identification.model.parametrisation.entry_scales`), the
#: signs alternating entry by entry, once each way.
RESTART_SHIFT = 0.01
#: The restarts along the tensor's most weakly determined direction go this many σ either way
#: (:func:`along_weakest`).
WEAK_RESTART_SIGMA = 10.0
#: The restarts along a valley of the likelihood move one moment of inertia by this share of its
#: scale either way (:func:`along_moments`) ...
VALLEY_SHIFT = 0.03
#: ... where that lies within this many of its σ (the Fisher information's at the estimate).
VALLEY_SIGMA = 100.0


def scaled_tensor_covariance(prob: RigProblem | JointProblem, J: np.ndarray, tensor: np.ndarray) -> np.ndarray:
    """(6, 6) the tensor entries' covariance by the inverse Fisher information of ``J`` (``prob``'s
    Jacobian at x0, weighted rows), each entry in units of its scale
    (:func:`~rig_identification.model.parametrisation.entry_scales` of ``tensor`` (6,) kg·m²)."""
    cov = np.linalg.pinv(J.T @ J, rcond=1e-13, hermitian=True)[prob.lay.inertia, prob.lay.inertia]
    unit = prob.scale[prob.lay.inertia] / entry_scales(tensor)
    scaled: np.ndarray = cov * np.outer(unit, unit)
    return scaled


def along_weakest(cov: np.ndarray, tensor: np.ndarray) -> list[np.ndarray]:
    """The tensors :data:`WEAK_RESTART_SIGMA` σ either way of ``tensor`` (6,) along the tensor's
    most weakly determined direction (``cov`` (6, 6): :func:`scaled_tensor_covariance` at
    ``tensor``): a minimum the descent stopped short of, or one beside it, lies along it."""
    w, v = np.linalg.eigh(cov)
    if not w[-1] > 0:
        return []
    step = WEAK_RESTART_SIGMA * np.sqrt(w[-1]) * v[:, -1] * entry_scales(tensor)
    return [tensor + step, tensor - step]


def along_moments(cov: np.ndarray, tensor: np.ndarray) -> list[np.ndarray]:
    """The tensors ``tensor`` (6,) kg·m² with one moment of inertia (Ixx, Iyy, Izz) moved
    :data:`VALLEY_SHIFT` of its scale either way, every other entry kept: restarts that walk a
    flat valley of the likelihood per cents, not σ.  On a rig whose data hardly tell two moments
    apart (bench_any_rig 21003: the bound 7 % at the truth) the likelihood along that valley
    ripples by a few units of χ², and each ripple's minimum is as sharp as a σ of 0.2 % (its own
    Fisher information): the restarts σ away all come back, those per cents away settle in
    another ripple at about the same χ² (:attr:`~.rig_fit.RigFit.ambiguous`).  Made only where the
    Fisher information (``cov`` (6, 6): :func:`scaled_tensor_covariance` at ``tensor``)
    determines every entry (:func:`~rig_identification.io.verdict.entry_determined`: elsewhere the
    verdict does not rest on the σ), and
    for each moment only where the shift lies within :data:`VALLEY_SIGMA` of its σ (beyond, the
    data see the moment too finely for such a valley: case 16's lie 560–1 250 σ out)."""
    std = np.sqrt(np.diag(cov))
    if not all(entry_determined(s) for s in std):
        return []
    tried = []
    for k in (0, 3, 5):
        if VALLEY_SHIFT <= VALLEY_SIGMA * std[k]:
            step = np.zeros(6)
            step[k] = VALLEY_SHIFT * entry_scales(tensor)[k]
            tried += [tensor + step, tensor - step]
    return tried


def along_valleys(prob: RigProblem | JointProblem, J: np.ndarray, tensor: np.ndarray) -> list[np.ndarray]:
    """The restarts of ``prob`` (``J`` (rows, size) its Jacobian at x0, ``tensor`` (6,) kg·m² its
    estimate) along the weakest direction (:func:`along_weakest`) and along the moments
    (:func:`along_moments`), both from one :func:`scaled_tensor_covariance`."""
    cov = scaled_tensor_covariance(prob, J, tensor)
    return along_weakest(cov, tensor) + along_moments(cov, tensor)


def shifted(x: np.ndarray, sign: float) -> np.ndarray:
    """(6,) the tensor entries of ``x`` (6,) moved by ``sign`` :data:`RESTART_SHIFT` of their scale
    (signs alternating entry by entry; halved until the tensor is physical)."""
    shift = sign * RESTART_SHIFT * entry_scales(x) * np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
    for _ in range(6):
        if physically_consistent(to_tensor(x + shift)):
            break
        shift = shift / 2
    moved: np.ndarray = x + shift
    return moved
