"""Peer orientation filters under packet loss: x-io Fusion and VQF, with paper 001's hybrid.

Two published filters a user may run instead of Madgwick's, fed the same received samples,
with wsnlib's conventions (:mod:`wsnlib`) and :func:`wsnlib.orientation.madgwick`'s loss
semantics:

* :func:`fusion_orientation`: x-io Technologies' Fusion (S. Madgwick's revised AHRS, a
  complementary filter with gain ramp-down at start-up and optional acceleration and
  magnetic rejection), through its Python package ``imufusion`` (1.3.x);
* :func:`vqf_orientation`: VQF, D. Laidig and T. Seel, "VQF: Highly accurate IMU
  orientation estimation with bias estimation and magnetic disturbance rejection",
  Information Fusion 91 (2023) 187–204, through its package ``vqf`` (2.x).

Loss semantics
--------------
Only received samples reach the filter: a lost sample makes no call and its output is the
previous output; the next received sample is integrated over the nominal Δt = 1/fs (the
receiver does not know how much time went by, paper 001 Sec. II).  Both libraries start
from their own initial state (identity, then Fusion's start-up ramp or VQF's averaging
initialisation) at a batch element's first received sample; before that sample the output
is the output at that sample, as :func:`wsnlib.orientation.madgwick` outputs its initial
estimate there.  Gaps before the first received sample are no gaps of the filter (λ_eff = 0
there, as for Madgwick with ``q0=None``).  Batches loop over elements in Python (each
library runs one recording at a time); each runs a contiguous run of received samples in one
compiled loop of its own C or C++ update, which gives the bits of its Python calls
(:mod:`wsnlib.orientation._fusion_updates`, :mod:`wsnlib.orientation._vqf_updates`: Fusion's Python
package has no batch call, and VQF's ``updateBatch`` from Python costs ~15 µs a call).

Frames (established by static tests at several orientations, ``tests/test_peers.py``)
-------------------------------------------------------------------------------------
* Fusion's quaternion rotates body vectors into the earth frame, ``[w, x, y, z]``, with
  ``convention = imufusion.CONVENTION_ENU`` exactly wsnlib's ENU (y = magnetic north: its
  magnetometer feedback aligns gravity × field with west).  No conversion.  In imufusion
  1.3.3 ``AhrsSettings(convention=...)`` silently ignores the convention argument (the
  result stays NWU, 90° off in heading); the attribute setter works, so the wrapper sets
  every field through attributes and checks the convention read back.
* VQF's 9D quaternion ``q = q_z(δ) ⊗ accQuat ⊗ gyrQuat`` rotates body vectors into an ENU
  frame whose y axis is magnetic north (its heading correction drives
  ``atan2(m_E,x, m_E,y)`` to 0); exactly wsnlib's.  No conversion.  The 6D quaternion
  (``mag=None``) is relative to a frame with z up and a heading fixed by the start, as
  Madgwick's IMU form.

Loss options
------------
The vocabulary of every filter of :mod:`wsnlib.orientation`: ``gap`` ("hold",
"constant_rate" or "ar"), ``replay``, ``output_on_lost``, ``gap_time_constant``, the AR
predictor's ``gap_rate_prediction_span_s`` and ``gap_rate_prediction_window_s`` (the fields of
:class:`wsnlib.orientation.KalmanSettings`, keywords here), and the hybrid as ``blend`` with
ρ, τ, ``schedule``, ``hold_window`` and ``single_frame_gate``.  The defaults differ from the
Kalman filter's: ``gap="hold"``, ``replay=False`` (the libraries as published) and
``gap_time_constant=None`` = a constant rate.

Hybrid
------
``blend="output"``: the peer runs untouched and its output goes through
:func:`wsnlib.orientation.hybrid_blend.blend_with_single_frame`: ``q_f = SLERP(q_s, q_d,
μ(λ_eff))`` on received samples with λ_eff > 0, ``q_s`` TRIAD of the sample.
``blend="feedback"``: ``q_f`` also replaces the filter's orientation after each such
update, so that the state itself is pulled towards TRIAD.  Both libraries allow it:

* Fusion: its quaternion becomes ``q_f`` (what ``Ahrs.set_quaternion`` does; the compiled loop of
  :mod:`wsnlib.orientation._fusion_updates` writes it in place); nothing else of its state is orientation.
* VQF: the ``state`` property is writable (a dict).  ``gyrQuat`` (body → the
  almost-inertial frame I_i of the strapdown integration) is set to
  ``accQuat* ⊗ q_z(−δ) ⊗ q_f``, so that the 9D output ``q_z(δ) ⊗ accQuat ⊗ gyrQuat``
  becomes ``q_f``; ``accQuat`` and δ (the magnetic heading offset) stay.  Not ``accQuat``:
  VQF low-pass filters the accelerometer in I_i and recomputes ``accQuat`` at every update
  as the full rotation that makes that filtered vector vertical, so an inclination written
  into ``accQuat`` is undone by the next update, while one written into ``gyrQuat`` is
  consistent with the filtered vector and persists.

Both blend inside their compiled loops (:mod:`wsnlib.orientation._fusion_updates`,
:mod:`wsnlib.orientation._vqf_updates`, which writes VQF's ``gyrQuat`` in place).
``single_frame_gate`` makes either hybrid the *gated hybrid*: no blend on received samples
whose TRIAD looks untrustworthy (:class:`wsnlib.orientation.SingleFrameGate`).

Gap prediction
--------------
The rates of a gap come from :mod:`wsnlib.orientation.gaps` (the Kalman filter's and
Madgwick's gap module; one call of :func:`~wsnlib.orientation.gaps.gap_rates` per gap, the
same compiled functions their loops call per sample).  The rate a peer "used" on a received
sample is its **raw gyroscope** (body frame, rad/s), for both peers: Fusion's AHRS has no bias
estimate, and VQF's ``updateGyr`` subtracts its own bias estimate from whatever rate it is
given, so gap rates on the raw scale are what it expects (a bias-corrected history would have
to get the bias added back, and would make the two peers' histories differ).  The rate
history holds these from the first received sample on, and on lost samples the rates the gap
module gave (the prediction, not the replay).

* ``gap="hold"`` (default): the output is held.
* ``gap="constant_rate"`` (as in :func:`wsnlib.orientation.estimate_orientation`): on a lost
  sample the estimate is the last received output turned on by the last received angular
  rate, ``q_k = q_last ⊗ Exp(ω Δt Σ_{j≤k} f^j)`` with ``f = 1`` or ``f = exp(−Δt/τ)``
  (``gap_time_constant`` τ); the rotation is about one body axis, so this is exact for that
  rate.  Without ``replay``, at the next received sample the filter's orientation is set to
  the last prediction (Fusion: ``set_quaternion``; VQF: ``gyrQuat``, as for the feedback
  hybrid) and the library updates from there.
* ``gap="ar"``: the per-axis linear (autoregressive) prediction of the rate fitted at the
  gap's start on the last ``gap_rate_prediction_window_s`` (default 6 s) of the history, of
  order ``round(gap_rate_prediction_span_s · fs)`` (default 0.96 s; at most 64), as the Kalman
  filter's; with less than a window of history it falls back to ``"constant_rate"`` (decaying
  with ``gap_time_constant``).  Fusion: the output is integrated sample by sample from the
  last output, ``q_k = q_{k−1} ⊗ Exp(ω_k Δt)``, and ``set_quaternion`` at the gap's end.  VQF:
  ``updateGyr(ω_k)`` on every lost sample (VQF's own strapdown integration, bias-corrected
  inside; its rest detector's gyroscope low-pass sees these rates too), output ``quat9D``
  (``quat6D`` without ``mag``); the next received sample updates from that state.
* ``replay=True`` (with any ``gap``): at the first received sample after a gap of L samples,
  the gap is re-run with the gap module's replay rates — with ``"ar"`` the predicted rates
  plus the end correction (:func:`~wsnlib.orientation.gaps.ar_end_weights`), otherwise (and
  when the AR fit fell back) the linear ramp between the last received rate and the new
  one (paper 001's gyroscope interpolation) — from the state at the gap's start, then the
  received sample is updated as usual.  Fusion: the replay rates are integrated from the
  output at the gap's start and ``set_quaternion`` sets the result (``imufusion.Ahrs`` cannot
  be copied: its start-up ramp and its rejection timers are not restored, they stay as they
  were, which for a gap that made no calls is the same).  VQF: ``filt.state`` (a snapshot: each
  read builds a new dict of new lists from the C++ state) is saved at the gap's start, restored at
  its end and ``updateGyr`` runs the L replay rates.
  The replay is causal: the outputs on the lost samples are those without replay.

A gap before the first received sample is held whatever ``gap`` (the filter has not
started); a gap at the end of the recording is predicted, never replayed.  With
``output_on_lost="hold"`` the output on lost samples is the previous output whatever ``gap``.
"""

from __future__ import annotations

import math

import imufusion
import numpy as np
import vqf
from numba import njit

from wsnlib import fixed_order
from wsnlib._validation import check_flag, check_nonnegative, check_positive
from wsnlib.frames import STANDARD_GRAVITY
from wsnlib.loss import last_received_index
from wsnlib.orientation import _batch as B
from wsnlib.orientation import gaps
from wsnlib.orientation._fusion_updates import FusionUpdates
from wsnlib.orientation._scalar_kernels import (
    COMPILE,
    integrate_rates,
    quat_multiply,
)
from wsnlib.orientation._vqf_updates import VQFUpdates
from wsnlib.orientation.hybrid_blend import blend_with_single_frame, check_single_frame_gate, trusted_unchecked
from wsnlib.orientation.kalman_settings import gap_prediction_window
from wsnlib.orientation.lost_run import check_weight_options, effective_lost_run, slerp_weight
from wsnlib.orientation.triad import triad

# --------------------------------------------------------------------------------------------
# Validation shared by both wrappers
# --------------------------------------------------------------------------------------------


def _prepare(gyr, acc, mag, fs, received):
    """Checked, broadcast signals ``(*batch, T, 3)`` and mask ``(*batch, T)``."""
    fs = check_positive(fs, "fs")
    signals, mask, _, shapes = B.check_inputs(gyr, acc, mag, received)
    n_t = signals["gyr"].shape[-2]
    batch = B.broadcast_batch(shapes)
    mask = B.check_usable(signals, mask)  # NaN/inf (zero acc, mag) in received samples; implausible ones lost
    mask = np.broadcast_to(mask, batch + (n_t,))
    has_sample = mask.any(axis=-1)
    if not np.all(has_sample):
        bad = tuple(int(i) for i in np.argwhere(~has_sample)[0])
        raise ValueError(f"received has no received sample for batch element {bad}: the output is undefined there")
    signals = {name: np.broadcast_to(arr, batch + (n_t, 3)) for name, arr in signals.items()}
    return fs, signals, mask, batch


@njit(**COMPILE)
def _predict_gap(q_last, omega, n_lost, dt, factor):
    """``(n_lost, 4)``: ``q_last ⊗ Exp(ω Δt Σ_{j≤k} f^j)``, k = 1 … n_lost (:mod:`wsnlib.orientation.peers`);
    ``q_last`` (4,), ``omega`` (3,) rad/s, ``dt`` s, ``factor`` f (1: a constant rate).

    Compiled (a peer's gap cost ~60 µs in numpy's small-array calls, ~3 µs here), with the operations of
    :func:`wsnlib.quaternion.from_rotation_vector` and :func:`wsnlib.quaternion.multiply` in their order:
    ``‖t‖ = √((t_x² + t_y²) + t_z²)`` (numpy's sum of three), ``sin(θ/2)/θ`` as ``np.sinc`` forms it
    (``y = π · ((θ/2)/π)``, ``½ sin(y)/y``, 1e-20 for 0), ``f^k`` by ``pow``: the same bits."""
    out = np.empty((n_lost, 4))
    q = (q_last[0], q_last[1], q_last[2], q_last[3])
    step = (omega[0] * dt, omega[1] * dt, omega[2] * dt)
    for i in range(n_lost):
        k = i + 1.0
        weight = k if factor == 1.0 else factor * (1.0 - math.pow(factor, k)) / (1.0 - factor)
        turn = (step[0] * weight, step[1] * weight, step[2] * weight)
        half = 0.5 * math.sqrt((turn[0] * turn[0] + turn[1] * turn[1]) + turn[2] * turn[2])
        x = half / math.pi
        y = math.pi * (x if x != 0.0 else 1.0e-20)
        scale = 0.5 * (math.sin(y) / y)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = quat_multiply(
            q, (math.cos(half), scale * turn[0], scale * turn[1], scale * turn[2]))
    return out


def _integrate(q_start, rates, dt: float) -> np.ndarray:
    """``(L, 4)``: ``q_k = q_{k−1} ⊗ Exp(ω_k Δt)`` from ``q_0 = q_start``, one step per row of ``rates`` (L, 3)."""
    out = np.empty((rates.shape[0], 4))
    integrate_rates(np.asarray(q_start, dtype=float), np.asarray(rates, dtype=float), dt, out)
    return out


class _GapRates:
    """The gap options of a peer call as :mod:`wsnlib.orientation.gaps` settings.

    ``gap`` the name, ``factor`` the per-sample decay of a held rate (None with ``"hold"``),
    ``replay``; ``tracked``: the call keeps a rate history and asks :func:`gaps.gap_rates`
    for the gap's rates (``gap="ar"`` or ``replay``), else the closed-form paths of
    :func:`_predict_gap` (unchanged results for ``"hold"``/``"constant_rate"``).
    """

    def __init__(self, gap, factor, replay, order, window):
        self.gap, self.factor, self.replay = gap, factor, replay
        self.tracked = gap == "ar" or replay
        self._settings = (gaps.GAP_CODES[gap], 1.0 if factor is None else factor, order, window)

    def rates(self, history, n_lost: int, measured) -> tuple[np.ndarray, np.ndarray]:
        """``(predicted, replayed)`` ``(n_lost, 3)`` rad/s of a gap after the rate ``history`` (n, 3)
        that ends at the rate ``measured`` (None: at the recording's end)."""
        # A copy: a read-only row (a broadcast recording's) would make numba compile gap_rates a second time.
        measured = np.zeros(3) if measured is None else np.array(measured, dtype=float)
        return gaps.gap_rates(np.ascontiguousarray(history), n_lost, measured, *self._settings)


def _feedback_inputs(signals, mask, rho, tau, schedule, window, gate=None, fs=None):
    """Where the feedback blends ``(*batch, T)``, TRIAD there ``(*batch, T, 4)`` and μ ``(*batch, T)``."""
    started_gap = mask | ~np.logical_or.accumulate(mask, axis=-1)  # no gap before the first sample
    lam = effective_lost_run(started_gap, schedule, window)
    blend_at = mask & (lam > 0.0)
    if gate is not None:
        blend_at &= trusted_unchecked(signals, mask, mask.shape[:-1], gate.vector(fs))
    q_s = np.zeros(mask.shape + (4,))
    q_s[..., 0] = 1.0
    if blend_at.any():
        q_s[blend_at] = triad(signals["acc"][blend_at], signals["mag"][blend_at])
    return blend_at, q_s, slerp_weight(lam, rho, tau)


def _hold(out: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Rows of ``out`` ``(T, 4)`` filled on received samples: lost ones take the last received
    row, those before the first received sample the first one."""
    return out[last_received_index(mask, backfill=True)]


def _run_batch(one, signals, mask, batch, feedback, predict=False):
    """``one(gyr, acc, mag, mask, fb)`` on every batch element; ``(*batch, T, 4)``.  With ``predict``
    ``one`` fills the lost samples after the first received one itself."""
    n_t = mask.shape[-1]
    out = np.empty(batch + (n_t, 4))
    for idx in np.ndindex(*batch):
        gyr, acc = (np.ascontiguousarray(signals[name][idx]) for name in ("gyr", "acc"))
        mag = np.ascontiguousarray(signals["mag"][idx]) if "mag" in signals else None
        fb = None if feedback is None else tuple(x[idx] for x in feedback)
        filled = np.logical_or.accumulate(mask[idx]) if predict else mask[idx]
        out[idx] = _hold(one(gyr, acc, mag, mask[idx], fb), filled)
    return out


class _Options:
    """The checked loss options of a peer call (:mod:`wsnlib.orientation`'s vocabulary)."""

    def __init__(self, filter_name, mag, fs, gap, replay, output_on_lost, gap_time_constant, span_s, window_s,
                 blend, rho, tau, schedule, hold_window, single_frame_gate):
        gap, gap_time_constant = B.check_gap(gap, gap_time_constant, filter_name, supported=B.GAPS)
        self.gap_factor = None if gap == "hold" else B.rate_factor(gap_time_constant, fs)
        order, window = gap_prediction_window(gap, span_s, window_s, fs, filter_name)
        self.gap = _GapRates(gap, self.gap_factor, check_flag(replay, "replay"), order, window)
        self.hold_output = B.check_output_on_lost(output_on_lost)
        self.blend = B.check_blend(blend, mag, filter_name)
        if self.blend is None:
            B.refuse_unused(filter_name, "without blend", rho=rho, tau=tau, schedule=schedule,
                            hold_window=hold_window, single_frame_gate=single_frame_gate)
        self.gate = check_single_frame_gate(single_frame_gate)
        self.rho, self.tau, self.schedule, self.window = check_weight_options(rho, tau, schedule, hold_window)
        for name, value in (("rho", self.rho), ("tau", self.tau), ("hold_window", self.window)):
            if value is not None and value.ndim:
                raise ValueError(f"{name} must be one number here, got {value!r}")
        self.fs = fs

    def feedback(self, signals, mask):
        """The feedback hybrid's inputs (:func:`_feedback_inputs`), or None."""
        if self.blend != "feedback":
            return None
        return _feedback_inputs(signals, mask, self.rho, self.tau, self.schedule, self.window, self.gate, self.fs)

    def finish(self, quat, signals, mask):
        """The output hybrid and the output on lost samples, on the peer's output."""
        if self.blend == "output":
            extra = {} if self.gate is None else {"single_frame_gate": self.gate, "gyr": signals["gyr"],
                                                  "fs": self.fs}
            quat = blend_with_single_frame(quat, signals["acc"], signals["mag"], mask, rho=self.rho, tau=self.tau,
                                           schedule=self.schedule,
                                           hold_window=None if self.window is None else int(self.window), **extra)
        if self.hold_output:
            B.hold_lost_output(quat, mask)
        return quat


# --------------------------------------------------------------------------------------------
# x-io Fusion (imufusion)
# --------------------------------------------------------------------------------------------

#: Fields of ``imufusion.AhrsSettings`` a caller may set through ``settings``, with
#: Fusion's defaults (all switch the feature off); see :func:`fusion_orientation` for units.
FUSION_DEFAULT_SETTINGS = {
    "gyroscope_range": 0.0,
    "acceleration_rejection": 0.0,
    "magnetic_rejection": 0.0,
    "rejection_timeout": 0.0,
}

def _fusion_settings(fs: float, gain, settings) -> imufusion.AhrsSettings:
    values = dict(FUSION_DEFAULT_SETTINGS)
    if settings is not None:
        if not isinstance(settings, dict):
            raise ValueError(f"settings must be a dict of imufusion.AhrsSettings fields, got {type(settings).__name__}")
        for key, value in settings.items():
            if key in ("sample_rate", "convention", "gain"):
                raise ValueError(f"settings[{key!r}] is set by fusion_orientation (fs, ENU, gain=); leave it out")
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


def _fusion_one(settings, dt, gap: _GapRates):
    gap_factor = gap.factor

    def one(gyr, acc, mag, mask, feedback):
        ahrs = imufusion.Ahrs()
        ahrs.set_settings(settings)
        n_t = mask.shape[-1]
        out = np.empty((n_t, 4))
        updates = FusionUpdates(ahrs, np.degrees(gyr), acc / STANDARD_GRAVITY, mag, out, feedback)  # Fusion takes g
        normalised = np.zeros(n_t, dtype=bool)  # Fusion computes in float32: each output row normalised once

        def normalise(t):
            out[t] /= fixed_order.norm(out[t])
            normalised[t] = True

        used = None
        if gap.tracked:  # the rate history (gaps module): the raw gyroscope, and each gap's rates once filled
            used = np.empty((n_t, 3))
            used[mask] = gyr[mask]
        first = int(np.argmax(mask))

        def fill_gap(prev, stop, measured):
            """Outputs on the lost samples ``prev + 1 … stop − 1`` and (``measured``: the rate of the
            received sample ``stop``) the quaternion the filter continues from at ``stop``."""
            normalise(prev)
            predicted, replayed = gap.rates(used[first:prev + 1], stop - prev - 1, measured)
            used[prev + 1:stop] = predicted
            if gap.gap == "ar":
                out[prev + 1:stop] = _integrate(out[prev], predicted, dt)
            elif gap_factor is not None:  # the same outputs as without replay
                out[prev + 1:stop] = _predict_gap(out[prev], gyr[prev], stop - prev - 1, dt, gap_factor)
            if measured is not None:
                if gap.replay:
                    ahrs.set_quaternion(_integrate(out[prev], replayed, dt)[-1])
                elif gap.gap == "ar":
                    ahrs.set_quaternion(out[stop - 1])

        prev = -1  # last received sample
        # Runs of received samples, each a loop of updates (and the feedback hybrid's blends).
        for start, end in zip(*_pieces(mask), strict=True):
            if prev >= 0 and start - prev > 1:
                if gap.tracked:
                    fill_gap(prev, start, gyr[start])
                elif gap_factor is not None:  # dead reckoning over the gap
                    normalise(prev)
                    out[prev + 1:start] = _predict_gap(out[prev], gyr[prev], start - prev - 1, dt, gap_factor)
                    ahrs.set_quaternion(out[start - 1])
            updates.run(start, end)
            prev = end - 1
        if gap.tracked and gap_factor is not None and prev < n_t - 1:  # a gap at the end
            fill_gap(prev, n_t, None)
        elif gap_factor is not None and 0 <= prev < n_t - 1:
            normalise(prev)
            out[prev + 1:] = _predict_gap(out[prev], gyr[prev], n_t - 1 - prev, dt, gap_factor)
        rest = mask & ~normalised  # the others at once: the same arithmetic per row, vectorised
        out[rest] /= fixed_order.norm(out[rest])[:, None]
        return out

    return one


def fusion_orientation(gyr, acc, mag=None, *, fs: float, received=None, gain: float = 0.5,
                       settings: dict | None = None, gap: str = "hold", replay: bool = False,
                       output_on_lost: str = "estimate", gap_time_constant=None, gap_rate_prediction_span_s=None,
                       gap_rate_prediction_window_s=None, blend: str | None = None, rho=None, tau=None,
                       schedule=None, hold_window=None, single_frame_gate=None) -> np.ndarray:
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
    gap : {"hold", "constant_rate", "ar"}
        In a gap: hold (default); keep turning by the last received angular rate (raw
        gyroscope); or by the linear (autoregressive) prediction of the rate, the filter
        continuing from that prediction (module docstring, "Gap prediction").
    replay : bool
        At the first received sample after a gap, re-run the gap from the state at its start
        with the rates now known at both ends (``"ar"``: prediction plus end correction;
        else the linear ramp between the rates around the gap), then update.  Causal: the
        outputs on lost samples do not change.  Default False.
    output_on_lost : {"estimate", "hold"}
        On lost samples: the estimate (the prediction with ``"constant_rate"`` or ``"ar"``),
        or the previous output.
    gap_time_constant : float, optional
        With ``"constant_rate"`` (and ``"ar"`` where it falls back): the extrapolated rate
        decays as ``exp(−t/τ)``, τ in s (> 0); ``None`` or ``inf``: constant.
    gap_rate_prediction_span_s, gap_rate_prediction_window_s : float, optional
        Only with ``gap="ar"``: how far back (s, > 0) the predictor looks (its order,
        ``round(span · fs)`` in [1, 64]) and the length (s, > 0) of the rate history it is
        fitted on.  ``None``: :class:`wsnlib.orientation.KalmanSettings`' defaults (0.96 s, 6 s).
    blend : {None, "output", "feedback"}
        Paper 001's SLERP towards TRIAD after a gap (module docstring); needs ``mag``.
    rho, tau : float, optional
        ρ, τ of eq. (3) (finite, > 0; default 2 and 6, μ = 1/2 at λ_eff = 12 samples); only
        with ``blend``.
    schedule : {"decay", "hold", "instant"}, optional
        λ_eff after a gap (:func:`wsnlib.orientation.lost_run.effective_lost_run`; default
        ``"decay"``); only with ``blend``.
    hold_window : int, optional
        Received samples during which ``schedule="hold"`` keeps λ_eff (default 50); only
        with that schedule.
    single_frame_gate : SingleFrameGate or bool, optional
        With ``blend``: the gated hybrid, no blend on received samples whose TRIAD fails a
        check of :class:`wsnlib.orientation.SingleFrameGate` (``True``: default tolerances).

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth), ``...`` the broadcast of the leading dimensions
        of the signals and ``received``.  Lost samples hold the previous output (or the
        prediction, ``gap="constant_rate"`` or ``"ar"``, unless ``output_on_lost="hold"``);
        samples before the first received one hold the output at it.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, a non-boolean ``received``, NaN/inf or a zero ``acc``/``mag`` vector in
        a received sample, ``fs`` <= 0, ``gain`` < 0, an unknown or negative setting, an
        unknown ``blend``, ``schedule``, ``gap`` or ``output_on_lost``, a non-boolean
        ``replay``, bad ρ, τ or ``hold_window``, ``mag`` None with ``blend``, ρ, τ,
        ``schedule``, ``hold_window`` or ``single_frame_gate`` without ``blend``, a
        ``gap_time_constant`` <= 0 or with ``"hold"``, a ``gap_rate_prediction_span_s`` or
        ``gap_rate_prediction_window_s`` that is not finite and > 0 or given without
        ``gap="ar"``, a ``single_frame_gate`` of the wrong type, or a batch element with no
        received sample.

    Notes
    -----
    Fusion computes in single precision: outputs are normalised again in double, and two
    runs on the same data agree exactly, but comparisons with double-precision filters
    should allow ~1e-6.
    """
    fs, signals, mask, batch = _prepare(gyr, acc, mag, fs, received)
    options = _Options("fusion_orientation", mag, fs, gap, replay, output_on_lost, gap_time_constant,
                       gap_rate_prediction_span_s, gap_rate_prediction_window_s, blend, rho, tau, schedule,
                       hold_window, single_frame_gate)
    ahrs_settings = _fusion_settings(fs, gain, settings)
    quat = _run_batch(_fusion_one(ahrs_settings, 1.0 / fs, options.gap), signals, mask, batch,
                      options.feedback(signals, mask), predict=options.gap_factor is not None)
    return options.finish(quat, signals, mask)


# --------------------------------------------------------------------------------------------
# VQF (vqf)
# --------------------------------------------------------------------------------------------

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


def _pieces(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and ends of the runs of received samples."""
    prev = np.concatenate(([False], mask[:-1]))
    nxt = np.concatenate((mask[1:], [False]))
    return np.flatnonzero(mask & ~prev), np.flatnonzero(mask & ~nxt) + 1


def _vqf_one(fs: float, params: dict, gap: _GapRates):
    gap_factor = gap.factor

    def one(gyr, acc, mag, mask, feedback):
        try:
            filt = vqf.VQF(1.0 / fs, **params)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"params rejected by vqf.VQF: {exc}") from exc
        n_t = mask.shape[-1]
        out = np.empty((n_t, 4))
        updates = VQFUpdates(filt, gyr, acc, mag, out, feedback)
        used = np.empty((n_t, 3)) if gap.tracked else None  # the rate history (gaps module): raw gyroscope
        first = int(np.argmax(mask))

        def fill_gap(prev, stop, measured):
            """Outputs on the lost samples ``prev + 1 … stop − 1`` and (``measured``: the rate of the
            received sample ``stop``) the replay, which leaves the state where ``stop``'s update starts."""
            predicted, replayed = gap.rates(used[first:prev + 1], stop - prev - 1, measured)
            used[prev + 1:stop] = predicted
            saved = filt.state if gap.replay and measured is not None else None  # a snapshot (module docstring)
            if gap.gap == "ar":  # VQF's own strapdown integration (bias-corrected inside)
                updates.turn(predicted, out[prev + 1:stop])
            elif gap_factor is not None:  # the same outputs as without replay
                out[prev + 1:stop] = _predict_gap(out[prev], gyr[prev], stop - prev - 1, 1.0 / fs, gap_factor)
            if saved is not None:
                filt.state = saved
                updates.turn(replayed)

        prev = -1  # last received sample
        for start, end in zip(*_pieces(mask), strict=True):
            if prev >= 0 and start - prev > 1:
                if gap.tracked:
                    fill_gap(prev, start, gyr[start])
                elif gap_factor is not None:  # dead reckoning over the gap
                    out[prev + 1:start] = _predict_gap(out[prev], gyr[prev], start - prev - 1, 1.0 / fs, gap_factor)
                    updates.set_output(out[start - 1])
            updates.run(start, end)  # (and the feedback hybrid's blends)
            if used is not None:
                used[start:end] = gyr[start:end]
            prev = end - 1
        if gap.tracked and gap_factor is not None and prev < n_t - 1:  # a gap at the end
            fill_gap(prev, n_t, None)
        elif gap_factor is not None and 0 <= prev < n_t - 1:
            out[prev + 1:] = _predict_gap(out[prev], gyr[prev], n_t - 1 - prev, 1.0 / fs, gap_factor)
        return out

    return one


def vqf_orientation(gyr, acc, mag=None, *, fs: float, received=None, params: dict | None = None, gap: str = "hold",
                    replay: bool = False, output_on_lost: str = "estimate", gap_time_constant=None,
                    gap_rate_prediction_span_s=None, gap_rate_prediction_window_s=None, blend: str | None = None,
                    rho=None, tau=None, schedule=None, hold_window=None, single_frame_gate=None) -> np.ndarray:
    """VQF (Laidig & Seel 2023, ``vqf.VQF``) over whole recordings, with packet loss, batched.

    Each batch element gets a fresh ``vqf.VQF(1/fs, **params)``; its received samples go through
    ``update`` (the bits of one ``updateBatch`` over them; :mod:`wsnlib.orientation._vqf_updates`),
    which is exactly "lost samples are skipped, the next received one uses the nominal Ts".  The output
    is ``quat9D`` with ``mag``, ``quat6D`` without.  This is the causal (online) filter; ``vqf.offlineVQF``
    (acausal) is not used.

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
    gap, replay, output_on_lost, gap_time_constant, gap_rate_prediction_span_s, gap_rate_prediction_window_s
        As in :func:`fusion_orientation`; in a gap with ``"ar"`` VQF's own ``updateGyr`` turns
        the state, and ``replay`` restores ``state`` (module docstring, "Gap prediction").
    blend, rho, tau, schedule, hold_window, single_frame_gate
        As in :func:`fusion_orientation`.

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        ENU unit quaternions (body → earth; y = magnetic north with ``mag``).  Lost samples
        hold the previous output (or the prediction, ``gap="constant_rate"`` or ``"ar"``, unless
        ``output_on_lost="hold"``); samples before the first received one hold the output at it.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, a non-boolean ``received``, NaN/inf or a zero ``acc``/``mag`` vector in
        a received sample, ``fs`` <= 0, an unknown key in ``params`` (or a value VQF
        rejects), and what :func:`fusion_orientation` refuses of the loss options, or a batch
        element with no received sample.
    """
    fs, signals, mask, batch = _prepare(gyr, acc, mag, fs, received)
    options = _Options("vqf_orientation", mag, fs, gap, replay, output_on_lost, gap_time_constant,
                       gap_rate_prediction_span_s, gap_rate_prediction_window_s, blend, rho, tau, schedule,
                       hold_window, single_frame_gate)
    vqf_params = _vqf_params(params)
    quat = _run_batch(_vqf_one(fs, vqf_params, options.gap), signals, mask, batch,
                      options.feedback(signals, mask), predict=options.gap_factor is not None)
    return options.finish(quat, signals, mask)
