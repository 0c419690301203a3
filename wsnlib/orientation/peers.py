"""Peer orientation filters under packet loss: x-io Fusion and VQF, with paper 001's hybrid.

Two published filters a user may run instead of Madgwick's, fed the same received samples,
with wsnlib's conventions (:mod:`wsnlib`) and :func:`wsnlib.orientation.madgwick`'s loss
semantics:

* :func:`fusion_ahrs`: x-io Technologies' Fusion (S. Madgwick's revised AHRS, a
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
library runs one recording at a time); VQF processes each contiguous run of received
samples in one compiled ``updateBatch`` call, Fusion needs one call per sample (its Python
package has no batch call).

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

Hybrid
------
``hybrid="output"``: the peer runs untouched and its output goes through
:func:`wsnlib.orientation.loss_handling.blend_with_single_frame`: ``q_f = SLERP(q_s, q_d,
μ(λ_eff))`` on received samples with λ_eff > 0, ``q_s`` TRIAD of the sample.
``hybrid="feedback"``: ``q_f`` also replaces the filter's orientation after each such
update, so that the state itself is pulled towards TRIAD.  Both libraries allow it:

* Fusion: ``Ahrs.set_quaternion(q_f)``; nothing else of its state is orientation.
* VQF: the ``state`` property is writable (a dict).  ``gyrQuat`` (body → the
  almost-inertial frame I_i of the strapdown integration) is set to
  ``accQuat* ⊗ q_z(−δ) ⊗ q_f``, so that the 9D output ``q_z(δ) ⊗ accQuat ⊗ gyrQuat``
  becomes ``q_f``; ``accQuat`` and δ (the magnetic heading offset) stay.  Not ``accQuat``:
  VQF low-pass filters the accelerometer in I_i and recomputes ``accQuat`` at every update
  as the full rotation that makes that filtered vector vertical, so an inclination written
  into ``accQuat`` is undone by the next update, while one written into ``gyrQuat`` is
  consistent with the filtered vector and persists.

Feedback calls the library once per blended sample (Fusion: always once per sample).
``single_frame_gate`` makes either hybrid the *gated hybrid*: no blend on received samples
whose TRIAD looks untrustworthy (:class:`wsnlib.orientation.SingleFrameGate`).

Gap prediction
--------------
``gap="constant_rate"`` (as in :func:`wsnlib.orientation.estimate_orientation`): on a lost
sample the output is the last received output turned on by the last received angular rate
(raw gyroscope, body frame), ``q_k = q_last ⊗ Exp(ω Δt Σ_{j≤k} f^j)`` with ``f = 1`` or
``f = exp(−Δt/τ)`` (``gap_time_constant`` τ); the rotation is about one body axis, so this is
exact for that rate.  At the next received sample the filter's orientation is set to the last
prediction (Fusion: ``set_quaternion``; VQF: ``gyrQuat``, as for the feedback hybrid) and
the library updates from there.  ``gap="hold"`` (default) holds the output.  A gap before the
first received sample is held either way (the filter has not started).

Modules
-------
* :mod:`wsnlib.orientation.fusion_peer`: :func:`fusion_ahrs` and its settings;
* :mod:`wsnlib.orientation.vqf_peer`: :func:`vqf_orientation`;
* :mod:`wsnlib.orientation._peer_common`: the checks and the loss, hybrid and gap plumbing both share.

Every name is re-exported here: ``from wsnlib.orientation.peers import fusion_ahrs`` keeps working.
"""

from __future__ import annotations

# The names marked F401 were imported or defined here by earlier versions; kept importable.
from wsnlib.orientation._peer_common import HYBRIDS, _predict_gap  # noqa: F401
from wsnlib.orientation.fusion_peer import FUSION_DEFAULT_SETTINGS, fusion_ahrs
from wsnlib.orientation.loss_handling import (  # noqa: F401
    DEFAULT_HOLD_WINDOW,
    SCHEDULES,
    SingleFrameGate,
    blend_with_single_frame,
    check_single_frame_gate,
    effective_lost_run,
    slerp_weight,
)
from wsnlib.orientation.triad import triad  # noqa: F401
from wsnlib.orientation.vqf_peer import _vqf_set_quat9d, vqf_orientation  # noqa: F401

__all__ = ["FUSION_DEFAULT_SETTINGS", "HYBRIDS", "fusion_ahrs", "vqf_orientation"]
