"""x-io Fusion (``imufusion``) as a wsnlib orientation filter under packet loss: :func:`fusion_ahrs`.

Loss semantics, frames, the hybrid and gap prediction: :mod:`wsnlib.orientation.peers`.
"""

from __future__ import annotations

import imufusion
import numpy as np

from wsnlib import fixed_order
from wsnlib._validation import check_nonnegative
from wsnlib.orientation._peer_common import (
    _feedback_inputs,
    _finish,
    _gap_options,
    _hybrid_options,
    _predict_gap,
    _prepare,
    _run_batch,
    _slerp,
)
from wsnlib.orientation.loss_handling import SingleFrameGate

#: Fields of ``imufusion.AhrsSettings`` a caller may set through ``settings``, with
#: Fusion's defaults (all switch the feature off); see :func:`fusion_ahrs` for units.
FUSION_DEFAULT_SETTINGS = {
    "gyroscope_range": 0.0,
    "acceleration_rejection": 0.0,
    "magnetic_rejection": 0.0,
    "rejection_timeout": 0.0,
}

#: m/s² per g, to feed Fusion's accelerometer in g.
_G = 9.80665


def _fusion_settings(fs: float, gain, settings) -> imufusion.AhrsSettings:
    values = dict(FUSION_DEFAULT_SETTINGS)
    if settings is not None:
        if not isinstance(settings, dict):
            raise ValueError(f"settings must be a dict of imufusion.AhrsSettings fields, got {type(settings).__name__}")
        for key, value in settings.items():
            if key in ("sample_rate", "convention", "gain"):
                raise ValueError(f"settings[{key!r}] is set by fusion_ahrs itself (fs, ENU, gain=); leave it out")
            if key not in FUSION_DEFAULT_SETTINGS:
                listed = ", ".join(repr(k) for k in FUSION_DEFAULT_SETTINGS)
                raise ValueError(f"settings has unknown key {key!r}; known: {listed}")
            values[key] = check_nonnegative(value, f"settings[{key!r}]")
    obj = imufusion.AhrsSettings()
    obj.sample_rate = fs
    obj.convention = imufusion.CONVENTION_ENU  # the constructor argument is ignored in 1.3.3
    obj.gain = check_nonnegative(gain, "gain")
    for key, value in values.items():
        setattr(obj, key, value)
    if obj.convention != imufusion.CONVENTION_ENU:  # pragma: no cover - guards a library change
        raise RuntimeError("imufusion did not accept CONVENTION_ENU")
    return obj


def _fusion_one(settings, dt=None, gap_factor=None):
    def one(gyr, acc, mag, mask, feedback):
        ahrs = imufusion.Ahrs()
        ahrs.set_settings(settings)
        gyr_deg = np.degrees(gyr).tolist()
        acc_g = (acc / _G).tolist()
        mag = None if mag is None else mag.tolist()
        n_t = mask.shape[-1]
        out = np.empty((n_t, 4))
        if feedback is not None:
            blend_at, q_s, mu = feedback
        received = np.flatnonzero(mask).tolist()
        prev = -1
        for t in received:
            if gap_factor is not None and prev >= 0 and t - prev > 1:  # dead reckoning over the gap
                out[prev + 1:t] = _predict_gap(out[prev], gyr[prev], t - prev - 1, dt, gap_factor)
                ahrs.set_quaternion(out[t - 1])
            prev = t
            if mag is None:
                ahrs.update_no_magnetometer(gyr_deg[t], acc_g[t])
            else:
                ahrs.update(gyr_deg[t], acc_g[t], mag[t])
            if feedback is not None and blend_at[t]:
                q = ahrs.get_quaternion().astype(float)
                q = _slerp(q_s[t], q / fixed_order.norm(q), mu[t])
                ahrs.set_quaternion(q)
                out[t] = q
            else:
                out[t] = ahrs.get_quaternion()
            out[t] /= fixed_order.norm(out[t])  # Fusion computes in float32
        if gap_factor is not None and 0 <= prev < n_t - 1:  # a gap at the end
            out[prev + 1:] = _predict_gap(out[prev], gyr[prev], n_t - 1 - prev, dt, gap_factor)
        return out

    return one


def fusion_ahrs(
    gyr,
    acc,
    mag=None,
    *,
    fs: float,
    received=None,
    gain: float = 0.5,
    settings: dict | None = None,
    hybrid: str | None = None,
    rho: float = 2.0,
    tau: float = 6.0,
    schedule: str = "decay",
    hold_window: int | None = None,
    gap: str = "hold",
    gap_time_constant: float | None = None,
    single_frame_gate: SingleFrameGate | bool | None = None,
) -> np.ndarray:
    """x-io Fusion AHRS (``imufusion.Ahrs``) over whole recordings, with packet loss, batched.

    Each batch element gets a fresh ``imufusion.Ahrs`` with ``convention =
    CONVENTION_ENU``, ``sample_rate = fs`` and the settings below, then one ``update`` (or
    ``update_no_magnetometer``) per received sample, gyroscope converted to °/s and
    accelerometer to g.  Lost samples make no call and hold the output (:mod:`wsnlib.orientation.peers`).
    Fusion's start-up is kept: its gain starts at 10 and falls linearly to ``gain`` over
    3 s of updates (150 received samples at 50 Hz), with rejection inactive meanwhile.

    Parameters
    ----------
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s², +g up at rest) in the body frame.
    mag : array_like, shape (..., T, 3), optional
        Magnetic field in the body frame (µT; Fusion uses the direction only).  ``None``:
        ``update_no_magnetometer`` (heading from the gyroscope, zeroed during start-up).
    fs : float
        Sampling rate (Hz), > 0: every received sample is integrated over 1/fs.
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read (they may hold NaN).  ``None``: all.
    gain : float
        Fusion's gain (rad/s per unit of the cross-product error, default 0.5, Fusion's
        default), >= 0: how strongly accelerometer and magnetometer correct the gyroscope.
    settings : dict, optional
        Overrides of the other ``imufusion.AhrsSettings`` fields (defaults, Fusion's own:
        every feature off):

        * ``"gyroscope_range"`` (°/s, default 0 = off): a gyroscope axis above 98 % of it
          restarts the start-up ramp (keeping the orientation);
        * ``"acceleration_rejection"`` (degrees, default 0 = off): the accelerometer is
          ignored while its direction disagrees with the estimated gravity by more than
          this (Fusion's README suggests 10°);
        * ``"magnetic_rejection"`` (degrees, default 0 = off): the same for the
          magnetometer's heading (README: 10°–20°);
        * ``"rejection_timeout"`` (s, default 0): after this long of rejection the sensor
          is used again (recovery); 0 switches both rejections off.  Counted in updates,
          i.e. in received samples × 1/fs.

        ``sample_rate`` (= ``fs``), ``convention`` (= ENU) and ``gain`` (its own argument)
        are not accepted here.
    hybrid : {None, "output", "feedback"}
        Paper 001's SLERP towards TRIAD after a gap (:mod:`wsnlib.orientation.peers`); needs ``mag``.
    rho, tau : float
        ρ, τ of eq. (3) (finite, > 0; default 2 and 6, μ = 1/2 at λ_eff = 12 samples).
    schedule : {"decay", "hold", "instant"}
        λ_eff after a gap (:func:`wsnlib.orientation.effective_lost_run`).
    hold_window : int, optional
        Received samples during which ``schedule="hold"`` keeps λ_eff (default 50); only
        with that schedule.
    gap : {"hold", "constant_rate"}
        On lost samples: hold the output (default), or keep turning it by the last received
        angular rate, the filter continuing from that prediction (:mod:`wsnlib.orientation.peers`; the
        semantics of :func:`wsnlib.orientation.estimate_orientation`).
    gap_time_constant : float, optional
        With ``"constant_rate"``: the extrapolated rate decays as ``exp(−t/τ)``, τ in s (> 0);
        ``None``: constant.
    single_frame_gate : SingleFrameGate or bool, optional
        With a hybrid: the gated hybrid, no blend on received samples whose TRIAD fails a
        check of :class:`wsnlib.orientation.SingleFrameGate` (``True``: default tolerances).

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth), ``...`` the broadcast of the leading dimensions
        of the signals and ``received``.  Lost samples hold the previous output (or the
        prediction, ``gap="constant_rate"``); samples before the first received one hold the
        output at it.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, a non-boolean ``received``, NaN/inf or a zero ``acc``/``mag`` vector in
        a received sample, ``fs`` <= 0, ``gain`` < 0, an unknown or negative setting, an
        unknown ``hybrid`` or ``schedule``, bad ρ, τ or ``hold_window``, ``mag`` None with
        a hybrid, an unknown ``gap``, a ``gap_time_constant`` <= 0 or without
        ``"constant_rate"``, a ``single_frame_gate`` without a hybrid or of the wrong type,
        or a batch element with no received sample.

    Notes
    -----
    Fusion computes in single precision: outputs are normalised again in double, and two
    runs on the same data agree exactly, but comparisons with double-precision filters
    should allow ~1e-6.
    """
    fs, signals, mask, batch = _prepare(gyr, acc, mag, fs, received)
    hybrid, rho, tau, schedule, window, gate = _hybrid_options(hybrid, mag, rho, tau, schedule, hold_window,
                                                               single_frame_gate)
    gap_factor = _gap_options(gap, gap_time_constant, fs)
    ahrs_settings = _fusion_settings(fs, gain, settings)
    feedback = (_feedback_inputs(signals, mask, rho, tau, schedule, window, gate, fs) if hybrid == "feedback"
                else None)
    quat = _run_batch(_fusion_one(ahrs_settings, 1.0 / fs, gap_factor), signals, mask, batch, feedback,
                      predict=gap_factor is not None)
    return _finish(quat, signals, mask, hybrid, rho, tau, schedule, window, gate, fs)
