"""VQF (Laidig & Seel 2023, package ``vqf``) as a wsnlib orientation filter under packet loss.

:func:`vqf_orientation`.  Loss semantics, frames, the hybrid (and why it writes ``gyrQuat``) and
gap prediction: :mod:`wsnlib.orientation.peers`.
"""

from __future__ import annotations

import numpy as np
import vqf

from wsnlib import fixed_order
from wsnlib import quaternion as Q
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


def _vqf_params(params) -> dict:
    if params is None:
        return {}
    if not isinstance(params, dict):
        raise ValueError(f"params must be a dict of VQF parameters, got {type(params).__name__}")
    known = vqf.VQF(1.0).params
    for key in params:
        if key in ("gyrTs", "accTs", "magTs"):
            raise ValueError(f"params[{key!r}] is set from fs; leave it out")
        if key not in known:
            raise ValueError(f"params has unknown key {key!r}; known: {', '.join(sorted(known))}")
    return dict(params)


def _pieces(mask: np.ndarray, blend_at) -> tuple[np.ndarray, np.ndarray]:
    """Starts and ends of the runs of received samples, also cut after every blended sample."""
    prev = np.concatenate(([False], mask[:-1]))
    nxt = np.concatenate((mask[1:], [False]))
    cut = np.zeros_like(mask) if blend_at is None else blend_at
    prev_cut = np.concatenate(([False], cut[:-1]))
    starts = np.flatnonzero(mask & (~prev | prev_cut))
    ends = np.flatnonzero(mask & (~nxt | cut)) + 1
    return starts, ends


def _vqf_set_quat9d(filt, q_f: np.ndarray, use_mag: bool = True) -> None:
    """Make ``filt``'s 9D output (6D without ``use_mag``) ``q_f`` by replacing ``gyrQuat``.

    Why ``gyrQuat`` and not ``accQuat``: :mod:`wsnlib.orientation.peers`.
    """
    state = filt.state
    half = -0.5 * state["delta"] if use_mag else 0.0
    undo_delta = np.array([np.cos(half), 0.0, 0.0, np.sin(half)])
    gyr_quat = Q.multiply(Q.conjugate(np.asarray(state["accQuat"])), Q.multiply(undo_delta, q_f))
    state["gyrQuat"] = gyr_quat / fixed_order.norm(gyr_quat)
    filt.state = state


def _vqf_one(fs: float, params: dict, gap_factor=None):
    def one(gyr, acc, mag, mask, feedback):
        try:
            filt = vqf.VQF(1.0 / fs, **params)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"params rejected by vqf.VQF: {exc}") from exc
        key = "quat6D" if mag is None else "quat9D"
        out = np.empty((mask.shape[-1], 4))
        blend_at, q_s, mu = (None, None, None) if feedback is None else feedback
        prev = -1  # last received sample
        for start, end in zip(*_pieces(mask, blend_at), strict=True):
            if gap_factor is not None and prev >= 0 and start - prev > 1:  # dead reckoning over the gap
                out[prev + 1:start] = _predict_gap(out[prev], gyr[prev], start - prev - 1, 1.0 / fs, gap_factor)
                _vqf_set_quat9d(filt, out[start - 1], mag is not None)
            prev = end - 1
            piece = filt.updateBatch(gyr[start:end], acc[start:end], None if mag is None else mag[start:end])
            out[start:end] = piece[key]
            last = end - 1
            if feedback is not None and blend_at[last]:
                out[last] = _slerp(q_s[last], out[last], mu[last])
                _vqf_set_quat9d(filt, out[last])
        n_t = mask.shape[-1]
        if gap_factor is not None and 0 <= prev < n_t - 1:  # a gap at the end
            out[prev + 1:] = _predict_gap(out[prev], gyr[prev], n_t - 1 - prev, 1.0 / fs, gap_factor)
        return out

    return one


def vqf_orientation(
    gyr,
    acc,
    mag=None,
    *,
    fs: float,
    received=None,
    params: dict | None = None,
    hybrid: str | None = None,
    rho: float = 2.0,
    tau: float = 6.0,
    schedule: str = "decay",
    hold_window: int | None = None,
    gap: str = "hold",
    gap_time_constant: float | None = None,
    single_frame_gate: SingleFrameGate | bool | None = None,
) -> np.ndarray:
    """VQF (Laidig & Seel 2023, ``vqf.VQF``) over whole recordings, with packet loss, batched.

    Each batch element gets a fresh ``vqf.VQF(1/fs, **params)``; every contiguous run of
    received samples goes through one ``updateBatch`` call, the state carrying over between
    calls, which is exactly "lost samples are skipped, the next received one uses the
    nominal Ts".  The output is ``quat9D`` with ``mag``, ``quat6D`` without.  This is the
    causal (online) filter; ``vqf.offlineVQF`` (acausal) is not used.

    Parameters
    ----------
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s²) in the body frame; VQF uses these
        units as given (rest detection and bias estimation thresholds are in them).
    mag : array_like, shape (..., T, 3), optional
        Magnetic field in the body frame (µT; VQF accepts any unit).  ``None``: 6D output,
        heading relative to the start.
    fs : float
        Sampling rate (Hz), > 0; VQF's ``gyrTs = 1/fs`` (accelerometer and magnetometer
        the same).
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read.  ``None``: all.
    params : dict, optional
        Overrides of ``VQFParams`` (``vqf.VQF`` keyword arguments); VQF's defaults:
        ``tauAcc`` 3.0 s, ``tauMag`` 9.0 s (inclination and heading correction time
        constants), ``motionBiasEstEnabled`` True, ``restBiasEstEnabled`` True,
        ``magDistRejectionEnabled`` True, ``biasSigmaInit`` 0.5 °/s,
        ``biasForgettingTime`` 100 s, ``biasClip`` 2 °/s, ``biasSigmaMotion`` 0.1 °/s,
        ``biasVerticalForgettingFactor`` 1e-4, ``biasSigmaRest`` 0.03 °/s, ``restMinT``
        1.5 s, ``restFilterTau`` 0.5 s, ``restThGyr`` 2 °/s, ``restThAcc`` 0.5 m/s²,
        ``magCurrentTau`` 0.05 s, ``magRefTau`` 20 s, ``magNormTh`` 0.1 (relative),
        ``magDipTh`` 10°, ``magNewTime`` 20 s, ``magNewFirstTime`` 5 s, ``magNewMinGyr``
        20 °/s, ``magMinUndisturbedTime`` 0.5 s, ``magMaxRejectionTime`` 60 s,
        ``magRejectionFactor`` 2.  Times are counted in received samples × Ts.  The
        sampling times come from ``fs`` and are not accepted here.
    hybrid : {None, "output", "feedback"}
        Paper 001's SLERP towards TRIAD after a gap (:mod:`wsnlib.orientation.peers`); needs ``mag``.
    rho, tau : float
        ρ, τ of eq. (3) (finite, > 0; default 2 and 6).
    schedule : {"decay", "hold", "instant"}
        λ_eff after a gap (:func:`wsnlib.orientation.effective_lost_run`).
    hold_window : int, optional
        For ``schedule="hold"`` only (default 50 received samples).
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
        ENU unit quaternions (body → earth; y = magnetic north with ``mag``).  Lost samples
        hold the previous output (or the prediction, ``gap="constant_rate"``); samples
        before the first received one hold the output at it.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, a non-boolean ``received``, NaN/inf or a zero ``acc``/``mag`` vector in
        a received sample, ``fs`` <= 0, an unknown key in ``params`` (or a value VQF
        rejects), an unknown ``hybrid`` or ``schedule``, bad ρ, τ or ``hold_window``,
        ``mag`` None with a hybrid, an unknown ``gap``, a ``gap_time_constant`` <= 0 or
        without ``"constant_rate"``, a ``single_frame_gate`` without a hybrid or of the
        wrong type, or a batch element with no received sample.
    """
    fs, signals, mask, batch = _prepare(gyr, acc, mag, fs, received)
    hybrid, rho, tau, schedule, window, gate = _hybrid_options(hybrid, mag, rho, tau, schedule, hold_window,
                                                               single_frame_gate)
    vqf_params = _vqf_params(params)
    gap_factor = _gap_options(gap, gap_time_constant, fs)
    feedback = (_feedback_inputs(signals, mask, rho, tau, schedule, window, gate, fs) if hybrid == "feedback"
                else None)
    quat = _run_batch(_vqf_one(fs, vqf_params, gap_factor), signals, mask, batch, feedback,
                      predict=gap_factor is not None)
    return _finish(quat, signals, mask, hybrid, rho, tau, schedule, window, gate, fs)
