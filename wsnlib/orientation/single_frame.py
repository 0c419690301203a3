"""Single-frame orientation beside TRIAD: Davenport's q-method, QUEST and the SVD solution (Wahba).

Both solve Wahba's problem (G. Wahba, SIAM Review 7(3):409, 1965) for the two observations
accelerometer and magnetometer: the rotation ``R`` (body → ENU) minimising
``Σ w_i ‖r_i − R b_i‖²`` with ``b_i`` the unit observations in the body frame and ``r_i`` the
unit references in ENU (gravity up, the magnetic field of :mod:`wsnlib.frames`).  Unlike
TRIAD, which matches gravity exactly and takes only the heading from the magnetometer, they
spread the disagreement over both vectors according to the weights, so the reference dip
matters.

* :func:`davenport` — Davenport's q-method (P. B. Davenport, 1968; M. D. Shuster, S. D. Oh,
  J. Guidance Control 4(1):70–77, 1981, Sec. III): ``B = Σ w_i r_i b_iᵀ``, ``S = B + Bᵀ``,
  ``σ = tr B``, ``z = [B_23 − B_32, B_31 − B_13, B_12 − B_21]``,
  ``K = [[σ, zᵀ], [z, S − σ I]]``; the optimal quaternion is the eigenvector of ``K`` of
  largest eigenvalue.  Vectorised over samples (``numpy.linalg.eigh``).
* :func:`quest` — QUEST (Shuster & Oh 1981, Sec. IV): the same eigenvector without an
  eigen-decomposition.  The largest eigenvalue λ of ``K`` is the root near ``Σ w_i`` of
  its characteristic polynomial, eq. (70),
  ``λ⁴ − (a + b)λ² − cλ + (ab + cσ − d) = 0`` with ``a = σ² − κ``, ``b = σ² + zᵀz``,
  ``c = Δ + zᵀSz``, ``d = zᵀS²z``, ``κ = tr adj S``, ``Δ = det S``, found by Newton's
  method from ``λ₀ = Σ w_i`` (exact on noise-free data); then, with ``M = (λ + σ)I − S``,
  ``q ∝ [det M, adj(M) z]`` (eqs. (66)–(68), the Gibbs vector ``M⁻¹z`` times ``det M``).
  This degenerates for rotations near 180° (``det M → 0``), so it is also solved with the
  references turned by 180° about x, y and z (Shuster & Oh's "method of sequential
  rotations") and the best-conditioned of the four solutions is kept.
* :func:`svd_single_frame` — the SVD solution (F. L. Markley, J. Astronaut. Sci. 36(3), 1988)
  through :meth:`scipy.spatial.transform.Rotation.align_vectors` with weights, one call per
  sample (a reference, not fast).

Same signature and output as :func:`wsnlib.orientation.triad`: ``(..., 3)`` → ``(..., 4)``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from wsnlib import fixed_order, frames
from wsnlib._validation import check_positive
from wsnlib.orientation.triad import unit_observations
from wsnlib.quaternion import canonical, conjugate, from_scipy, multiply

#: Default weights (accelerometer, magnetometer): gravity's direction is far more reliable than
#: the field's dip indoors, so it dominates the tilt, while the magnetometer still sets heading.
DEFAULT_WEIGHTS = (1.0, 0.1)


def _observations(acc, mag, weights):
    b_acc, b_mag, shape = unit_observations(acc, mag)
    if len(weights) != 2:
        raise ValueError(f"weights must be two numbers (acc, mag), got {weights!r}")
    w = (check_positive(weights[0], "weights[0]"), check_positive(weights[1], "weights[1]"))
    r_acc = np.array([0.0, 0.0, 1.0])
    field = frames.magnetic_field_enu()
    r_mag = field / fixed_order.norm(field)
    return np.broadcast_to(b_acc, shape), np.broadcast_to(b_mag, shape), r_acc, r_mag, w, shape


def davenport(acc, mag, *, weights=DEFAULT_WEIGHTS) -> np.ndarray:
    """Orientation from one accelerometer and one magnetometer sample by Davenport's q-method.

    Parameters
    ----------
    acc, mag : array_like, shape (..., 3)
        Specific force (m/s²) and magnetic field (µT) in the body frame; only directions are
        used.  They broadcast.
    weights : (float, float)
        Weights of the accelerometer and magnetometer observations, > 0.

    Returns
    -------
    numpy.ndarray, shape (..., 4)
        Unit quaternions ``[w, x, y, z]`` (``w >= 0``), body → ENU.

    Raises
    ------
    ValueError
        Wrong shapes, NaN/inf or zero vectors, non-positive weights.
    """
    b_acc, b_mag, r_acc, r_mag, w, shape = _observations(acc, mag, weights)
    # B = Σ w_i r_i b_iᵀ  (earth ← body), so that the optimum R maximises tr(Rᵀ B).
    B = _attitude_profile(r_acc, r_mag, b_acc, b_mag, w)
    sigma, S, z = _sigma_s_z(B)
    K = np.empty(shape[:-1] + (4, 4))
    K[..., 0, 0] = sigma
    K[..., 0, 1:] = z
    K[..., 1:, 0] = z
    K[..., 1:, 1:] = S - sigma[..., None, None] * np.eye(3)
    _, vectors = np.linalg.eigh(K)
    return canonical(vectors[..., :, -1])  # eigenvalues ascending: the last is the largest


#: Newton steps of QUEST's characteristic equation: quadratic convergence from Σ w_i reaches
#: double precision within a few steps for any two observations; extra steps change nothing.
QUEST_NEWTON_STEPS = 8


def _attitude_profile(r_acc, r_mag, b_acc, b_mag, w):
    """``B = Σ w_i r_i b_iᵀ`` (earth ← body), shape ``(..., 3, 3)``."""
    return w[0] * r_acc[:, None] * b_acc[..., None, :] + w[1] * r_mag[:, None] * b_mag[..., None, :]


def _sigma_s_z(B):
    """Davenport's ``σ = tr B``, ``S = B + Bᵀ``, ``z = [B_23 − B_32, B_31 − B_13, B_12 − B_21]``."""
    sigma = np.trace(B, axis1=-2, axis2=-1)
    S = B + np.swapaxes(B, -1, -2)
    z = np.stack([B[..., 2, 1] - B[..., 1, 2], B[..., 0, 2] - B[..., 2, 0], B[..., 1, 0] - B[..., 0, 1]], axis=-1)
    return sigma, S, z


def _quest_unnormalised(B, lam):
    """``[det M, adj(M) z]`` with ``M = (λ + σ)I − S`` (QUEST's optimal quaternion × ``det M``)."""
    sigma, S, z = _sigma_s_z(B)
    M = (lam + sigma)[..., None, None] * np.eye(3) - S
    m0, m1, m2 = M[..., 0, :], M[..., 1, :], M[..., 2, :]
    # adj(M) has the columns m1 × m2, m2 × m0, m0 × m1 (rows m_i of M), det M = m0 · (m1 × m2).
    c12, c20, c01 = np.cross(m1, m2), np.cross(m2, m0), np.cross(m0, m1)
    vector = c12 * z[..., 0:1] + c20 * z[..., 1:2] + c01 * z[..., 2:3]
    return np.concatenate([np.sum(m0 * c12, axis=-1, keepdims=True), vector], axis=-1)


def quest(acc, mag, *, weights=DEFAULT_WEIGHTS) -> np.ndarray:
    """Orientation from one accelerometer and one magnetometer sample by QUEST.

    Same parameters, return value and errors as :func:`davenport`, to which it is equal up
    to rounding (the same eigenvector of ``K``, module docstring).
    """
    b_acc, b_mag, r_acc, r_mag, w, shape = _observations(acc, mag, weights)
    B = _attitude_profile(r_acc, r_mag, b_acc, b_mag, w)
    sigma, S, z = _sigma_s_z(B)
    # Eq. (70): coefficients of the characteristic polynomial, then Newton from λ₀ = Σ w_i.
    adj_trace = (S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] * S[..., 1, 0] + S[..., 0, 0] * S[..., 2, 2]
                 - S[..., 0, 2] * S[..., 2, 0] + S[..., 1, 1] * S[..., 2, 2] - S[..., 1, 2] * S[..., 2, 1])
    Sz = np.einsum("...ij,...j->...i", S, z)
    a = sigma**2 - adj_trace
    b = sigma**2 + np.sum(z * z, axis=-1)
    c = np.linalg.det(S) + np.sum(z * Sz, axis=-1)
    d = np.sum(Sz * Sz, axis=-1)
    lam = np.full(shape[:-1], w[0] + w[1])
    for _ in range(QUEST_NEWTON_STEPS):
        f = lam**4 - (a + b) * lam**2 - c * lam + (a * b + c * sigma - d)
        slope = 4.0 * lam**3 - 2.0 * (a + b) * lam - c
        lam = lam - np.divide(f, slope, out=np.zeros_like(f), where=slope != 0.0)
    # Method of sequential rotations: references turned by 180° about none, x, y, z
    # (B → T B, T = diag(±1)); the solution q' of the turned problem gives q = [0, e]* ⊗ q'.
    # [det M, adj(M) z] is the first column of adj(λI − K) = c q qᵀ, c the same in every turned
    # frame, so |det M| = |c| q₀² is largest for the turned problem farthest from 180°.
    best, best_score = None, None
    for axis in (None, 0, 1, 2):
        turn = np.ones(3) if axis is None else -np.ones(3)
        if axis is not None:
            turn[axis] = 1.0
        raw = _quest_unnormalised(turn[:, None] * B, lam)
        norm = np.maximum(np.linalg.norm(raw, axis=-1), np.finfo(float).tiny)
        q, score = raw / norm[..., None], np.abs(raw[..., 0])
        if axis is not None:
            q_turn = np.zeros(4)
            q_turn[1 + axis] = 1.0
            q = multiply(conjugate(q_turn), q)
        if best is None:
            best, best_score = q, score
        else:
            better = score > best_score
            best = np.where(better[..., None], q, best)
            best_score = np.where(better, score, best_score)
    return canonical(best)


def svd_single_frame(acc, mag, *, weights=DEFAULT_WEIGHTS) -> np.ndarray:
    """Orientation by the SVD solution of Wahba's problem (``Rotation.align_vectors``).

    Same parameters, return value and errors as :func:`davenport`, to which it is equal up
    to rounding (two solutions of the same problem).
    """
    b_acc, b_mag, r_acc, r_mag, w, shape = _observations(acc, mag, weights)
    flat_acc, flat_mag = b_acc.reshape(-1, 3), b_mag.reshape(-1, 3)
    refs = np.stack([r_acc, r_mag])
    out = np.empty((flat_acc.shape[0], 4))
    for i in range(flat_acc.shape[0]):
        rotation, _ = Rotation.align_vectors(refs, np.stack([flat_acc[i], flat_mag[i]]), weights=w)
        out[i] = from_scipy(rotation)
    return canonical(out.reshape(shape[:-1] + (4,)))
