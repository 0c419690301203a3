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
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import as_float_array, check_nonnegative, check_nonzero_norm, check_positive
from wsnlib.orientation.triad import tilt_quaternion, triad
from wsnlib.quaternion import multiply

#: q_z(+90°): the rotation taking NWU coordinates to ENU coordinates.
Q_ENU_FROM_NWU = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])

# p ⊗ q is linear in q; row j of this matrix is p ⊗ e_j, so that for row vectors
# q_enu = q_nwu @ _TO_ENU and, the matrix being orthogonal, q_nwu = q_enu @ _TO_ENU.T.
_TO_ENU = multiply(Q_ENU_FROM_NWU, np.eye(4))
_TO_NWU = np.ascontiguousarray(_TO_ENU.T)


def _gradient(q_nwu, acc, mag):
    """Half the objective-function gradient ½ Jᵀ f (eqs. (25)-(34), (45)-(46)).

    Component axis first: ``q_nwu`` unit ``(4, ...)`` in the report's NWU frame, ``acc`` and
    ``mag`` unit vectors ``(3, ...)`` (``mag=None``: gravity only).  Returns the four
    components.  The common factor 2 of J is dropped: only the direction of ∇f is used
    (eq. (44)).
    """
    qw, qx, qy, qz = q_nwu
    ax, ay, az = acc

    # Rotation matrix R (body → NWU) of q; its rows give q* ⊗ d ⊗ q for the references.
    xx, yy, zz = qx * qx, qy * qy, qz * qz
    xy, xz, yz = qx * qy, qx * qz, qy * qz
    wx, wy, wz = qw * qx, qw * qy, qw * qz
    r11 = 0.5 - yy - zz  # R / 2, entry by entry
    r12, r13 = xy - wz, xz + wy
    r31, r32 = xz - wy, yz + wx
    r33 = 0.5 - xx - yy

    # Eqs. (25)-(26), (34): f_g = q* ⊗ [0, 0, 0, 1] ⊗ q - a and ∇f = J_gᵀ f_g.
    f1 = 2.0 * r31 - ax
    f2 = 2.0 * r32 - ay
    f3 = 2.0 * r33 - az
    grad_w = qx * f2 - qy * f1
    grad_x = qz * f1 + qw * f2 - 2.0 * qx * f3
    grad_y = qz * f2 - qw * f1 - 2.0 * qy * f3
    grad_z = qx * f1 + qy * f2

    if mag is not None:
        mx, my, mz = mag
        # Eq. (45): h = q ⊗ [0, m] ⊗ q* = R m (only h_x, h_y, h_z needed).
        hx = 2.0 * (r11 * mx + r12 * my + r13 * mz)
        hy = 2.0 * ((xy + wz) * mx + (0.5 - xx - zz) * my + (yz - wx) * mz)
        hz = 2.0 * (r31 * mx + r32 * my + r33 * mz)
        # Eq. (46): b = [0, √(h_x² + h_y²), 0, h_z].
        bx = np.hypot(hx, hy)
        bz = hz
        # Eq. (29): f_b = q* ⊗ [0, b_x, 0, b_z] ⊗ q - m.
        f4 = 2.0 * (bx * r11 + bz * r31) - mx
        f5 = 2.0 * (bx * r12 + bz * r32) - my
        f6 = 2.0 * (bx * r13 + bz * r33) - mz
        # Eqs. (30), (32), (34): add J_bᵀ f_b (halved like J_g; not in place, since mag may
        # widen the batch).
        grad_w = grad_w + bx * (qy * f6 - qz * f5) + bz * (qx * f5 - qy * f4)
        grad_x = grad_x + bx * (qy * f5 + qz * f6) + bz * (qz * f4 + qw * f5 - 2.0 * qx * f6)
        grad_y = grad_y + bx * (qx * f5 + qw * f6 - 2.0 * qy * f4) + bz * (
            qz * f5 - qw * f4 - 2.0 * qy * f6
        )
        grad_z = grad_z + bx * (qx * f6 - qw * f5 - 2.0 * qz * f4) + bz * (qx * f4 + qy * f5)
    return grad_w, grad_x, grad_y, grad_z


def _update(q, gyr, acc, mag, dt, beta_dt) -> np.ndarray:
    """One filter update, no validation, component axis FIRST (the hot loop).

    ``q``: ENU unit quaternions ``(4, ...)``; ``gyr`` (rad/s), ``acc`` and ``mag`` (unit
    vectors) ``(3, ...)``, ``mag=None`` for the IMU form; ``dt`` (s) and ``beta_dt = β·Δt``
    scalars or arrays broadcasting over ``...``.  Returns ENU unit quaternions ``(4, ...)``.
    Component-first arrays keep every operand contiguous, which makes a step several times
    faster than slicing ``(..., 4)`` arrays; products are written out for the same reason
    instead of calling :mod:`wsnlib.quaternion`.  All inputs must be finite.
    """
    q_nwu = np.tensordot(_TO_NWU, q, axes=(0, 0))  # q_NWU = q_z(+90°)* ⊗ q_ENU
    qw, qx, qy, qz = q_nwu
    gx, gy, gz = gyr
    grad_w, grad_x, grad_y, grad_z = _gradient(q_nwu, acc, mag)

    # Eq. (44): unit gradient.  At an exact optimum ∇f = 0 has no direction: no correction.
    grad_norm = np.sqrt(grad_w * grad_w + grad_x * grad_x + grad_y * grad_y + grad_z * grad_z)
    step = beta_dt * np.divide(
        1.0, grad_norm, out=np.zeros_like(grad_norm), where=grad_norm > 0.0
    )
    # Eqs. (11), (42)-(43): q + (½ q ⊗ [0, ω] - β ∇f/‖∇f‖) Δt, the product written out.
    half_dt = 0.5 * dt
    q_new = np.stack(
        [
            qw - half_dt * (qx * gx + qy * gy + qz * gz) - step * grad_w,
            qx + half_dt * (qw * gx + qy * gz - qz * gy) - step * grad_x,
            qy + half_dt * (qw * gy - qx * gz + qz * gx) - step * grad_y,
            qz + half_dt * (qw * gz + qx * gy - qy * gx) - step * grad_z,
        ]
    )
    q_new /= np.sqrt(np.einsum("i...,i...->...", q_new, q_new))
    return np.tensordot(_TO_ENU, q_new, axes=(0, 0))


def _step(q, gyr, acc, mag, dt, beta_dt) -> np.ndarray:
    """:func:`_update` for ``(..., 4)`` / ``(..., 3)`` arrays (component axis last)."""
    first = [np.moveaxis(np.asarray(x, dtype=float), -1, 0) for x in (q, gyr, acc)]
    mag = None if mag is None else np.moveaxis(np.asarray(mag, dtype=float), -1, 0)
    return np.moveaxis(_update(*first, mag, dt, beta_dt), 0, -1)


def _broadcast_batch(shapes: dict[str, tuple[int, ...]]) -> tuple[int, ...]:
    try:
        return np.broadcast_shapes(*shapes.values())
    except ValueError as exc:
        listed = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(f"leading (batch) dimensions do not broadcast: {listed}") from exc


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
    mag : array_like, shape (..., 3), or None
        Magnetic field in the body frame (µT), direction only; ``None`` selects the IMU
        form (gravity only, heading from the gyroscope alone).
    dt : float or array_like, shape (...)
        Integration step (s), > 0; an array gives one step per batch element (e.g. an
        extended step after a loss).
    beta : float or array_like, shape (...)
        Gain β (rad/s), >= 0, scalar or one per batch element.

    Returns
    -------
    numpy.ndarray, shape (..., 4)
        Updated ENU unit quaternions; ``...`` is the broadcast of all leading dimensions.

    Raises
    ------
    ValueError
        On wrong shapes, NaN/inf, a zero ``q``, ``acc`` or ``mag``, ``dt <= 0`` or
        ``beta < 0``, naming the argument.
    """
    q = as_float_array(q, "q", last_dim=4)
    q = q / check_nonzero_norm(q, "q", "a zero quaternion is not a rotation")[..., None]
    gyr = as_float_array(gyr, "gyr", last_dim=3)
    acc = as_float_array(acc, "acc", last_dim=3)
    acc = acc / check_nonzero_norm(acc, "acc", "free fall has no gravity direction")[..., None]
    shapes = {"q": q.shape[:-1], "gyr": gyr.shape[:-1], "acc": acc.shape[:-1]}
    if mag is not None:
        mag = as_float_array(mag, "mag", last_dim=3)
        mag = mag / check_nonzero_norm(mag, "mag", "a magnetometer reading needs a direction")[
            ..., None
        ]
        shapes["mag"] = mag.shape[:-1]
    dt = as_float_array(dt, "dt", min_ndim=0)
    if np.any(dt <= 0.0):
        raise ValueError("dt must be > 0")
    beta = as_float_array(beta, "beta", min_ndim=0)
    if np.any(beta < 0.0):
        raise ValueError("beta must be >= 0")
    shapes["dt"] = dt.shape
    shapes["beta"] = beta.shape
    _broadcast_batch(shapes)
    return _step(q, gyr, acc, mag, dt, beta * dt)


def _as_signal(value, name: str) -> np.ndarray:
    """Float array of shape ``(..., T, 3)``; finiteness is checked later, on received samples."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array, got {type(value).__name__}") from exc
    if arr.ndim < 2 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., T, 3), got shape {arr.shape}")
    return arr


def _first_bad(bad: np.ndarray, name: str, what: str) -> None:
    if np.any(bad):
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{name} {what} at received sample (batch..., t) = {index}")


def _usable(arr: np.ndarray, name: str, received, unit: bool) -> np.ndarray:
    """Check the received samples of ``arr`` ``(..., T, 3)``; return it safe to compute with.

    Raises if a received sample is not finite (or, with ``unit``, is a zero vector).  Lost
    samples that are not finite become 0 so that no NaN enters the arithmetic (their result
    is discarded).  With ``unit`` the vectors are scaled to unit length (lost zero vectors
    stay 0).
    """
    sq = np.einsum("...i,...i->...", arr, arr)  # one pass finds NaN/inf and the norm
    finite = np.isfinite(sq)
    if not np.all(finite):
        _first_bad(~finite if received is None else ~finite & received, name, "is not finite")
        arr = np.where(finite[..., None], arr, 0.0)
        sq = np.where(finite, sq, 0.0)
    if unit:
        zero = sq == 0.0
        _first_bad(zero if received is None else zero & received, name, "is a zero vector")
        inv_norm = np.divide(1.0, np.sqrt(sq), out=np.zeros_like(sq), where=~zero)
        arr = arr * inv_norm[..., None]
    return arr


def madgwick(
    gyr, acc, mag=None, *, fs: float, beta: float, received=None, q0=None
) -> np.ndarray:
    """Madgwick's filter over whole recordings, with packet loss, batched.

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
        Sampling rate (Hz), > 0; every received sample is integrated over Δt = 1/fs.
    beta : float
        Gain β (rad/s), >= 0: the assumed gyroscope error as a quaternion rate.
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
        non-boolean ``received``, ``fs <= 0``, ``beta < 0`` (or NaN), a zero ``q0``, or a
        batch element with no received sample when ``q0`` is None.

    Notes
    -----
    No gyroscope bias compensation (ζ = 0).  Batches run in one vectorised pass; the only
    Python loop is over time.
    """
    fs = check_positive(fs, "fs")
    beta = check_nonnegative(beta, "beta")
    signals = {"gyr": _as_signal(gyr, "gyr"), "acc": _as_signal(acc, "acc")}
    if mag is not None:
        signals["mag"] = _as_signal(mag, "mag")
    n_t = signals["gyr"].shape[-2]
    for name, arr in signals.items():
        if arr.shape[-2] != n_t:
            raise ValueError(f"{name} has {arr.shape[-2]} samples (axis -2), gyr has {n_t}")
    shapes = {name: arr.shape[:-2] for name, arr in signals.items()}

    if received is not None:
        received = np.asarray(received)
        if received.dtype != np.bool_:
            raise ValueError(f"received must be a boolean mask, got dtype {received.dtype}")
        if received.ndim < 1 or received.shape[-1] != n_t:
            raise ValueError(f"received must have shape (..., {n_t}), got {received.shape}")
        shapes["received"] = received.shape[:-1]
    if q0 is not None:
        q0 = as_float_array(q0, "q0", last_dim=4)
        q0 = q0 / check_nonzero_norm(q0, "q0", "a zero quaternion is not a rotation")[..., None]
        shapes["q0"] = q0.shape[:-1]
    batch = _broadcast_batch(shapes)

    # Received samples must be usable; lost ones are never read.
    for name, arr in signals.items():
        signals[name] = _usable(arr, name, received, unit=name != "gyr")

    if q0 is None:
        q_init, update = _initial_estimate(signals, received, batch, n_t)
    else:
        q_init, update = q0, received

    def sample(name, t):
        # Component-first copy (3, ...) of sample t: contiguous rows for _update.
        return None if name not in signals else np.moveaxis(signals[name][..., t, :], -1, 0).copy()

    dt = 1.0 / fs
    beta_dt = beta * dt
    out = np.empty(batch + (n_t, 4))
    q = np.array(np.moveaxis(np.broadcast_to(q_init, batch + (4,)), -1, 0))  # (4, *batch)
    start = 0
    if update is None and q0 is None and n_t > 0:
        out[..., 0, :] = np.moveaxis(q, 0, -1)  # sample 0 initialised the filter
        start = 1
    if update is not None:
        update_t = np.ascontiguousarray(np.moveaxis(update, -1, 0))
        any_update = np.any(update_t, axis=tuple(range(1, update_t.ndim)))
    for t in range(start, n_t):
        if update is None or any_update[t]:
            q_new = _update(q, sample("gyr", t), sample("acc", t), sample("mag", t), dt, beta_dt)
            q = q_new if update is None else np.where(update_t[t], q_new, q)
        out[..., t, :] = np.moveaxis(q, 0, -1)
    return out


def _initial_estimate(signals, received, batch, n_t):
    """Per-batch-element start from the first received sample (TRIAD or tilt).

    Returns the ENU initial quaternions ``batch + (4,)`` and the update mask (``received``
    with each first received sample switched off), or ``None`` when all are received.
    """
    if received is None:
        if n_t == 0:
            raise ValueError("no samples (T = 0): pass q0 to define the output")
        first = np.zeros(batch, dtype=int)
        update = None
    else:
        mask = np.broadcast_to(received, batch + (n_t,))
        has_sample = mask.any(axis=-1)
        if not np.all(has_sample):
            bad = tuple(int(i) for i in np.argwhere(~has_sample)[0])
            raise ValueError(
                f"received has no received sample for batch element {bad}; "
                "pass q0 to define the estimate there"
            )
        first = mask.argmax(axis=-1)
        update = mask.copy()
        np.put_along_axis(update, first[..., None], False, axis=-1)

    def first_sample(arr):
        arr = np.broadcast_to(arr, batch + arr.shape[-2:])
        return np.take_along_axis(arr, first[..., None, None], axis=-2)[..., 0, :]

    acc0 = first_sample(signals["acc"])
    if "mag" in signals:
        return triad(acc0, first_sample(signals["mag"])), update
    return tilt_quaternion(acc0), update
