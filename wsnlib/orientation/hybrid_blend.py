"""Paper 001's hybrid as an output stage on any filter, and the gate that says when to trust TRIAD.

Eq. (4) of paper 001, ``q_f = SLERP(q_s, q_d, μ_λ)``, interpolates between the single-frame
(TRIAD) estimate ``q_s`` and the data-fusion estimate ``q_d`` with μ of eq. (3)
(:mod:`wsnlib.orientation.lost_run`): μ = 1 gives the data fusion, μ → 0 the single frame.
Whether the SLERP output is fed back into the filter the paper leaves open: Fig. 4 draws it as
an output stage, while Sec. V speaks of a method "to make the internal state of [the]
data-fusion algorithm recover fast".  :func:`blend_with_single_frame` is the output stage
(``blend="output"`` of :func:`wsnlib.orientation.estimate_orientation`) applied to any
filter's output (the peer filters of :mod:`wsnlib.orientation.peers` use it); the feedback
form lives inside the filter's loop (``blend="feedback"``).

Gated hybrid
------------
TRIAD is off by tens of degrees under acceleration or near iron.  :class:`SingleFrameGate`
makes μ = 1 on received samples whose single frame fails a scalar check (accelerometer norm,
angular rate, field norm and dip against a causal reference), so that the data fusion is kept
there (:func:`single_frame_trusted` gives the mask).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wsnlib._validation import check_settings_fields
from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kernels as K
from wsnlib.orientation.lost_run import SCHEDULE_CODES, check_weight_options


@dataclass(frozen=True)
class SingleFrameGate:
    """When the gated hybrid trusts TRIAD: outside these tolerances μ = 1 (data fusion only).

    TRIAD takes the accelerometer for gravity and the magnetometer for the earth's field.
    Under linear or centripetal acceleration, or near iron, it is off by tens of degrees
    (8–105° on BROAD's translation and disturbed trials, issue 11), and the plain hybrid pulls
    the estimate towards that error exactly after a gap, when its weight is largest.  The gated
    hybrid (``single_frame_gate=SingleFrameGate()`` in :func:`~wsnlib.orientation.estimate_orientation`,
    :func:`blend_with_single_frame`, :func:`wsnlib.orientation.fusion_ahrs` and
    :func:`wsnlib.orientation.vqf_orientation`) applies eq. (4) only on received samples whose
    single frame passes all four checks below (:func:`single_frame_trusted`); elsewhere μ = 1,
    the data-fusion estimate is kept whole, and λ_eff goes on as before.  Each check is one
    scalar comparison per received sample (:func:`wsnlib.orientation._kernels.single_frame_check`).

    Every tolerance may be ``inf`` (that check off); all must be > 0.

    Attributes
    ----------
    acc_norm_tolerance : float
        Largest ``|‖a‖/g − 1|`` (relative, g = 9.80665 m/s²; ``acc`` must be in m/s²).
        Default 0.1: a norm 10 % off g means a linear acceleration of at least 0.1 g, which
        tilts the measured "up" by up to asin(0.1) = 5.7°, about half of Fusion's suggested
        acceleration rejection angle (10°, x-io Fusion README, ``accelerationRejection``), and
        a fifth of VQF's rest threshold is far stricter (``restThAcc`` = 0.5 m/s² ≈ 0.05 g,
        for rest detection, not rejection).  Fusion rejects by the angle between measured and
        *estimated* gravity, which is also large after a gap, exactly when the hybrid acts;
        the norm needs no estimate.
    rate_limit : float
        Largest ‖ω‖ (rad/s, the raw gyroscope).  Default 2 rad/s: centripetal acceleration
        ω² r reaches 0.1 g (the tolerance above) at ω = 1.8 rad/s for a sensor r = 0.3 m
        from the joint it turns about (a forearm), and a turning sensor's norm can stay
        near g while its direction is off.  (VQF's rest threshold ``restThGyr`` = 2 °/s is
        for rest detection, far stricter; VQF uses ``magNewMinGyr`` = 20 °/s as "moving".)
    mag_norm_tolerance : float
        Largest ``|‖m‖/‖m_ref‖ − 1|`` (relative).  Default 0.1, VQF's ``magNormTh``
        (Laidig & Seel 2023, Sec. 3.4).
    mag_dip_tolerance : float
        Largest ``|dip − dip_ref|`` (rad), the dip being the field's angle below the plane
        normal to ``a`` (``asin(−â·m̂)``, no orientation estimate needed; undefined under
        acceleration, so the reference dip is only updated while the norm check on ``a``
        passes).  Default 10°, VQF's ``magDipTh``.  A magnet attached to the sensor gives a
        field constant in the body frame: its norm is steady, but its dip follows the tilt.
    reference_tau_s : float
        Time constant (s) of the references ``‖m_ref‖`` and ``dip_ref``: set by the first
        received sample, then low-pass filtered over received samples (causal; counted in
        received samples × Δt), so a lasting change of the field becomes the new reference
        within about this time.  Default 20 s, VQF's ``magRefTau`` (and its ``magNewTime``).
    """

    acc_norm_tolerance: float = 0.1
    rate_limit: float = 2.0
    mag_norm_tolerance: float = 0.1
    mag_dip_tolerance: float = math.radians(10.0)
    reference_tau_s: float = 20.0

    def __post_init__(self):
        check_settings_fields(self)  # every tolerance > 0, inf allowed (that check off)

    def vector(self, fs: float) -> np.ndarray:
        """The kernels' gate vector (:data:`wsnlib.orientation._kernels.GATE_SIZE` floats) at ``fs`` (Hz)."""
        out = np.empty(K.GATE_SIZE)
        out[K.GATE_ACC_NORM] = self.acc_norm_tolerance
        out[K.GATE_RATE] = self.rate_limit
        out[K.GATE_MAG_NORM] = self.mag_norm_tolerance
        out[K.GATE_MAG_DIP] = self.mag_dip_tolerance
        out[K.GATE_REF_GAIN] = -math.expm1(-1.0 / (fs * self.reference_tau_s))
        return out


def check_single_frame_gate(single_frame_gate) -> SingleFrameGate | None:
    """``None`` or a :class:`SingleFrameGate` (``True``: the defaults), else ``ValueError``."""
    if single_frame_gate is None or single_frame_gate is False:
        return None
    if single_frame_gate is True:
        return SingleFrameGate()
    if not isinstance(single_frame_gate, SingleFrameGate):
        raise ValueError(f"single_frame_gate must be None, True or a SingleFrameGate, got "
                         f"{type(single_frame_gate).__name__}")
    return single_frame_gate


def single_frame_trusted(gyr, acc, mag, received=None, *, fs: float, single_frame_gate=True) -> np.ndarray:
    """Which received samples' single frame (TRIAD) the gated hybrid trusts, causally.

    The four checks of :class:`SingleFrameGate` on every received sample, the field's
    reference norm and dip learned from the received samples before it (lost ones are never
    read).  This is the mask the gated hybrid uses inside :func:`~wsnlib.orientation.estimate_orientation` and
    :func:`blend_with_single_frame`.

    Parameters
    ----------
    gyr, acc, mag : array_like, shape (..., T, 3)
        Angular rate (rad/s), specific force (m/s²), magnetic field (any unit), body frame.
    received : array_like of bool, shape (..., T), optional
        True = received; ``None``: all.
    fs : float
        Sampling rate (Hz), > 0 (for the reference's time constant).
    single_frame_gate : SingleFrameGate or True
        Tolerances (``True``: the defaults).

    Returns
    -------
    numpy.ndarray of bool, shape (..., T)
        True where the sample was received and passed every check; ``...`` is the broadcast
        of the leading dimensions of the arguments.

    Raises
    ------
    ValueError
        Naming the argument: shapes, NaN/inf or zero vectors in received samples, a
        non-boolean ``received``, ``fs`` <= 0, a ``single_frame_gate`` that is not a
        :class:`SingleFrameGate`.
    """
    gate = check_single_frame_gate(single_frame_gate)
    if gate is None:
        raise ValueError("single_frame_gate must be True or a SingleFrameGate here")
    fs = B.check_fs(fs)
    if mag is None:
        raise ValueError("mag is required: the gate checks the magnetometer")
    signals, mask, _, shapes = B.check_inputs(gyr, acc, mag, received)
    batch = B.broadcast_batch(shapes)
    mask = B.check_usable(signals, mask)
    return trusted_unchecked(signals, mask, batch, gate.vector(fs))


def trusted_unchecked(signals, mask, batch, gate_vector) -> np.ndarray:
    """:func:`single_frame_trusted` on checked inputs: ``(*batch, T)`` bool."""
    n_t = mask.shape[-1]
    out = np.empty(batch + (n_t,), dtype=bool)
    if n_t:
        index = [B.index_into(signals[name].shape[:-2], batch) for name in ("gyr", "acc", "mag")]
        K.run_single_frame_trust(B.flat(signals["gyr"], 2), B.flat(signals["acc"], 2), B.flat(signals["mag"], 2),
                                 B.flat(mask, 1), *index, B.index_into(mask.shape[:-1], batch), gate_vector,
                                 out.reshape(-1, n_t))
    return out


def blend_with_single_frame(
    quat_d,
    acc,
    mag,
    received=None,
    *,
    rho=2.0,
    tau=6.0,
    schedule: str = "decay",
    hold_window=None,
    leading_gap: bool = False,
    single_frame_gate: SingleFrameGate | bool | None = None,
    gyr=None,
    fs: float | None = None,
) -> np.ndarray:
    """Paper 001's hybrid as an output stage on any data-fusion output: eqs. (3)–(4).

    ``q_f = SLERP(q_s, q_d, μ)`` with ``μ = slerp_weight(λ_eff, ρ, τ)`` on every received
    sample where λ_eff > 0 (:func:`~wsnlib.orientation.effective_lost_run`), ``q_s`` = TRIAD of that sample's
    ``acc`` and ``mag``, ``q_d`` = ``quat_d`` there; elsewhere ``quat_d`` unchanged.  On a
    lost sample the output is eq. (4) with the held ``q_d`` and the ``q_s``, μ of the last
    received sample, i.e. the previous output whenever ``quat_d`` holds its previous value
    there, as every filter of wsnlib does.  This is ``estimate_orientation(...,
    method="hybrid", blend="output")`` with Madgwick's filter replaced by whatever produced
    ``quat_d`` (e.g. :mod:`wsnlib.orientation.peers`): with ``quat_d`` the output of
    :func:`wsnlib.orientation.madgwick` (same mask, ``q0=None``) the two agree to rounding.

    Parameters
    ----------
    quat_d : array_like, shape (..., T, 4)
        Data-fusion estimate (ENU, body → earth), finite and non-zero (normalised here).
    acc, mag : array_like, shape (..., T, 3)
        Specific force (m/s²) and magnetic field (µT) in the body frame, for TRIAD; only
        received samples are read (lost ones may hold NaN).
    received : array_like of bool, shape (..., T), optional
        True = received; ``None``: all received (then λ_eff = 0 and ``quat_d`` comes back).
    rho, tau : float or array_like
        ρ, τ of eq. (3), finite and > 0; arrays broadcast against the leading dimensions, as
        in :func:`~wsnlib.orientation.estimate_orientation`.
    schedule : {"decay", "hold", "instant"}
        λ_eff after a gap (:func:`~wsnlib.orientation.effective_lost_run`).
    hold_window : int or array_like of int, optional
        For ``schedule="hold"`` only (default 50 received samples).
    leading_gap : bool
        Whether a gap before a batch element's first received sample counts.  ``False``
        (default): the filter had not started, λ_eff is 0 up to that sample, as in
        :func:`~wsnlib.orientation.estimate_orientation` with ``q0=None``; ``True``: it counts like any gap,
        as there with ``q0`` given.
    single_frame_gate : SingleFrameGate or bool, optional
        The gated hybrid: no blend on received samples whose TRIAD fails a check of
        :class:`SingleFrameGate` (``True``: default tolerances).  Needs ``gyr`` and ``fs``.
    gyr : array_like, shape (..., T, 3), optional
        Angular rate (rad/s), body frame; only for ``single_frame_gate`` (its rate check).
    fs : float, optional
        Sampling rate (Hz); only for ``single_frame_gate`` (its reference time constant).

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        Blended ENU unit quaternions; ``...`` is the broadcast of the leading dimensions of
        all array arguments.  Blended samples keep the sign (hemisphere) of ``quat_d``.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes or mismatched T, leading dimensions that do not
        broadcast, NaN/inf or a zero quaternion in ``quat_d``, NaN/inf or a zero vector in a
        received ``acc``/``mag`` sample, a non-boolean ``received``, an unknown
        ``schedule``, ρ or τ not finite and > 0, a bad ``hold_window``.  ``acc`` parallel to
        ``mag`` on a blended sample fails in TRIAD.
    """
    rho, tau, schedule, window = check_weight_options(rho, tau, schedule, hold_window)
    gate = check_single_frame_gate(single_frame_gate)
    if gate is None and (gyr is not None or fs is not None):
        raise ValueError("gyr and fs are only used with single_frame_gate")
    if gate is not None and (gyr is None or fs is None):
        raise ValueError("single_frame_gate needs gyr (rad/s) and fs (Hz)")
    quat_d = B.unit_quaternions(quat_d, "quat_d")
    if quat_d.ndim < 2:
        raise ValueError(f"quat_d must have shape (..., T, 4), got shape {quat_d.shape}")
    signals = {"acc": B.as_signal(acc, "acc"), "mag": B.as_signal(mag, "mag")}
    if gate is not None:
        signals["gyr"] = B.as_signal(gyr, "gyr")
        fs = B.check_fs(fs)
    n_t = quat_d.shape[-2]
    for name, arr in signals.items():
        if arr.shape[-2] != n_t:
            raise ValueError(f"{name} has {arr.shape[-2]} samples (axis -2), quat_d has {n_t}")
    mask = B.check_received(received, n_t)
    shapes = {name: arr.shape[:-2] for name, arr in signals.items()} | {"received": mask.shape[:-1]}
    B.broadcast_batch(shapes)
    shapes["quat_d"] = quat_d.shape[:-2]
    params = {"rho": rho.shape, "tau": tau.shape}
    if window is not None:
        params["hold_window"] = window.shape
    batch = B.broadcast_batch(shapes | params)
    mask = B.check_usable(signals, mask)
    out = B.new_output(batch, n_t)
    if n_t:
        if gate is None:
            trusted = np.ones((1, n_t), dtype=bool)
            i_tr = np.zeros(int(np.prod(batch)), dtype=np.int64)
        else:
            sig_batch = B.broadcast_batch({name: arr.shape[:-2] for name, arr in signals.items()}
                                          | {"received": mask.shape[:-1]})
            trusted = trusted_unchecked(signals, mask, sig_batch, gate.vector(fs)).reshape(-1, n_t)
            i_tr = B.index_into(sig_batch, batch)
        status = np.empty(int(np.prod(batch, dtype=np.int64)), dtype=np.int64)
        K.run_output_blend(B.flat(quat_d, 2), B.flat(signals["acc"], 2), B.flat(signals["mag"], 2),
                           B.flat(mask, 1), trusted, B.index_into(quat_d.shape[:-2], batch),
                           B.index_into(signals["acc"].shape[:-2], batch),
                           B.index_into(signals["mag"].shape[:-2], batch), B.index_into(mask.shape[:-1], batch), i_tr,
                           B.per_element(rho, batch), B.per_element(tau, batch), SCHEDULE_CODES[schedule],
                           B.per_element(1 if window is None else window, batch, np.int64), leading_gap,
                           out.reshape(-1, n_t, 4), status)
        B.raise_on_status(status, batch)
    return out
