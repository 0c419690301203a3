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

Speed.  The time loop is the cost; the comments above :func:`_update` and at
:class:`_SignalBlocks` explain the memory layout it uses, and
``benchmarks/bench_madgwick.py`` measures it.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import as_float_array, check_nonnegative, check_nonzero_norm, check_positive
from wsnlib.orientation.triad import tilt_quaternion, triad

#: q_z(+90°): the rotation taking NWU coordinates to ENU coordinates.
Q_ENU_FROM_NWU = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])

# ------------------------------------------------------------------------------------------
# The kernel: one update, component axis first, every intermediate in preallocated rows.
#
# Why the layout.  Each quaternion or vector component is one contiguous row ``(...)`` of a
# component-first array ``(4, ...)`` / ``(3, ...)``, so every operation below is a single
# numpy call over contiguous memory.  Every intermediate is written with ``out=`` into a
# row of one preallocated ``work`` array: at large batches (10⁴ elements, 80 kB a row) the
# many short-lived temporaries of plain expressions cost more than the arithmetic, because
# the allocator hands their pages back to the OS and takes them again at every step (page
# faults).  Expressions are ordered as in the report's expanded formulas, so results agree
# with them (and with ``ahrs``) to rounding.
# ------------------------------------------------------------------------------------------

_C45 = Q_ENU_FROM_NWU[0]  # cos 45° = sin 45°

#: Rows of ``work`` (each ``(*batch)``) used by :func:`_gradient`, group by group: 2q, the
#: products 2 q_i q_j, R, e, scratch, h, f_b, J_xᵀ f_b, b_x.
_GRADIENT_GROUPS = (4, 9, 9, 3, 3, 3, 3, 4, 1)
#: ... and by :func:`_update`: q_NWU, ∇f, q_new, squares, norms, step; then :func:`_gradient`'s.
_UPDATE_GROUPS = (4, 4, 4, 4, 1, 1)
_GRADIENT_ROWS = sum(_GRADIENT_GROUPS)
_UPDATE_ROWS = sum(_UPDATE_GROUPS) + _GRADIENT_ROWS


def _groups(work, sizes):
    """Consecutive groups of rows of ``work`` (views), ``sizes[i]`` rows in group ``i``."""
    groups, start = [], 0
    for size in sizes:
        groups.append(work[start : start + size])
        start += size
    return groups


def _lift(x, ndim: int):
    """``(C, *s)`` viewed as ``(C, 1, …, 1, *s)`` with ``ndim`` axes after the first (or None)."""
    if x is None or x.ndim == ndim + 1:
        return x
    return x.reshape(x.shape[:1] + (1,) * (ndim + 1 - x.ndim) + x.shape[1:])


def _nwu_from_enu(q, out):
    """``q_NWU = q_z(+90°)* ⊗ q_ENU = c·[w + z, x + y, y − x, z − w]``, c = cos 45°."""
    np.add(q[0:2], q[3:1:-1], out=out[0:2])
    np.subtract(q[2:4], q[1::-1], out=out[2:4])
    out *= _C45
    return out


def _enu_from_nwu(q, out):
    """``q_ENU = q_z(+90°) ⊗ q_NWU = c·[w − z, x − y, x + y, z + w]``, c = cos 45°."""
    np.subtract(q[0:2], q[3:1:-1], out=out[0:2])
    np.add(q[2:4], q[1::-1], out=out[2:4])
    out *= _C45
    return out


def _gradient(q_nwu, acc, mag, *, out=None, work=None):
    """Half the objective-function gradient ½ Jᵀ f (eqs. (25)-(34), (45)-(46)).

    Component axis first: ``q_nwu`` unit ``(4, ...)`` in the report's NWU frame, ``acc`` and
    ``mag`` unit vectors ``(3, ...)`` (``mag=None``: gravity only).  Returns ``(4, ...)``
    (into ``out`` if given; ``work``: scratch ``(_GRADIENT_ROWS, ...)``).  The common
    factor 2 of J is dropped: only the direction of ∇f is used (eq. (44)).
    """
    if out is None:
        shapes = [q_nwu.shape[1:], acc.shape[1:]] + ([] if mag is None else [mag.shape[1:]])
        out = np.empty((4,) + np.broadcast_shapes(*shapes))
    batch = out.shape[1:]
    if not batch:  # rows must be arrays, not scalars: run a batch of one
        one = [None if x is None else x.reshape(x.shape[:1] + (1,)) for x in (q_nwu, acc, mag)]
        work = None if work is None else work.reshape(-1, 1)
        return _gradient(*one, out=out.reshape(4, 1), work=work)[:, 0]
    if work is None:
        work = np.empty((_GRADIENT_ROWS,) + batch)
    q, acc, mag = (_lift(x, len(batch)) for x in (q_nwu, acc, mag))
    qw, qx, qy, qz = q
    twice_q, products, rot, e, tmp, h, f_b, jx, (bx,) = _groups(work, _GRADIENT_GROUPS)
    rot = rot.reshape((3, 3) + batch)
    t = tmp[0]

    # Rotation matrix R (body → NWU) of q, from the products 2 q_i q_j.  Row i of R is
    # q* ⊗ d ⊗ q for d = the i-th NWU axis: the reference directions in the body frame.
    np.multiply(q, 2.0, out=twice_q)
    two_w, two_x, two_y, two_z = twice_q
    xx, xy, xz, yy, yz, zz, wx, wy, wz = products
    np.multiply(two_x, q[1:], out=products[0:3])  # 2xx, 2xy, 2xz
    np.multiply(two_y, q[2:], out=products[3:5])  # 2yy, 2yz
    np.multiply(two_z, qz, out=zz)
    np.multiply(two_w, q[1:], out=products[6:9])  # 2wx, 2wy, 2wz
    (r11, r12, r13), (r21, r22, r23), (r31, r32, r33) = rot
    np.subtract(xz, wy, out=r31)
    np.add(yz, wx, out=r32)
    np.subtract(1.0, xx, out=r33)
    r33 -= yy

    # Eqs. (25), (34): f_g = q* ⊗ [0, 0, 0, 1] ⊗ q − a = (third row of R) − a.
    np.subtract(rot[2], acc, out=e)

    if mag is not None:
        np.subtract(1.0, yy, out=r11)
        r11 -= zz
        np.subtract(xy, wz, out=r12)
        np.add(xz, wy, out=r13)
        np.add(xy, wz, out=r21)
        np.subtract(1.0, xx, out=r22)
        r22 -= zz
        np.subtract(yz, wx, out=r23)
        mx, my, mz = mag
        # Eq. (45): h = q ⊗ [0, m] ⊗ q* = R m.
        np.multiply(rot[:, 0], mx, out=h)
        h += np.multiply(rot[:, 1], my, out=tmp)
        h += np.multiply(rot[:, 2], mz, out=tmp)
        # Eq. (46): b = [0, √(h_x² + h_y²), 0, h_z].
        np.multiply(h[0], h[0], out=bx)
        bx += np.multiply(h[1], h[1], out=t)
        np.sqrt(bx, out=bx)
        bz = h[2]
        # Eq. (29): f_b = q* ⊗ [0, b_x, 0, b_z] ⊗ q − m = b_x (row 1 of R) + b_z (row 3) − m.
        np.multiply(rot[0], bx, out=f_b)
        f_b += np.multiply(rot[2], bz, out=tmp)
        f_b -= mag
        # Eqs. (30), (32), (34): J_b = b_z J_g + b_x J_x, so the stacked gradient
        # J_gᵀ f_g + J_bᵀ f_b is J_gᵀ (f_g + b_z f_b) + b_x J_xᵀ f_b.  Halved, like J_g:
        #   J_x / 2 = [[0, 0, -2q_y, -2q_z], [-q_z, q_y, q_x, -q_w], [q_y, q_z, q_w, q_x]].
        e += np.multiply(f_b, bz, out=tmp)
        f4, f5, f6 = f_b
        j_w, j_x, j_y, j_z = jx
        np.multiply(qy, f6, out=j_w)
        j_w -= np.multiply(qz, f5, out=t)
        np.multiply(qy, f5, out=j_x)
        j_x += np.multiply(qz, f6, out=t)
        np.multiply(qx, f5, out=j_y)
        j_y += np.multiply(qw, f6, out=t)
        j_y -= np.multiply(two_y, f4, out=t)
        np.multiply(qx, f6, out=j_z)
        j_z -= np.multiply(qw, f5, out=t)
        j_z -= np.multiply(two_z, f4, out=t)

    # Eqs. (26), (34): J_gᵀ e, with J_g / 2 = [[-q_y, q_z, -q_w, q_x], [q_x, q_w, q_z, q_y],
    # [0, -2q_x, -2q_y, 0]] (e = f_g for the IMU form).
    e1, e2, e3 = e
    grad_w, grad_x, grad_y, grad_z = out
    np.multiply(qx, e2, out=grad_w)
    grad_w -= np.multiply(qy, e1, out=t)
    np.multiply(qz, e1, out=grad_x)
    grad_x += np.multiply(qw, e2, out=t)
    grad_x -= np.multiply(two_x, e3, out=t)
    np.multiply(qz, e2, out=grad_y)
    grad_y -= np.multiply(qw, e1, out=t)
    grad_y -= np.multiply(two_y, e3, out=t)
    np.multiply(qx, e1, out=grad_z)
    grad_z += np.multiply(qy, e2, out=t)
    if mag is not None:
        out += np.multiply(jx, bx, out=jx)
    return out


def _update(q, gyr, acc, mag, dt, beta_dt, *, out=None, work=None) -> np.ndarray:
    """One filter update, no validation, component axis FIRST (the hot loop).

    ``q``: ENU unit quaternions ``(4, ...)``; ``gyr`` (rad/s), ``acc`` and ``mag`` (unit
    vectors) ``(3, ...)``, ``mag=None`` for the IMU form; ``dt`` (s) and ``beta_dt = β·Δt``
    scalars or arrays broadcasting over ``...``.  Returns ENU unit quaternions ``(4, ...)``.
    All inputs must be finite.

    Optional, for loops: ``out`` ``(4, *batch)`` receives the result (it must not overlap
    ``q``), and ``work`` ``(_UPDATE_ROWS, *batch)`` is scratch space reused between calls;
    ``batch`` is the broadcast of all leading shapes.
    """
    if out is None:
        shapes = [q.shape[1:], gyr.shape[1:], acc.shape[1:], np.shape(dt), np.shape(beta_dt)]
        out = np.empty((4,) + np.broadcast_shapes(*shapes, *([] if mag is None else [mag.shape[1:]])))
    batch = out.shape[1:]
    if not batch:  # rows must be arrays, not scalars: run a batch of one
        one = [None if x is None else x.reshape(x.shape[:1] + (1,)) for x in (q, gyr, acc, mag)]
        work = None if work is None else work.reshape(-1, 1)
        return _update(*one, dt, beta_dt, out=out.reshape(4, 1), work=work)[:, 0]
    if work is None:
        work = np.empty((_UPDATE_ROWS,) + batch)
    q, gyr = _lift(q, len(batch)), _lift(gyr, len(batch))
    q_nwu, grad, q_new, squares, (norm,), (step,) = _groups(work, _UPDATE_GROUPS)
    t = squares[0]

    _nwu_from_enu(q, out=q_nwu)  # the report's equations are written for NWU
    _gradient(q_nwu, acc, mag, out=grad, work=work[sum(_UPDATE_GROUPS) :])

    # Eq. (44): unit gradient.  At an exact optimum ∇f = 0 has no direction: no correction.
    np.multiply(grad, grad, out=squares)
    np.add.reduce(squares, axis=0, out=norm)
    np.sqrt(norm, out=norm)
    if norm.min() > 0.0:
        np.divide(1.0, norm, out=step)
    else:
        step.fill(0.0)
        np.divide(1.0, norm, out=step, where=norm > 0.0)
    step *= beta_dt  # β Δt / ‖∇f‖

    # Eq. (11): q ⊗ [0, ω] (the ½ goes into ½Δt below), the product written out.
    qw, qx, qy, qz = q_nwu
    gx, gy, gz = gyr
    d_w, d_x, d_y, d_z = q_new
    np.multiply(qx, gx, out=d_w)
    d_w += np.multiply(qy, gy, out=t)
    d_w += np.multiply(qz, gz, out=t)
    np.negative(d_w, out=d_w)
    np.multiply(qw, gx, out=d_x)
    d_x += np.multiply(qy, gz, out=t)
    d_x -= np.multiply(qz, gy, out=t)
    np.multiply(qw, gy, out=d_y)
    d_y -= np.multiply(qx, gz, out=t)
    d_y += np.multiply(qz, gx, out=t)
    np.multiply(qw, gz, out=d_z)
    d_z += np.multiply(qx, gy, out=t)
    d_z -= np.multiply(qy, gx, out=t)
    # Eqs. (42)-(43): q + ½ q ⊗ [0, ω] Δt − β Δt ∇f/‖∇f‖, then normalised.
    q_new *= 0.5 * dt
    q_new += q_nwu
    q_new -= np.multiply(grad, step, out=grad)
    np.multiply(q_new, q_new, out=squares)
    np.add.reduce(squares, axis=0, out=norm)
    np.sqrt(norm, out=norm)
    q_new /= norm
    return _enu_from_nwu(q_new, out=out)


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


def _squared_norm(x, y, z, out=None):
    """``(x² + y²) + z²``, in this order wherever a squared norm is taken (same rounding)."""
    out = np.multiply(x, x, out=out)
    out += y * y
    out += z * z
    return out


def _usable(arr: np.ndarray, name: str, received, unit: bool) -> np.ndarray:
    """Check the received samples of ``arr`` ``(..., T, 3)``; return it safe to compute with.

    Raises if a received sample is not finite (or, with ``unit``, is a zero vector).  Lost
    samples that are not finite become 0 so that no NaN enters the arithmetic (their result
    is discarded).  With ``unit`` the vectors are scaled to unit length (lost zero vectors
    stay 0).  :class:`_SignalBlocks` does the same block by block.
    """
    sq = _squared_norm(*np.moveaxis(arr, -1, 0))  # one pass finds NaN/inf and the norm
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


def _check_inputs(gyr, acc, mag, received, q0=None):
    """Shared argument checks of the whole-recording filters (madgwick, loss handling, peers).

    Returns the signals ``{"gyr", "acc"[, "mag"]}`` as float arrays ``(..., T, 3)`` (finiteness
    is checked later, on received samples only), ``received`` as a boolean array or None,
    ``q0`` normalised or None, and the leading (batch) shape of each argument, by name.
    """
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
    return signals, received, q0, shapes


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
    signals, received, q0, shapes = _check_inputs(gyr, acc, mag, received, q0)
    n_t = signals["gyr"].shape[-2]
    batch = _broadcast_batch(shapes)

    out = np.empty(batch + (n_t, 4))
    try:
        # Received samples must be usable; lost ones are never read.  The samples are
        # checked (and acc, mag scaled to unit vectors) as the loop reaches them.
        blocks = {name: _SignalBlocks(arr, name, received, len(batch)) for name, arr in signals.items()}
        if q0 is None:
            q_init, update = _initial_estimate(signals, received, batch, n_t, blocks)
        else:
            q_init, update = q0, received
        start = 0
        if update is None and q0 is None and n_t > 0:
            out[..., 0, :] = q_init  # sample 0 initialised the filter
            start = 1
            blocks["gyr"].load(0, 1)  # (checked all the same; acc and mag were, for q_init)
        dt = 1.0 / fs
        _filter_loop(blocks, update, q_init, dt, beta * dt, out, start)
    except Exception:
        # Report any unusable received sample as a full check before the loop would have
        # (the first one in (batch..., t) order, gyr then acc then mag), then other errors.
        for name, arr in signals.items():
            _usable(arr, name, received, unit=name != "gyr")
        raise
    return out


class _BadSample(Exception):
    """A received sample is not finite, or a zero acc/mag vector: :func:`madgwick` reports it."""


#: Samples per block of :class:`_SignalBlocks` (8 to 32 are about equally fast at batch 10⁴).
_BLOCK = 16


class _SignalBlocks:
    """One signal ``(..., T, 3)`` served ``_BLOCK`` samples at a time, time-major and
    component first ``(K, 3, ...)``, checked and (``acc``, ``mag``) scaled to unit vectors.

    Why.  The signal is sample-major: gathering sample ``t`` of every batch element at each
    step touches a separate cache line (and page) per element, which costs as much as the
    filter update itself.  A block first copies the contiguous runs ``[..., t0:t1, :]``, then
    transposes that small copy, which stays in cache; the steps then read contiguous rows.
    Checking and scaling here, on data in cache, replaces full-size passes before the loop.
    """

    def __init__(self, arr, name, received, ndim):
        self.arr, self.name, self.received, self.ndim = arr, name, received, ndim
        self.unit = name != "gyr"
        shape = arr.shape[:-2]
        self._stage = np.empty(shape + (_BLOCK, 3))
        self._block = np.empty((_BLOCK, 3) + shape)
        self._sq, self._tmp = np.empty((2, _BLOCK) + shape)
        self._ok, self._nonzero = np.empty((2, _BLOCK) + shape, dtype=bool)

    def load(self, t0: int, t1: int) -> np.ndarray:
        """Samples ``t0:t1`` as ``(t1 - t0, 3, ...)``, unit vectors if ``unit``."""
        n = t1 - t0
        stage, block, sq, tmp, ok = self._stage[..., :n, :], self._block[:n], self._sq[:n], self._tmp[:n], self._ok[:n]
        np.copyto(stage, self.arr[..., t0:t1, :])
        np.copyto(block, np.moveaxis(stage, (-2, -1), (0, 1)))
        x, y, z = block[:, 0], block[:, 1], block[:, 2]
        np.multiply(x, x, out=sq)  # _squared_norm's order
        sq += np.multiply(y, y, out=tmp)
        sq += np.multiply(z, z, out=tmp)
        np.isfinite(sq, out=ok)
        if self.unit:
            ok &= np.not_equal(sq, 0.0, out=self._nonzero[:n])
        all_ok = ok.all()
        if not all_ok:
            self._drop_lost(t0, t1, block, sq, ok)
        if self.unit:
            np.sqrt(sq, out=sq)
            np.divide(1.0, sq, out=sq, where=True if all_ok else ok)  # sq is 0 where not ok
            block *= sq[:, None]
        return block

    def _drop_lost(self, t0, t1, block, sq, ok) -> None:
        """Zero the unusable samples if all are lost; raise :class:`_BadSample` otherwise."""
        bad = ~ok
        received = None if self.received is None else np.moveaxis(self.received[..., t0:t1], -1, 0)
        if received is None or np.any(_lift(bad, self.ndim) & _lift(received, self.ndim)):
            raise _BadSample(self.name)
        np.copyto(block, 0.0, where=bad[:, None])
        np.copyto(sq, 0.0, where=bad)

    def first_unit(self, first) -> np.ndarray:
        """Sample ``first[...]`` of each batch element ``(..., 3)``, checked, unit if ``unit``."""
        arr = np.broadcast_to(self.arr, first.shape + self.arr.shape[-2:])
        sample = np.take_along_axis(arr, first[..., None, None], axis=-2)[..., 0, :]
        sq = _squared_norm(*np.moveaxis(sample, -1, 0))
        if not np.all(np.isfinite(sq) & (sq != 0.0)):
            raise _BadSample(self.name)
        return sample * (1.0 / np.sqrt(sq))[..., None]


def _filter_loop(blocks, update, q_init, dt, beta_dt, out, start) -> None:
    """Filter samples ``start…`` into ``out`` ``(*batch, T, 4)``; hold where ``update`` is False.

    The estimate stays in ENU between steps, as :func:`_update` takes and returns it: row
    ``k + 1`` of a ``(K + 1, 4, *batch)`` state block is the update of row ``k`` (row 0: the
    estimate before the block), and the block goes back to ``out`` in one copy (which, unlike
    the reads of :class:`_SignalBlocks`, is no faster in two stages).
    """
    batch, n_t = out.shape[:-2], out.shape[-2]
    state = np.empty((_BLOCK + 1, 4) + batch)
    state[0] = np.moveaxis(np.broadcast_to(q_init, batch + (4,)), -1, 0)
    work = np.empty((_UPDATE_ROWS,) + batch)
    if update is not None:
        lost = np.empty((_BLOCK,) + update.shape[:-1], dtype=bool)
        axes = tuple(range(update.ndim - 1))
        any_update, all_update = update.any(axis=axes), update.all(axis=axes)

    for t0 in range(start, n_t, _BLOCK):
        t1 = min(t0 + _BLOCK, n_t)
        n = t1 - t0
        gyr, acc = blocks["gyr"].load(t0, t1), blocks["acc"].load(t0, t1)
        mag = blocks["mag"].load(t0, t1) if "mag" in blocks else None
        if update is not None:
            np.logical_not(np.moveaxis(update[..., t0:t1], -1, 0), out=lost[:n])
        for k in range(n):
            t = t0 + k
            if update is not None and not any_update[t]:
                state[k + 1] = state[k]  # nothing received anywhere: hold
                continue
            m_k = None if mag is None else mag[k]
            _update(state[k], gyr[k], acc[k], m_k, dt, beta_dt, out=state[k + 1], work=work)
            if update is not None and not all_update[t]:
                np.copyto(state[k + 1], state[k], where=lost[k])  # hold where lost
        out[..., t0:t1, :] = np.moveaxis(state[1 : n + 1], (0, 1), (-2, -1))
        state[0] = state[n]


def _initial_estimate(signals, received, batch, n_t, blocks=None):
    """Per-batch-element start from the first received sample (TRIAD or tilt).

    Returns the ENU initial quaternions ``batch + (4,)`` and the update mask (``received``
    with each first received sample switched off), or ``None`` when all are received.
    ``signals`` must be unit vectors (:func:`_usable`), unless ``blocks``
    (:class:`_SignalBlocks`) are given, which check and scale the first samples.
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

    def first_sample(name):
        if blocks is not None:
            return blocks[name].first_unit(first)
        arr = np.broadcast_to(signals[name], batch + signals[name].shape[-2:])
        return np.take_along_axis(arr, first[..., None, None], axis=-2)[..., 0, :]

    acc0 = first_sample("acc")
    if "mag" in signals:
        return triad(acc0, first_sample("mag")), update
    return tilt_quaternion(acc0), update
