"""Paper 002's own reference positions, "manually derived" with errors of a few centimetres,
simulated from the true ones (:func:`hand_derived_reference`).

Paper 002, Sec. 4.2: there was no optoelectronic system; "true target positions have been
manually derived": each movement starts and ends at two fingerprint positions of known
coordinates, the trajectory is taken to be the arc between them, and "the users are asked to
try to perform these movements at constant speed and, therefore, physical positions of
intermediate points along the trajectories can be computed by sampling at constant rate the
arcs' points".  "Some errors are certainly introduced …, these errors tend to be limited to a
few centimeters."  The Kinect was scored against the same reference ("following the same
experimental approach").  Our simulated users move on exactly those arcs at constant speed,
so the two error sources the paper's procedure leaves are modelled:

* posture: the user's arm is off the drawn arc — a small rotation of the whole arm about the
  shoulder, one per (session, movement), rotation vector ~ N(0, σ_rot² I) (an error growing
  with the distance from the shoulder, shared by both targets);
* timing: the manual segmentation of the movement and the constant-speed assumption put the
  reference ahead of or behind the arm — one time offset per (session, movement),
  ~ N(0, σ_t²), the reference reading the trajectory at ``t + δ`` (held at the movement's ends).

σ_rot = 3° and σ_t = 0.1 s are *assumed* ("a few centimeters": at the forearm target, about
0.45 m from the shoulder, 3° is 2.4 cm per perpendicular axis; 0.1 s at the 0.2–0.4 m/s of a
2–4 s movement is 2–4 cm along the arc).  The paper gives no number.
"""

from __future__ import annotations

import math

import numpy as np

from wsnlib import fixed_order
from wsnlib._validation import as_float_array, check_nonnegative

#: Default standard deviation (°, per axis) of the posture rotation of the hand-derived reference.
REFERENCE_ROTATION_STD_DEG = 3.0

#: Default standard deviation (s) of the timing offset of the hand-derived reference.
REFERENCE_TIMING_STD_S = 0.1


def _check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def hand_derived_reference(true_positions, movement, time_s, *, rng: np.random.Generator,
                           rotation_std_deg: float = REFERENCE_ROTATION_STD_DEG,
                           timing_std_s: float = REFERENCE_TIMING_STD_S) -> np.ndarray:
    """Reference positions as paper 002 derived them by hand, from the true ones (module docstring).

    Parameters
    ----------
    true_positions : array_like, shape (n, 3) or (n, J, 3)
        True positions (m) in the shoulder frame (origin at the shoulder), rows in time order
        within each movement; ``J`` targets share each row's posture and timing errors.
    movement : array_like of int, shape (n,)
        Movement label of each row (the errors are drawn once per label; label 0 or any other
        is treated alike).
    time_s : array_like, shape (n,)
        Time of each row (s), non-decreasing within a movement; the timing offset interpolates
        the movement's own rows in time.
    rng : numpy.random.Generator
        Draws, per movement in sorted label order, the rotation vector (3) then the time offset.
        The number of draws does not depend on the standard deviations, so zero ones reproduce
        the truth with the same generator state afterwards.
    rotation_std_deg, timing_std_s : float
        Standard deviations (≥ 0) of the two error components.

    Returns
    -------
    numpy.ndarray, shape of ``true_positions``
        The reference (m).  With both standard deviations 0 it equals ``true_positions``.
    """
    rng = _check_rng(rng)
    positions = as_float_array(true_positions, "true_positions", last_dim=3)
    if positions.ndim not in (2, 3):
        raise ValueError(f"true_positions must have shape (n, 3) or (n, J, 3), got {positions.shape}")
    n = positions.shape[0]
    labels = np.asarray(movement)
    if labels.shape != (n,) or not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"movement must be integer labels of shape ({n},), got dtype {labels.dtype}, "
                         f"shape {labels.shape}")
    times = as_float_array(time_s, "time_s")
    if times.shape != (n,):
        raise ValueError(f"time_s must have shape ({n},), got {times.shape}")
    sigma_rot = math.radians(check_nonnegative(rotation_std_deg, "rotation_std_deg"))
    sigma_t = check_nonnegative(timing_std_s, "timing_std_s")
    flat = positions.reshape(n, -1, 3)
    reference = flat.copy()
    for label in np.unique(labels):
        rows = np.flatnonzero(labels == label)
        rotvec = sigma_rot * rng.standard_normal(3)
        shift = sigma_t * rng.standard_normal()
        t = times[rows]
        if np.any(np.diff(t) < 0):
            raise ValueError(f"time_s must be non-decreasing within movement {label}")
        shifted = flat[rows]
        if shift != 0.0 and rows.size > 1:
            query = np.clip(t + shift, t[0], t[-1])
            shifted = np.stack([np.stack([np.interp(query, t, flat[rows, j, d]) for d in range(3)], axis=-1)
                                for j in range(flat.shape[1])], axis=1)
        angle = float(fixed_order.norm(rotvec))
        if angle > 0.0:
            axis = rotvec / angle
            # Rodrigues' rotation of every point about the shoulder (the origin).
            cross = np.cross(axis, shifted)
            dot = np.sum(shifted * axis, axis=-1, keepdims=True)
            shifted = shifted * math.cos(angle) + cross * math.sin(angle) + axis * dot * (1.0 - math.cos(angle))
        reference[rows] = shifted
    return reference.reshape(positions.shape)
