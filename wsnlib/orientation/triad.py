"""Single-frame orientation from one accelerometer and one magnetometer sample.

:func:`triad` is the TRIAD algorithm of Shuster & Oh, "Three-axis attitude determination
from vector observations", J. Guidance Control 4(1):70–77 (1981), Sec. II, the
single-frame algorithm [10] of paper 001.  From the reference vectors ``V1, V2`` (earth
frame) and the observations ``W1, W2`` (body frame) it builds two orthonormal triads::

    r1 = V1/|V1|,   r2 = (V1 × V2)/|V1 × V2|,   r3 = r1 × r2
    s1 = W1/|W1|,   s2 = (W1 × W2)/|W1 × W2|,   s3 = s1 × s2

and the attitude matrix ``A = M_obs M_refᵀ = Σ s_i r_iᵀ`` (earth → body).  wsnlib
quaternions rotate body → earth, so the rotation returned here is ``Aᵀ = M_ref M_obsᵀ``.
The first pair (gravity) is matched exactly; the magnetometer only fixes the heading, so
its dip angle does not matter.  References are ENU from :mod:`wsnlib.frames`: gravity
specific force up (primary) and magnetic north dipping below the horizon (secondary).
The arithmetic is :func:`wsnlib.orientation._kernels.triad` (compiled, one sample at a
time; the tests cross-check it with scipy's ``Rotation.align_vectors``).

:func:`tilt_quaternion` is the accelerometer-only orientation with zero heading, used to
initialise the IMU (no magnetometer) form of Madgwick's filter.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import as_float_array, check_nonzero_norm
from wsnlib.orientation import _kernels as K

#: Below this |sin(angle)| between acc and mag the heading is undetermined.
_PARALLEL_SIN_TOL = K.PARALLEL_SIN_TOL
#: Above this many rows TRIAD runs in parallel.
PARALLEL_TRIAD_ROWS = 10_000


def _unit(v: np.ndarray, name: str, what: str) -> np.ndarray:
    return v / check_nonzero_norm(v, name, what)[..., None]


def unit_observations(acc, mag):
    """``acc`` and ``mag`` ``(..., 3)`` as unit vectors, and their broadcast shape: the checks every
    single-frame solver shares (``ValueError`` on shapes, NaN/inf or a zero vector, naming it)."""
    acc = as_float_array(acc, "acc", last_dim=3)
    mag = as_float_array(mag, "mag", last_dim=3)
    try:
        shape = np.broadcast_shapes(acc.shape, mag.shape)
    except ValueError as exc:
        raise ValueError(f"acc {acc.shape} and mag {mag.shape} do not broadcast") from exc
    return (_unit(acc, "acc", "free fall or a broken accelerometer has no gravity direction"),
            _unit(mag, "mag", "a magnetometer reading needs a direction"), shape)


def triad(acc, mag) -> np.ndarray:
    """Orientation from one accelerometer and one magnetometer sample (TRIAD).

    Parameters
    ----------
    acc : array_like, shape (..., 3)
        Specific force in the body frame (m/s²); only its direction is used.  At rest it
        points up, so it is matched to the ENU gravity reference ``[0, 0, +g]`` exactly.
    mag : array_like, shape (..., 3)
        Magnetic field in the body frame (µT); only its direction is used.  It fixes the
        heading (north = ENU +y).  Broadcasts against ``acc``.

    Returns
    -------
    numpy.ndarray, shape (..., 4)
        Unit quaternions ``[w, x, y, z]`` (``w >= 0``) rotating body-frame vectors into the
        ENU earth frame; ``...`` is the broadcast of the leading dimensions.  Works for
        ``(..., T, 3)`` recordings as for single samples.

    Raises
    ------
    ValueError
        If ``acc`` or ``mag`` is not ``(..., 3)``, holds NaN/inf or a zero vector, if the
        shapes do not broadcast, or if ``acc`` and ``mag`` are parallel (heading undefined).
    """
    s1, m, shape = unit_observations(acc, mag)
    sin_angle = np.linalg.norm(np.cross(s1, m), axis=-1)
    if np.any(sin_angle < _PARALLEL_SIN_TOL):
        bad = np.argwhere(sin_angle < _PARALLEL_SIN_TOL)[0]
        raise ValueError(
            f"acc and mag are parallel at index {tuple(int(i) for i in bad)}: "
            "the heading is undefined"
        )
    # Body → earth rotation R = M_ref M_obsᵀ (so that R s_i = r_i), in the compiled kernel.
    rows = [np.ascontiguousarray(np.broadcast_to(v, shape).reshape(-1, 3)) for v in (s1, m)]
    out = np.empty(shape[:-1] + (4,))
    run = K.run_triad if rows[0].shape[0] > PARALLEL_TRIAD_ROWS else K.triad_rows
    run(*rows, out.reshape(-1, 4))
    return out


def tilt_quaternion(acc) -> np.ndarray:
    """Orientation from the accelerometer alone, with zero heading.

    Heading cannot be observed from gravity.  The choice made here is the smallest
    rotation taking the measured (body-frame) up direction ``a/|a|`` onto earth up
    ``[0, 0, 1]``: its axis ``a × z`` is horizontal, so the result has no twist about
    the vertical (zero heading in the swing–twist sense; an untilted sensor gets the
    identity).  For a sensor exactly upside down (``a ∥ -z``) every horizontal axis
    is equally short; the body x axis is used, giving ``[0, 1, 0, 0]``.

    Parameters
    ----------
    acc : array_like, shape (..., 3)
        Specific force in the body frame (m/s²), e.g. ``(..., T, 3)``.

    Returns
    -------
    numpy.ndarray, shape (..., 4)
        Unit quaternions ``[w, x, y, z]`` rotating body-frame vectors into the ENU
        earth frame, ``w >= 0``.

    Raises
    ------
    ValueError
        If ``acc`` is not ``(..., 3)``, holds NaN/inf, or has a zero vector.
    """
    acc = as_float_array(acc, "acc", last_dim=3)
    a = _unit(acc, "acc", "free fall or a broken accelerometer has no gravity direction")
    ax, ay, az = np.moveaxis(a, -1, 0)
    # Rotation from unit u to unit v: normalise([1 + u·v, u × v]), here v = z.
    quat = np.stack([1.0 + az, ay, -ax, np.zeros_like(az)], axis=-1)
    norm = np.linalg.norm(quat, axis=-1, keepdims=True)
    flipped = norm == 0.0
    quat = np.where(flipped, np.array([0.0, 1.0, 0.0, 0.0]), quat)
    return quat / np.where(flipped, 1.0, norm)
