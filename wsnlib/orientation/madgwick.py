"""Madgwick's gradient-descent orientation filter, IMU and MARG forms, vectorised over batches.

Source: S. O. H. Madgwick, "An efficient orientation filter for inertial and
inertial/magnetic sensor arrays", report, University of Bristol (2010); the data-fusion
algorithm [7] of paper 001.  Equation numbers below refer to that report:

* rate of change of orientation from the gyroscope, eqs. (11)–(12):  q̇_ω = ½ q ⊗ [0, ω];
* objective function and Jacobian for gravity, eqs. (25)–(26), for the earth field,
  eqs. (29)–(30), stacked for MARG, eqs. (31)–(32); gradient ∇f = Jᵀ f, eq. (34);
* fusion, eqs. (42)–(44):  q̇_est = q̇_ω − β ∇f/‖∇f‖,  q_t = q_{t−1} + q̇_est Δt,
  then normalised;
* magnetic distortion compensation, eqs. (45)–(46):  h = q ⊗ [0, m] ⊗ q*,
  b = [0, √(h_x² + h_y²), 0, h_z].  (Many C ports, MadgwickAHRS.c among them, call this
  √(h_x² + h_y²) "_2bx" and so use half the reference field; this is the report's version.)

Gyroscope bias drift compensation (ζ, eqs. (47)–(48)) is not implemented: ζ = 0.

Frames.  The report's earth frame has x = magnetic north (horizontal) and z up, hence
y = west (NWU); the expanded f and J above are written for it.  The filter runs in NWU
internally, and quaternions are converted at the boundary with
``q_ENU = q_z(+90°) ⊗ q_NWU``, ``q_z(+90°) = [cos 45°, 0, 0, sin 45°]``, which takes north
(NWU x) onto ENU y and west (NWU y) onto ENU −x.  Inputs and outputs are ENU, as
everywhere in wsnlib.  Body-frame signals need no conversion.

Packet loss.  :func:`madgwick` feeds only received samples to the filter: on a lost sample
the estimate is held, and the next received sample is integrated over the nominal
Δt = 1/fs, since the receiver does not know how much time went by (paper 001, Sec. II).
:func:`madgwick_step` is the single update the loss-handling variants are built from.

Behaviour of the normalised gradient: each update moves the estimate by β·Δt (quaternion
units, about 2β·Δt rad) along −∇f whatever the size of ∇f, so even on perfect data the
estimate chatters around the truth, by a few times 2β·Δt rad, instead of settling on it.
Where ∇f is at rounding level (e.g. the first update after TRIAD on a repeated sample), its
direction, and so the step, depends on the last bits of the arithmetic: implementations that
agree to 1e-15 elsewhere (this one, ``ahrs``) can differ by up to β·Δt there.

Implementation.  The update is :func:`wsnlib.orientation._kernels.madgwick_update`, a
numba-compiled scalar function whose lines follow the equations above; the loop over time is
:func:`wsnlib.orientation._kernels.filter_stream`, run in parallel over the batch.
``benchmarks/bench_madgwick.py`` measures it.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import as_float_array
from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kernels as K

#: q_z(+90°): the rotation taking NWU coordinates to ENU coordinates.
Q_ENU_FROM_NWU = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])


def madgwick_step(q, gyr, acc, mag, dt, beta) -> np.ndarray:
    """One update of Madgwick's filter (eqs. (11), (25)–(34), (42)–(46)), vectorised.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Current estimates, ENU (body → earth); normalised here.
    gyr : array_like, shape (..., 3)
        Angular rate in the body frame (rad/s).
    acc : array_like, shape (..., 3)
        Specific force in the body frame (m/s²); only its direction is used.
    mag : array_like, shape (..., 3) or None
        Magnetic field in the body frame (µT); only its direction is used.  ``None`` runs
        the IMU form (gravity only).
    dt : float or array_like
        Time step (s), > 0.
    beta : float or array_like
        Gain β (rad/s), >= 0.

    Returns
    -------
    numpy.ndarray, shape (..., 4)
        Updated ENU unit quaternions; ``...`` is the broadcast of all leading dimensions.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, NaN/inf, a zero ``q``, ``acc`` or ``mag`` vector,
        ``dt <= 0``, ``beta < 0``, leading dimensions that do not broadcast, or parameters so
        extreme that the update overflows.
    """
    q = B.unit_quaternions(q, "q")
    gyr = as_float_array(gyr, "gyr", last_dim=3)
    acc = B.nonzero_vectors(acc, "acc", 3, "free fall has no gravity direction")
    shapes = {"q": q.shape[:-1], "gyr": gyr.shape[:-1], "acc": acc.shape[:-1]}
    if mag is not None:
        mag = B.nonzero_vectors(mag, "mag", 3, "a magnetometer reading needs a direction")
        shapes["mag"] = mag.shape[:-1]
    dt = as_float_array(dt, "dt", min_ndim=0)
    if np.any(dt <= 0.0):
        raise ValueError("dt must be > 0")
    beta = B.check_beta(beta)
    shapes["dt"] = dt.shape
    shapes["beta"] = beta.shape
    batch = B.broadcast_batch(shapes)

    def rows(arr, n):
        return np.ascontiguousarray(np.broadcast_to(arr, batch + (n,)).reshape(-1, n))

    out = np.empty(batch + (4,))
    use_mag = mag is not None
    K.run_step(rows(q, 4), rows(gyr, 3), rows(acc, 3), rows(mag, 3) if use_mag else np.zeros((1, 3)), use_mag,
               B.per_element(dt, batch), B.per_element(beta * dt, batch), out.reshape(-1, 4))
    if not np.all(np.isfinite(out)):
        B.raise_on_status(~np.isfinite(out).all(axis=-1).reshape(-1), batch, dt=dt, beta=beta)
    return out


def madgwick(gyr, acc, mag=None, *, fs: float, beta: float, received=None, q0=None) -> np.ndarray:
    """Madgwick's filter over whole recordings, with packet loss, batched.

    The paper's receiver: a lost sample is skipped and the previous estimate is output there.
    The loss-handling options (prediction in a gap, replay, the hybrid, paper 001's Sec. V
    methods) are :func:`wsnlib.orientation.estimate_orientation`'s.

    Parameters
    ----------
    gyr : array_like, shape (..., T, 3)
        Angular rate in the body frame (rad/s).
    acc : array_like, shape (..., T, 3)
        Specific force in the body frame (m/s², +g along earth z at rest).
    mag : array_like, shape (..., T, 3), optional
        Magnetic field in the body frame (µT).  ``None`` runs the IMU form: heading then
        comes from the gyroscope only.
    fs : float
        Sampling rate (Hz), in [1e-6, 1e9]; every received sample is integrated over
        Δt = 1/fs.
    beta : float
        Gain β (rad/s), in [0, 1e6]: the assumed gyroscope error as a quaternion rate.
    received : array_like of bool, shape (..., T), optional
        Which samples arrived.  Lost samples are never used (they may hold NaN); the
        output holds the previous estimate there.  ``None`` means all received.
    q0 : array_like, shape (4,) or (..., 4), optional
        ENU estimate before the first sample; every received sample then updates it.
        ``None``: each batch element starts at the first sample it received, from TRIAD
        (MARG form) or :func:`tilt_quaternion` (IMU form, zero heading); that sample only
        initialises, and updates start at the next one.

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth), one per sample.  ``...`` is the broadcast of
        the leading dimensions of ``gyr``, ``acc``, ``mag``, ``received`` and ``q0``
        (e.g. one ``(T, 3)`` recording with ``(100, T)`` masks gives ``(100, T, 4)``).
        Before a batch element's first received sample it holds the initial estimate.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, NaN/inf or a zero ``acc``/``mag`` vector in a received sample, a
        non-boolean ``received``, ``fs`` or ``beta`` out of range (or NaN), a zero ``q0``, a
        batch element with no received sample when ``q0`` is None, or an overflow.
    MemoryError
        At once, with the size, when the output would not fit in the memory available.

    Notes
    -----
    No gyroscope bias compensation (ζ = 0).  One compiled loop over time per batch element,
    batch elements in parallel; broadcasting copies no signal.
    """
    fs = B.check_fs(fs)
    beta = B.check_beta(beta)
    if beta.ndim:
        raise ValueError(f"beta must be one number here, got shape {beta.shape} (use estimate_orientation)")
    signals, received, q0, shapes = B.check_inputs(gyr, acc, mag, received, q0)
    batch = B.broadcast_batch(shapes)
    if q0 is None and signals["gyr"].shape[-2] == 0:
        raise ValueError("no samples (T = 0): pass q0 to define the output")
    return B.run_filter(signals, received, q0, batch, fs=fs, beta=float(beta))
