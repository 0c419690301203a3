"""Bridging a gap with a measured rotation: a Kalman step whose rate is known but nothing else.

A packet of :mod:`wsnlib.stream` may carry a summary of the node's earlier packets: the rotation
the body went through during each (:mod:`wsnlib.stream.packet`).  When such a packet arrives
after a burst of lost packets, the receiver re-runs the burst from the filter's state before it
(the state after its last received sample), and on each lost sample whose packet's rotation is
known it takes :func:`bridge_step` instead of the filter's prediction with a *predicted* rate
(``gap``).  The step is the filter's own prediction (:func:`~._kalman_kernels.predict`) with a
rate the receiver derived from the summary, minus the bias estimate (the rates over the covered
samples turn, together, by exactly the summary's rotation), and with the gap's noise model: the
summary's rate error (std ``rate_sigma``, rad/s: its quantisation, module
:mod:`wsnlib.stream.receiver`) in place of the predicted rate's ``σ_gap``, so the attitude
variance grows by ``(rate_sigma · kΔt)²`` after ``k`` such samples, and the unknown linear
acceleration (``gap_acc_noise``) in the leaky velocity's, as in a gap (kalman.py's docstring,
"Gap").  No accelerometer or magnetometer update: the summary carries none.  The rate goes into
the gap module's history (:func:`~.gaps.gap_received`), so a later gap's linear prediction
fits measured rates; a gap replay (``replay``) of lost samples just before the bridged ones
runs first, as at a received sample.
"""

from __future__ import annotations

from numba import njit

from wsnlib.orientation import gaps
from wsnlib.orientation._kalman_kernels import _keep_prediction, _replay, predict
from wsnlib.orientation._scalar_kernels import COMPILE, PLAIN_FALSE


@njit(**COMPILE)
def bridge_step(st, gs, history, work, c, bridge_c, rate, rate_sigma, run, replayed):
    """Advance the filter (``st``, gap record ``gs``, rate ``history``, ``work``) by one sample turned by
    the measured rate ``rate`` (3-tuple, rad/s, raw: the bias is subtracted here).

    ``c``: the run's constants; ``bridge_c``: a copy of them (one record) this function owns (its
    ``gap_noise`` is set to ``rate_sigma``, its ``gap_relative_noise`` to 0); ``run``: samples since
    the last received one, this one included (the gap's count, which sets the leaky velocity's
    growth); ``replayed``: as :func:`~._kalman_kernels.kalman_step`'s.
    """
    omega = (rate[0] - st.bias[0], rate[1] - st.bias[1], rate[2] - st.bias[2])
    if c.replay and gs.lost > 0 and gs.n > gs.lost:  # lost samples before these: replayed to meet ω̄
        _replay(st, gs, history, omega, c.dt, replayed)
    bridge_c.gap_noise = rate_sigma
    bridge_c.gap_relative_noise = 0.0
    st.gap_sigma = rate_sigma
    st.hi_prev_ok = False  # the hard-iron estimate differentiates consecutive received fields
    predict(st, work, bridge_c, omega, omega, PLAIN_FALSE, run)
    _keep_prediction(st, work, c)
    gaps.gap_received(gs, history, omega)
