"""Loss profiles: a named packet-loss pattern that draws the received masks of a recording.

One type for every study: the Monte Carlo trials of notebooks 03–04
(:func:`wsnlib.sim.trials.arm_loss_trials`) and the loss-tolerance study of notebooks 05 and 10
(:mod:`wsnlib.studies.loss_tolerance`).  A profile is one of

* ``LossProfile.none()`` — everything received (the lossless reference);
* ``LossProfile.burst(start_s, n_packets, period_s=None)`` — paper 001, Section IV: ``n_packets``
  whole packets lost right after ``start_s`` seconds (:func:`wsnlib.loss.burst_mask`), or, with
  a period, one such burst every ``period_s`` from ``start_s`` on
  (:func:`wsnlib.loss.burst_train`);
* ``LossProfile.gilbert_elliott(loss_rate, mean_burst_packets=3)`` — bursty random loss
  (:func:`wsnlib.loss.gilbert_elliott`), an independent chain per mask drawn.

Times are in seconds, so a profile means the same at any sampling rate; packets hold
``samples_per_packet`` samples (6 in paper 001).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib.loss.masks import SAMPLES_PER_PACKET, n_packets_for, packets_to_samples
from wsnlib.loss.models import burst_mask, burst_train, gilbert_elliott

#: What generates a profile's masks.
MODELS = ("none", "burst", "gilbert_elliott")


@dataclass(frozen=True)
class LossProfile:
    """A packet-loss pattern; build it with the class methods.

    Attributes
    ----------
    name : str
        Label used in tables (e.g. ``"burst 4 packets"``, ``"GE 10 %"``).
    model : {"none", "burst", "gilbert_elliott"}
    loss_rate : float
        Gilbert–Elliott stationary packet loss rate, in [0, 1).
    mean_burst_packets : float
        Gilbert–Elliott mean burst length (packets), ≥ 1.
    samples_per_packet : int
    burst_packets : int
        Packets lost per burst (``"burst"``).
    burst_start_s : float
        When the first burst may begin (s): the burst starts at the first packet boundary at
        or after ``round(burst_start_s · fs)`` samples.
    burst_period_s : float or None
        Time (s) from one burst's nominal start to the next's; ``None``: a single burst.
    """

    name: str
    model: str
    loss_rate: float = 0.0
    mean_burst_packets: float = 3.0
    samples_per_packet: int = SAMPLES_PER_PACKET
    burst_packets: int = 4
    burst_start_s: float = 4.0
    burst_period_s: float | None = None

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {self.model!r}")

    @classmethod
    def none(cls, name: str = "no loss") -> LossProfile:
        """Everything received."""
        return cls(name, "none")

    @classmethod
    def burst(cls, start_s: float, n_packets: int = 4, *, period_s: float | None = None,
              samples_per_packet: int = SAMPLES_PER_PACKET, name: str | None = None) -> LossProfile:
        """``n_packets`` lost right after ``start_s`` (s), once or every ``period_s`` (s)."""
        return cls(f"burst {n_packets} packets" if name is None else name, "burst", burst_packets=n_packets,
                   burst_start_s=start_s, burst_period_s=period_s, samples_per_packet=samples_per_packet)

    @classmethod
    def gilbert_elliott(cls, loss_rate: float, mean_burst_packets: float = 3.0, *,
                        samples_per_packet: int = SAMPLES_PER_PACKET, name: str | None = None) -> LossProfile:
        """Bursty random loss at ``loss_rate`` (0 gives the lossless model, named ``"GE 0 %"``)."""
        name = f"GE {100 * loss_rate:g} %" if name is None else name
        if loss_rate == 0.0:
            return cls(name, "none", samples_per_packet=samples_per_packet)
        return cls(name, "gilbert_elliott", loss_rate=loss_rate, mean_burst_packets=mean_burst_packets,
                   samples_per_packet=samples_per_packet)

    def mask(self, n_samples: int, fs: float, rng: np.random.Generator | None, shape: tuple = ()) -> np.ndarray:
        """Received masks ``(*shape, n_samples)``, True = received.

        ``rng`` draws the Gilbert–Elliott chains (one per mask, ``shape`` of them) and may be
        None for the deterministic models; bursts are the same in every mask.
        """
        shape = tuple(shape)
        if self.model == "none":
            return np.ones(shape + (n_samples,), dtype=bool)
        if self.model == "burst":
            start = int(round(self.burst_start_s * fs))
            if self.burst_period_s is None:
                one = burst_mask(n_samples, start, self.burst_packets, self.samples_per_packet)
            else:
                one = burst_train(n_samples, start, int(round(self.burst_period_s * fs)), self.burst_packets,
                                  self.samples_per_packet)[0]
            return np.broadcast_to(one, shape + (n_samples,)).copy()
        packets = gilbert_elliott(n_packets_for(n_samples, self.samples_per_packet), self.loss_rate,
                                  self.mean_burst_packets, rng=rng, shape=shape)
        return packets_to_samples(packets, self.samples_per_packet, n_samples)
