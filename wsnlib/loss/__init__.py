"""Packet loss: packets of samples, loss masks (burst, Gilbert–Elliott), run lengths.

Every mask is boolean with ``True`` = received; rows are never deleted.  Leading dimensions
are batches (Monte Carlo runs, parameter grids); the last axis is time (packets or samples).

Packets
-------
Samples are sent in packets of ``samples_per_packet`` consecutive samples (6 in paper 001,
Section IV: "the raw data have been organized in 6-sample packets"); losing a packet loses
all of its samples.  Packet ``k`` carries samples ``k·S … k·S + S − 1`` (``S`` samples per
packet), i.e. the packet grid starts at sample 0.  A recording of ``T`` samples needs
``ceil(T / S)`` packets (:func:`n_packets_for`); the last one may be partial.

Loss models
-----------
* :func:`burst_loss`, :func:`burst_mask`: a single burst, as in paper 001, Section IV ("a
  loss λ of four packets right after 80 samples").
* :func:`gilbert_elliott`: the two-state Markov chain of E. N. Gilbert, "Capacity of a
  burst-noise channel", Bell Syst. Tech. J. 39:1253–1265, 1960, and E. O. Elliott,
  "Estimates of error rates for codes on burst-noise channels", Bell Syst. Tech. J.
  42:1977–1997, 1963, in its simplified form (Good = received, Bad = lost), as commonly used
  for bursty IEEE 802.15.4 links.
* :class:`LossProfile`: a named pattern (none, bursts, Gilbert–Elliott) that draws the masks
  of a recording, in seconds (the studies' profiles).

λ
-
:func:`lost_run_length` gives paper 001's λ, "the number of samples lost consecutively", at
every sample: 0 on received samples, ``1, 2, …`` along a run of lost samples.

Modules
-------
* :mod:`wsnlib.loss.models`: the loss models above (bursts, burst trains, Gilbert–Elliott).
* :mod:`wsnlib.loss.masks`: packets ↔ samples and statistics of masks (λ, run lengths,
  hold-last, the last received sample).
* :mod:`wsnlib.loss.profiles`: :class:`LossProfile`.

This package's door gathers every public name: ``from wsnlib.loss import gilbert_elliott``.
"""

from __future__ import annotations

from wsnlib.loss.masks import (
    SAMPLES_PER_PACKET,
    burst_lengths,
    hold_last,
    last_received_index,
    lost_run_length,
    n_packets_for,
    packets_to_samples,
)
from wsnlib.loss.models import (
    burst_loss,
    burst_mask,
    burst_train,
    gilbert_elliott,
    gilbert_elliott_probabilities,
)
from wsnlib.loss.profiles import LossProfile

__all__ = ["LossProfile", "SAMPLES_PER_PACKET", "burst_lengths", "burst_loss", "burst_mask", "burst_train",
           "gilbert_elliott", "gilbert_elliott_probabilities", "hold_last", "last_received_index", "lost_run_length",
           "n_packets_for", "packets_to_samples"]
