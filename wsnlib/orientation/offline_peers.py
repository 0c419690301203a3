"""Offline peers of the smoother under packet loss: offline VQF and a forward–backward average.

:func:`wsnlib.orientation.smooth_orientation` uses samples after ``t`` to estimate sample
``t``; a fair comparison needs peers that may do the same.  Two, with wsnlib's conventions
(:mod:`wsnlib`) and the loss semantics of :mod:`wsnlib.orientation.peers`:

* :func:`offline_vqf_orientation`: ``vqf.offlineVQF`` (D. Laidig and T. Seel, "VQF: Highly
  accurate IMU orientation estimation with bias estimation and magnetic disturbance
  rejection", Information Fusion 91 (2023) 187–204; the package ``vqf`` 2.x), VQF's own
  acausal variant, on a recording whose lost samples are filled first;
* :func:`forward_backward_orientation`: any causal estimator run forwards and on the
  time-reversed recording, the two averaged per sample by a weighted SLERP.

Filling lost samples (offline VQF)
----------------------------------
``offlineVQF`` takes one evenly sampled array and has no notion of a missing sample, so every
lost sample between the first and the last received one gets a value before the call: each
axis of the gyroscope, accelerometer and magnetometer is interpolated linearly between the
last received sample before the gap and the first one after it (for the gyroscope this is
paper 001's gyroscope interpolation, the linear ramp :mod:`wsnlib.orientation.gaps` replays a
gap with; exact for a rate that is constant or changes linearly across the gap).  A linearly
interpolated vector is shorter than its ends when its direction turns; VQF's magnetic
disturbance check (``magNormTh``) may then reject filled magnetometer samples, which is what
it should do with a made-up field.

Samples before the first received one and after the last are not given to ``offlineVQF``:
they hold its output at the first (last) received sample, as :func:`vqf_orientation
<wsnlib.orientation.vqf_orientation>` outputs there.  This is what holding the nearest
received *signals* there would amount to, minus a contradiction: a held nonzero rate keeps
turning the estimate while the held accelerometer and magnetometer say it stands still, and
the acausal filter would carry that conflict into the received span.

Time reversal (forward–backward)
--------------------------------
A body-frame recording played backwards is again a body-frame recording: with
``q_r(s) = q(T − s)``, ``dq_r/ds = −dq/dt = ½ q_r ⊗ (−ω)``, so the reversed recording has the
samples in reverse order with the gyroscope *negated*; accelerometer and magnetometer (body
vectors at each instant) are reversed unchanged, and so is the loss mask.  The same sample
times are kept: a filter that integrates sample ``k``'s rate over the step before it lags by
half a sample forwards and leads by half a sample backwards, which the average cancels.  The
backward run's output, reversed back, is an estimate of the same ENU orientation when the
estimator uses a magnetometer (heading from the field); without one its heading is relative
to the *end* of the recording, unrelated to the forward run's, and the two cannot be averaged.

Average
-------
Per sample, ``q = SLERP(q_b, q_f, w_f)`` (the shorter arc: :func:`wsnlib.quaternion.slerp`
aligns the hemispheres first) with a weight that trusts each direction more where it has seen
a received sample recently: ``d_f`` (``d_b``) = samples since the last received sample at or
before (at or after) ``t``, plus 1, and ``w_f = d_b / (d_f + d_b)``.  On received samples
``d_f = d_b = 1`` and ``w_f = 1/2`` (the plain midpoint); inside a gap the weight moves
linearly from the forward run at the gap's start to the backward run at its end; before the
first received sample only the backward run (``w_f = 0``), after the last only the forward
run (``w_f = 1``).  Why weighted: with ``gap="constant_rate"`` each run extrapolates from its
own side of a gap and is worst at the far side, where the other run is best; on a 1-s gap
over a swing's turning point (``tests/test_offline_peers.py``) the plain midpoint is no
better than the forward run, the weighted average halves its error.  Each run's start-up
transient (a filter converging from its initial state) is *not* weighted down: it enters the
average at half weight.
"""

from __future__ import annotations

import numpy as np
import vqf

from wsnlib import quaternion as Q
from wsnlib.loss import last_received_index
from wsnlib.orientation.peers import _prepare, _vqf_params


def _fill_lost(signal: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Rows ``known[0]`` … ``known[-1]`` of ``signal`` ``(T, 3)``, the lost ones (not in the
    sorted indices ``known``) linearly interpolated between the received ones; contiguous float64."""
    index = np.arange(known[0], known[-1] + 1)
    values = signal[known]
    filled = np.empty((index.size, signal.shape[-1]))
    for axis in range(signal.shape[-1]):
        filled[:, axis] = np.interp(index, known, values[:, axis])
    return filled


def offline_vqf_orientation(gyr, acc, mag=None, *, fs: float, received=None, params: dict | None = None
                            ) -> np.ndarray:
    """VQF's offline (acausal) variant (``vqf.offlineVQF``) over whole recordings, with packet loss, batched.

    Lost samples are filled first by linear interpolation between the received samples around
    them (every axis of every sensor), because ``offlineVQF`` needs every sample of an evenly
    sampled recording (:mod:`wsnlib.orientation.offline_peers`).  Then each batch element's
    span from its first to its last received sample goes through one ``offlineVQF(gyr, acc,
    mag, 1/fs, params)`` call; samples outside the span hold the output at its end.  Frames as
    :func:`wsnlib.orientation.vqf_orientation`: ``quat9D`` with ``mag`` is wsnlib's ENU
    body → earth quaternion (y = magnetic north), no conversion; ``quat6D`` without ``mag``
    has z up and a heading fixed by the data.

    Parameters
    ----------
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s², +g up at rest) in the body frame.
    mag : array_like, shape (..., T, 3), optional
        Magnetic field in the body frame (µT; VQF accepts any unit).  ``None``: 6D output.
    fs : float
        Sampling rate (Hz), > 0: ``Ts = 1/fs`` for every sensor.
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read (they may hold NaN).  ``None``: all.
    params : dict, optional
        Overrides of ``VQFParams`` (the keys and defaults listed at
        :func:`wsnlib.orientation.vqf_orientation`); the sampling times come from ``fs``.

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth), ``...`` the broadcast of the leading dimensions
        of the signals and ``received``; an estimate on every sample, lost ones included
        (before the first received sample the output at it, after the last the output there).

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, a non-boolean ``received``, NaN/inf or a zero ``acc``/``mag`` vector in a
        received sample, ``fs`` <= 0, an unknown key in ``params`` (or a value VQF rejects),
        or a batch element with no received sample.
    """
    fs, signals, mask, batch = _prepare(gyr, acc, mag, fs, received)
    vqf_params = _vqf_params(params)
    key = "quat6D" if mag is None else "quat9D"
    out = np.empty(batch + (mask.shape[-1], 4))
    for idx in np.ndindex(*batch):
        known = np.flatnonzero(mask[idx])
        filled = {name: _fill_lost(signals[name][idx], known) for name in signals}
        try:
            result = vqf.offlineVQF(filled["gyr"], filled["acc"], filled.get("mag"), 1.0 / fs, vqf_params)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"params rejected by vqf.offlineVQF: {exc}") from exc
        first, last = known[0], known[-1]
        out[idx][first:last + 1] = result[key]
        out[idx][:first] = result[key][0]
        out[idx][last + 1:] = result[key][-1]
    return out


def _samples_since_received(mask: np.ndarray) -> np.ndarray:
    """Per sample, samples since the last received one at or before it, plus 1 (``inf`` before
    the first received sample); ``mask`` ``(..., T)``."""
    index = np.arange(mask.shape[-1])
    last = last_received_index(mask)
    return np.where(last < 0, np.inf, index - last + 1.0)


def _forward_weight(received) -> np.ndarray:
    """Weight ``w_f`` ``(..., T)`` of the forward run in :func:`forward_backward_orientation`:
    1/2 on received samples, linear across a gap, 0 before the first received sample and 1
    after the last.  ``received`` boolean ``(..., T)`` with a received sample in every batch
    element (checked by the caller)."""
    mask = np.asarray(received, dtype=bool)
    d_f = _samples_since_received(mask)
    d_b = _samples_since_received(mask[..., ::-1])[..., ::-1]
    with np.errstate(invalid="ignore"):  # inf/inf cannot occur: each element has a received sample
        return np.where(np.isinf(d_f), 0.0, np.where(np.isinf(d_b), 1.0, d_b / (d_f + d_b)))


def forward_backward_orientation(estimate, gyr, acc, mag=None, *, fs: float, received=None, **options
                                 ) -> np.ndarray:
    """A causal estimator run forwards and on the time-reversed recording, averaged per sample.

    ``estimate(gyr, acc, mag, fs=fs, received=received, **options)`` runs once on the
    recording and once on its time reversal (samples reversed, gyroscope negated, mask
    reversed), whose output is reversed back; the two are averaged per sample by
    ``SLERP(q_b, q_f, w_f)`` with ``w_f = d_b / (d_f + d_b)``, ``d_f`` (``d_b``) the samples
    since the last received sample at or before (at or after) each sample, plus 1: 1/2 on
    received samples, shifting linearly to the run that saw the nearer received sample inside
    a gap (module docstring :mod:`wsnlib.orientation.offline_peers`).

    Parameters
    ----------
    estimate : callable
        A whole-recording estimator with the signature of
        :func:`wsnlib.orientation.vqf_orientation` (``(gyr, acc, mag, *, fs, received,
        ...) -> (..., T, 4)`` ENU quaternions), e.g. ``vqf_orientation``,
        ``fusion_orientation`` or ``functools.partial(vqf_orientation, params=...)``.
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s²) in the body frame.
    mag : array_like, shape (..., T, 3)
        Magnetic field in the body frame (µT).  Required: it puts both runs' headings in the
        same ENU frame.
    fs : float
        Sampling rate (Hz), > 0.
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read.  ``None``: all.
    **options
        Passed to both runs of ``estimate`` (e.g. ``gap="constant_rate"``).

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth), ``...`` the broadcast of the leading dimensions
        of the signals and ``received``.

    Raises
    ------
    ValueError
        ``estimate`` not callable, ``mag`` None (a 6D backward run's heading is relative to
        the recording's end, unrelated to the forward run's), what the peers refuse of the
        signals (wrong shapes, mismatched T, leading dimensions that do not broadcast, a
        non-boolean ``received``, NaN/inf or a zero ``acc``/``mag`` vector in a received
        sample, ``fs`` <= 0, a batch element with no received sample), what ``estimate``
        refuses of ``options``, or an output of ``estimate`` that is not ``(..., T, 4)``.
    """
    if not callable(estimate):
        raise ValueError(f"estimate must be a callable orientation estimator, got {type(estimate).__name__}")
    if mag is None:
        raise ValueError("forward_backward_orientation needs mag: without a magnetometer the backward run's "
                         "heading is relative to the end of the recording and cannot be averaged with the "
                         "forward run's")
    fs, signals, mask, batch = _prepare(gyr, acc, mag, fs, received)
    expected = batch + (mask.shape[-1], 4)
    forward = estimate(signals["gyr"], signals["acc"], signals["mag"], fs=fs, received=mask, **options)
    backward = estimate(-signals["gyr"][..., ::-1, :], signals["acc"][..., ::-1, :], signals["mag"][..., ::-1, :],
                        fs=fs, received=mask[..., ::-1], **options)
    for name, quat in (("forward", forward), ("backward", backward)):
        if np.shape(quat) != expected:
            raise ValueError(f"estimate returned shape {np.shape(quat)} on the {name} run, expected {expected}")
    return Q.slerp(np.asarray(backward)[..., ::-1, :], forward, _forward_weight(mask))
