"""What the Fusion and VQF wrappers share: checks, loss and hybrid plumbing, gap prediction.

The semantics (loss, hybrid, gap prediction) are described in :mod:`wsnlib.orientation.peers`;
:mod:`wsnlib.orientation.fusion_peer` and :mod:`wsnlib.orientation.vqf_peer` call these helpers.
"""

from __future__ import annotations

import numpy as np

from wsnlib import quaternion as Q
from wsnlib._validation import check_positive
from wsnlib.orientation import _batch as B
from wsnlib.orientation import _kernels as K
from wsnlib.orientation.loss_handling import (
    DEFAULT_HOLD_WINDOW,
    SCHEDULES,
    _trusted,
    blend_with_single_frame,
    check_single_frame_gate,
    effective_lost_run,
    slerp_weight,
)
from wsnlib.orientation.triad import triad

#: Values of the ``hybrid`` argument besides ``None``.
HYBRIDS = ("output", "feedback")


# --------------------------------------------------------------------------------------------
# Validation shared by both wrappers
# --------------------------------------------------------------------------------------------


def _prepare(gyr, acc, mag, fs, received):
    """Checked, broadcast signals ``(*batch, T, 3)`` and mask ``(*batch, T)``."""
    fs = check_positive(fs, "fs")
    signals, mask, _, shapes = B.check_inputs(gyr, acc, mag, received)
    n_t = signals["gyr"].shape[-2]
    if mask is None:
        mask = np.ones(n_t, dtype=bool)
    batch = B.broadcast_batch(shapes)
    B.check_usable(signals, mask)  # NaN/inf (zero acc, mag) in received samples
    mask = np.broadcast_to(mask, batch + (n_t,))
    has_sample = mask.any(axis=-1)
    if not np.all(has_sample):
        bad = tuple(int(i) for i in np.argwhere(~has_sample)[0])
        raise ValueError(f"received has no received sample for batch element {bad}: the output is undefined there")
    signals = {name: np.broadcast_to(arr, batch + (n_t, 3)) for name, arr in signals.items()}
    return fs, signals, mask, batch


def _hybrid_options(hybrid, mag, rho, tau, schedule, hold_window, single_frame_gate=None):
    if hybrid is not None and (not isinstance(hybrid, str) or hybrid not in HYBRIDS):
        raise ValueError(f"hybrid must be None, 'output' or 'feedback'; got {hybrid!r}")
    gate = check_single_frame_gate(single_frame_gate)
    if gate is not None and hybrid is None:
        raise ValueError("single_frame_gate is only used with a hybrid ('output' or 'feedback')")
    rho = check_positive(rho, "rho")
    tau = check_positive(tau, "tau")
    schedule = B.check_choice(schedule, "schedule", SCHEDULES)
    window = B.check_hold_window(hold_window, schedule, DEFAULT_HOLD_WINDOW)
    if window is not None and window.ndim:
        raise ValueError(f"hold_window must be one positive integer here, got {hold_window!r}")
    if hybrid is not None and mag is None:
        raise ValueError(f"mag is required for hybrid={hybrid!r}: TRIAD (q_s) needs the magnetometer")
    return hybrid, rho, tau, schedule, window, gate


def _gap_options(gap, gap_time_constant, fs):
    """Checked ``gap`` and the rate's factor per lost sample (None: hold)."""
    gap, gap_time_constant = B.check_gap(gap, gap_time_constant)
    if gap == "hold":
        return None
    return 1.0 if gap_time_constant is None else float(np.exp(-1.0 / (fs * gap_time_constant)))


def _predict_gap(q_last, omega, n_lost: int, dt: float, factor: float) -> np.ndarray:
    """``(n_lost, 4)``: ``q_last ⊗ Exp(ω Δt Σ_{j≤k} f^j)``, k = 1 … n_lost (:mod:`wsnlib.orientation.peers`)."""
    k = np.arange(1, n_lost + 1)
    weight = k.astype(float) if factor == 1.0 else factor * (1.0 - factor**k) / (1.0 - factor)
    turns = np.asarray(omega, dtype=float) * dt * weight[:, None]
    return Q.multiply(np.asarray(q_last, dtype=float), Q.from_rotation_vector(turns))


def _feedback_inputs(signals, mask, rho, tau, schedule, window, gate=None, fs=None):
    """Where the feedback blends ``(*batch, T)``, TRIAD there ``(*batch, T, 4)`` and μ ``(*batch, T)``."""
    started_gap = mask | ~np.logical_or.accumulate(mask, axis=-1)  # no gap before the first sample
    lam = effective_lost_run(started_gap, schedule, window)
    blend_at = mask & (lam > 0.0)
    if gate is not None:
        blend_at &= _trusted(signals, mask, mask.shape[:-1], gate.vector(fs))
    q_s = np.zeros(mask.shape + (4,))
    q_s[..., 0] = 1.0
    if blend_at.any():
        q_s[blend_at] = triad(signals["acc"][blend_at], signals["mag"][blend_at])
    return blend_at, q_s, slerp_weight(lam, rho, tau)


def _slerp(q_s: np.ndarray, q_d: np.ndarray, mu: float) -> np.ndarray:
    """Eq. (4) for one sample, in ``q_d``'s hemisphere (:func:`wsnlib.orientation._kernels.slerp`)."""
    return np.array(K.slerp(tuple(q_s.tolist()), tuple(q_d.tolist()), float(mu)))


def _hold(out: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Rows of ``out`` ``(T, 4)`` filled on received samples: lost ones take the last received
    row, those before the first received sample the first one."""
    index = np.arange(mask.shape[-1])
    src = np.maximum.accumulate(np.where(mask, index, -1))
    return out[np.where(src < 0, np.argmax(mask), src)]


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


def _finish(quat, signals, mask, hybrid, rho, tau, schedule, window, gate=None, fs=None):
    if hybrid != "output":
        return quat
    hold_window = None if window is None else int(window)
    extra = {} if gate is None else {"single_frame_gate": gate, "gyr": signals["gyr"], "fs": fs}
    return blend_with_single_frame(
        quat, signals["acc"], signals["mag"], mask, rho=rho, tau=tau, schedule=schedule, hold_window=hold_window,
        **extra
    )

