"""Loss models: single bursts, burst trains, Gilbert–Elliott.

Each returns a boolean mask with ``True`` = received; the package docstring
(:mod:`wsnlib.loss`) gives the references.
"""

from __future__ import annotations

import math

import numpy as np

from wsnlib._validation import check_count, check_rng
from wsnlib.loss._checks import _check_rate, _check_shape
from wsnlib.loss.masks import SAMPLES_PER_PACKET

# --------------------------------------------------------------------------------------------
# Deterministic bursts
# --------------------------------------------------------------------------------------------


def burst_loss(n_packets: int, start_packet: int, n_lost: int) -> np.ndarray:
    """Per-packet mask with one burst of ``n_lost`` lost packets starting at ``start_packet``.

    Parameters
    ----------
    n_packets : int
        Length of the mask.
    start_packet : int
        Index of the first lost packet, ``0 <= start_packet <= n_packets``.
    n_lost : int
        Number of lost packets (≥ 0); a burst running past the end is cut there.

    Returns
    -------
    numpy.ndarray of bool, shape (n_packets,)
        False on ``start_packet … start_packet + n_lost − 1``, True elsewhere.
    """
    n_packets = check_count(n_packets, "n_packets", 0)
    start = check_count(start_packet, "start_packet", 0)
    if start > n_packets:
        raise ValueError(f"start_packet must be <= n_packets = {n_packets}, got {start}")
    n_lost = check_count(n_lost, "n_lost", 0)
    mask = np.ones(n_packets, dtype=bool)
    mask[start : start + n_lost] = False
    return mask


def burst_mask(n_samples: int, start_sample: int, n_packets: int, samples_per_packet: int = SAMPLES_PER_PACKET, *,
               align: str = "next") -> np.ndarray:
    """Per-sample mask with ``n_packets`` whole packets lost "right after ``start_sample`` samples".

    Parameters
    ----------
    n_samples : int
        Length ``T`` of the mask.
    start_sample : int
        Number of samples received before the burst may begin, ``0 <= start_sample <= T``.
    n_packets : int
        Number of lost packets (≥ 0); λ reaches ``n_packets · samples_per_packet`` unless the
        burst is cut at the end of the recording.
    samples_per_packet : int
        Samples per packet ``S``.
    align : {"next", "exact"}
        Where the burst starts:

        * ``"next"`` (default): on the packet grid of the module (packets start at multiples
          of ``S``), the first lost packet is the first one starting at or after
          ``start_sample``.  With ``S = 6``, ``burst_mask(T, 80, 4)`` loses samples 84–107
          (packets 14–17): samples 0–83 are received.  The mask is then exactly
          ``packets_to_samples(burst_loss(...), S, T)``.
        * ``"exact"``: the burst starts at ``start_sample`` itself, as if the packet grid
          were shifted so that a packet begins there.  ``burst_mask(T, 80, 4,
          align="exact")`` loses samples 80–103, the literal reading of paper 001's "four
          packets right after 80 samples" (80 is not a multiple of 6).

    Returns
    -------
    numpy.ndarray of bool, shape (n_samples,)
    """
    n_samples = check_count(n_samples, "n_samples", 0)
    start = check_count(start_sample, "start_sample", 0)
    if start > n_samples:
        raise ValueError(f"start_sample must be <= n_samples = {n_samples}, got {start}")
    n_lost = check_count(n_packets, "n_packets", 0)
    spp = check_count(samples_per_packet, "samples_per_packet")
    if align == "next":
        first = -(-start // spp) * spp
    elif align == "exact":
        first = start
    else:
        raise ValueError(f"align must be 'next' or 'exact', got {align!r}")
    mask = np.ones(n_samples, dtype=bool)
    mask[first : first + n_lost * spp] = False
    return mask


def burst_train(n_samples: int, start_sample: int, period_samples: int, n_packets: int,
                samples_per_packet: int = SAMPLES_PER_PACKET) -> tuple[np.ndarray, np.ndarray]:
    """Repeated bursts: ``n_packets`` lost every ``period_samples`` samples from ``start_sample`` on.

    Each burst is placed like :func:`burst_mask` (on the packet grid, at or after its nominal
    start); bursts that would not end before the record does are left out, so every burst has
    a first received sample after it.

    Returns
    -------
    received : numpy.ndarray of bool, shape (n_samples,)
    burst_ends : numpy.ndarray of int, shape (B,)
        Index of the first received sample after each burst (for
        :func:`wsnlib.metrics.burst_response`).
    """
    n_samples = check_count(n_samples, "n_samples", 0)
    period = check_count(period_samples, "period_samples")
    n_packets = check_count(n_packets, "n_packets")
    start = check_count(start_sample, "start_sample", 0)
    length = n_packets * samples_per_packet
    if period <= length:
        raise ValueError(f"period_samples ({period}) must exceed the burst length ({length} samples)")
    received = np.ones(n_samples, dtype=bool)
    ends = []
    for nominal in range(start, n_samples, period):
        burst = burst_mask(n_samples, nominal, n_packets, samples_per_packet)
        first_lost = int(np.argmin(burst))
        if burst.all() or first_lost + length >= n_samples:
            break
        received &= burst
        ends.append(first_lost + length)
    return received, np.asarray(ends, dtype=np.int64)


# --------------------------------------------------------------------------------------------
# Random loss models
# --------------------------------------------------------------------------------------------


def gilbert_elliott_probabilities(loss_rate: float, mean_burst: float) -> tuple[float, float]:
    """Transition probabilities ``(p_GB, p_BG)`` of the Gilbert–Elliott chain.

    ``p_BG = 1 / mean_burst`` (bursts of lost packets are geometric with that mean) and
    ``p_GB = loss_rate · p_BG / (1 − loss_rate)``, so that the stationary probability of the
    Bad state, ``p_GB / (p_GB + p_BG)``, equals ``loss_rate``.

    Raises
    ------
    ValueError
        Unless ``0 <= loss_rate < 1``, ``mean_burst >= 1``, and ``p_GB <= 1``, i.e.
        ``loss_rate <= mean_burst / (1 + mean_burst)`` (with bursts of mean length ``m``
        separated by at least one received packet, at most ``m / (1 + m)`` can be lost).
    """
    rate = _check_rate(loss_rate, "loss_rate")
    try:
        burst = float(mean_burst)
    except (TypeError, ValueError):
        raise ValueError(f"mean_burst must be a number >= 1, got {mean_burst!r}") from None
    if not math.isfinite(burst) or burst < 1.0:
        raise ValueError(f"mean_burst must be a finite number >= 1, got {mean_burst!r}")
    p_bg = 1.0 / burst
    p_gb = rate * p_bg / (1.0 - rate)
    if p_gb > 1.0:
        raise ValueError(f"loss_rate = {rate:g} cannot be reached with mean_burst = {burst:g}: "
                         f"loss_rate must be <= mean_burst / (1 + mean_burst) = {burst / (1.0 + burst):g}")
    return p_gb, p_bg


def gilbert_elliott(n_packets: int, loss_rate: float, mean_burst: float, *, rng: np.random.Generator,
                    shape=()) -> np.ndarray:
    """Bursty packet loss from the two-state Gilbert–Elliott Markov chain.

    States: Good (packet received) and Bad (packet lost).  ``p(B→G) = 1 / mean_burst`` and
    ``p(G→B)`` is set so that the stationary loss rate is ``loss_rate``
    (:func:`gilbert_elliott_probabilities`).  The first packet's state is drawn from the
    stationary distribution, so every packet is lost with probability ``loss_rate`` and the
    lengths of loss bursts are geometric with mean ``mean_burst``.

    Parameters
    ----------
    n_packets : int
        Packets per sequence.
    loss_rate : float
        Long-run fraction of lost packets, ``0 <= loss_rate < 1``.
    mean_burst : float
        Mean number of consecutive lost packets, ``>= 1``.
    rng : numpy.random.Generator
    shape : tuple of int
        Batch shape; each sequence is an independent chain.

    Returns
    -------
    numpy.ndarray of bool, shape (*shape, n_packets)
        True = received.
    """
    n_packets = check_count(n_packets, "n_packets", 0)
    p_gb, p_bg = gilbert_elliott_probabilities(loss_rate, mean_burst)
    shape = _check_shape(shape)
    rng = check_rng(rng)
    u = rng.random(shape + (n_packets,))
    lost = np.empty(shape + (n_packets,), dtype=bool)
    if n_packets == 0:
        return ~lost
    stationary_bad = p_gb / (p_gb + p_bg)
    # The chain, lost_k = (u_k >= p_BG) if lost_{k-1} else (u_k < p_GB) (Bad stays Bad with 1 - p_BG;
    # Good turns Bad with p_GB), without a loop over packets: each u_k either sets the state (both
    # branches agree) or keeps it or flips it.  So lost_k is the state set last, at or before k (the
    # first packet's from the stationary distribution), flipped once per flip since then.
    if_bad, if_good = u >= p_bg, u < p_gb
    sets = if_bad == if_good
    sets[..., 0] = True
    if_bad[..., 0] = u[..., 0] < stationary_bad
    flips = np.cumsum(~if_bad & if_good, axis=-1)
    last_set = np.maximum.accumulate(np.where(sets, np.arange(n_packets), 0), axis=-1)
    set_value = np.take_along_axis(if_bad, last_set, axis=-1)
    flips_since = flips - np.take_along_axis(flips, last_set, axis=-1)
    lost[...] = set_value ^ (flips_since % 2 == 1)
    return ~lost
