"""Packet loss: packets of samples, loss masks (burst, Bernoulli, Gilbert–Elliott), run lengths.

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
* :func:`bernoulli_loss`: independent packet losses.
* :func:`gilbert_elliott`: the two-state Markov chain of E. N. Gilbert, "Capacity of a
  burst-noise channel", Bell Syst. Tech. J. 39:1253–1265, 1960, and E. O. Elliott,
  "Estimates of error rates for codes on burst-noise channels", Bell Syst. Tech. J.
  42:1977–1997, 1963, in its simplified form (Good = received, Bad = lost), as commonly used
  for bursty IEEE 802.15.4 links.
* :func:`loss_trace_from_file`: a measured per-packet trace.

λ
-
:func:`lost_run_length` gives paper 001's λ, "the number of samples lost consecutively", at
every sample: 0 on received samples, ``1, 2, …`` along a run of lost samples.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

#: Samples per packet in paper 001, Section IV.
SAMPLES_PER_PACKET = 6


# --------------------------------------------------------------------------------------------
# Validation helpers
# --------------------------------------------------------------------------------------------


def _check_count(value, name: str, minimum: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value!r}")
    return int(value)


def _check_shape(shape, name: str = "shape") -> tuple[int, ...]:
    if isinstance(shape, (int, np.integer)) and not isinstance(shape, bool):
        shape = (shape,)
    try:
        shape = tuple(shape)
    except TypeError:
        raise ValueError(
            f"{name} must be a tuple of non-negative integers, got {shape!r}"
        ) from None
    return tuple(_check_count(s, name) for s in shape)


def _check_mask(value, name: str, min_ndim: int = 1) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype != np.bool_:
        raise ValueError(f"{name} must be a boolean mask (True = received), got dtype {arr.dtype}")
    if arr.ndim < min_ndim:
        raise ValueError(
            f"{name} must have at least {min_ndim} dimension(s), got shape {arr.shape}"
        )
    return arr


def _check_rate(value, name: str, upper_inclusive: bool) -> float:
    try:
        rate = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    ok = 0.0 <= rate <= 1.0 if upper_inclusive else 0.0 <= rate < 1.0
    if not ok:
        interval = "[0, 1]" if upper_inclusive else "[0, 1)"
        raise ValueError(f"{name} must lie in {interval}, got {value!r}")
    return rate


def _check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


# --------------------------------------------------------------------------------------------
# Packets ↔ samples
# --------------------------------------------------------------------------------------------


def n_packets_for(n_samples: int, samples_per_packet: int = SAMPLES_PER_PACKET) -> int:
    """Packets needed to carry ``n_samples`` samples: ``ceil(n_samples / samples_per_packet)``."""
    n_samples = _check_count(n_samples, "n_samples")
    spp = _check_count(samples_per_packet, "samples_per_packet", 1)
    return -(-n_samples // spp)


def packets_to_samples(
    packet_received,
    samples_per_packet: int = SAMPLES_PER_PACKET,
    n_samples: int | None = None,
) -> np.ndarray:
    """Expand a per-packet mask to a per-sample mask.

    Parameters
    ----------
    packet_received : array_like of bool, shape (..., P)
        True where the packet arrived.
    samples_per_packet : int
        Samples per packet ``S`` (6 in paper 001).
    n_samples : int, optional
        Number of samples ``T`` of the recording.  Default ``P · S``.  Otherwise ``P`` must
        equal ``ceil(T / S)``: the last packet may be partial (it carries the last
        ``T − (P − 1)·S`` samples, and its flag applies to them); more or fewer packets than
        that is an error rather than silent padding or truncation.

    Returns
    -------
    numpy.ndarray of bool, shape (..., T)
        True where the sample was received.
    """
    mask = _check_mask(packet_received, "packet_received")
    spp = _check_count(samples_per_packet, "samples_per_packet", 1)
    n_packets = mask.shape[-1]
    samples = np.repeat(mask, spp, axis=-1)
    if n_samples is None:
        return samples
    n_samples = _check_count(n_samples, "n_samples")
    needed = n_packets_for(n_samples, spp)
    if n_packets != needed:
        raise ValueError(
            f"packet_received has {n_packets} packets, but n_samples = {n_samples} at "
            f"{spp} samples per packet needs {needed}"
        )
    return samples[..., :n_samples]


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
    n_packets = _check_count(n_packets, "n_packets")
    start = _check_count(start_packet, "start_packet")
    if start > n_packets:
        raise ValueError(f"start_packet must be <= n_packets = {n_packets}, got {start}")
    n_lost = _check_count(n_lost, "n_lost")
    mask = np.ones(n_packets, dtype=bool)
    mask[start : start + n_lost] = False
    return mask


def burst_mask(
    n_samples: int,
    start_sample: int,
    n_packets: int,
    samples_per_packet: int = SAMPLES_PER_PACKET,
    *,
    align: str = "next",
) -> np.ndarray:
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
    n_samples = _check_count(n_samples, "n_samples")
    start = _check_count(start_sample, "start_sample")
    if start > n_samples:
        raise ValueError(f"start_sample must be <= n_samples = {n_samples}, got {start}")
    n_lost = _check_count(n_packets, "n_packets")
    spp = _check_count(samples_per_packet, "samples_per_packet", 1)
    if align == "next":
        first = -(-start // spp) * spp
    elif align == "exact":
        first = start
    else:
        raise ValueError(f"align must be 'next' or 'exact', got {align!r}")
    mask = np.ones(n_samples, dtype=bool)
    mask[first : first + n_lost * spp] = False
    return mask


# --------------------------------------------------------------------------------------------
# Random loss models
# --------------------------------------------------------------------------------------------


def bernoulli_loss(
    n_packets: int, loss_rate: float, *, rng: np.random.Generator, shape=()
) -> np.ndarray:
    """Independent packet losses with probability ``loss_rate``.

    Parameters
    ----------
    n_packets : int
        Packets per sequence.
    loss_rate : float
        Probability that a packet is lost, in [0, 1].
    rng : numpy.random.Generator
    shape : tuple of int
        Batch shape.

    Returns
    -------
    numpy.ndarray of bool, shape (*shape, n_packets)
        True = received.
    """
    n_packets = _check_count(n_packets, "n_packets")
    rate = _check_rate(loss_rate, "loss_rate", upper_inclusive=True)
    shape = _check_shape(shape)
    rng = _check_rng(rng)
    return rng.random(shape + (n_packets,)) >= rate


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
    rate = _check_rate(loss_rate, "loss_rate", upper_inclusive=False)
    try:
        burst = float(mean_burst)
    except (TypeError, ValueError):
        raise ValueError(f"mean_burst must be a number >= 1, got {mean_burst!r}") from None
    if not math.isfinite(burst) or burst < 1.0:
        raise ValueError(f"mean_burst must be a finite number >= 1, got {mean_burst!r}")
    p_bg = 1.0 / burst
    p_gb = rate * p_bg / (1.0 - rate)
    if p_gb > 1.0:
        raise ValueError(
            f"loss_rate = {rate:g} cannot be reached with mean_burst = {burst:g}: "
            f"loss_rate must be <= mean_burst / (1 + mean_burst) = {burst / (1.0 + burst):g}"
        )
    return p_gb, p_bg


def gilbert_elliott(
    n_packets: int,
    loss_rate: float,
    mean_burst: float,
    *,
    rng: np.random.Generator,
    shape=(),
) -> np.ndarray:
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
    n_packets = _check_count(n_packets, "n_packets")
    p_gb, p_bg = gilbert_elliott_probabilities(loss_rate, mean_burst)
    shape = _check_shape(shape)
    rng = _check_rng(rng)
    u = rng.random(shape + (n_packets,))
    lost = np.empty(shape + (n_packets,), dtype=bool)
    if n_packets == 0:
        return ~lost
    stationary_bad = p_gb / (p_gb + p_bg)
    state = u[..., 0] < stationary_bad
    lost[..., 0] = state
    for k in range(1, n_packets):
        # Bad stays Bad with 1 - p_BG; Good turns Bad with p_GB.
        state = np.where(state, u[..., k] >= p_bg, u[..., k] < p_gb)
        lost[..., k] = state
    return ~lost


def loss_trace_from_file(path) -> np.ndarray:
    """Read a measured per-packet loss trace.

    Format: a text file of per-packet flags, ``1`` = received and ``0`` = lost (also
    ``true``/``false``, any case).  Flags are separated by commas, semicolons, whitespace or
    line breaks (one per line, or a CSV row); blank lines and lines starting with ``#`` are
    ignored, and the first non-comment line may be the header ``received``.

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    numpy.ndarray of bool, shape (n_packets,)
        True = received.

    Raises
    ------
    ValueError
        If the file is missing, empty or holds any other token (the file and the offending
        token and line are named).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file ({exc})") from None
    values = {"1": True, "0": False, "true": True, "false": False}
    flags: list[bool] = []
    header_allowed = True
    for line_no, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        tokens = [tok for tok in re.split(r"[\s,;]+", stripped) if tok]
        if header_allowed and [tok.lower() for tok in tokens] == ["received"]:
            header_allowed = False
            continue
        header_allowed = False
        for tok in tokens:
            flag = values.get(tok.lower())
            if flag is None:
                raise ValueError(
                    f"{path}: line {line_no}: {tok!r} is not a packet flag "
                    "(1/0 or true/false, 1 = received)"
                )
            flags.append(flag)
    if not flags:
        raise ValueError(f"{path}: holds no packet flags")
    return np.array(flags, dtype=bool)


# --------------------------------------------------------------------------------------------
# Statistics of masks
# --------------------------------------------------------------------------------------------


def lost_run_length(received) -> np.ndarray:
    """λ: samples lost in a row up to and including each sample (0 where received).

    Parameters
    ----------
    received : array_like of bool, shape (..., T)
        True = received.

    Returns
    -------
    numpy.ndarray of int, shape (..., T)
        For a lost sample at index ``i`` whose last received predecessor is at ``j``
        (``j = −1`` if none), ``i − j``; 0 on received samples.
    """
    mask = _check_mask(received, "received")
    n = mask.shape[-1]
    index = np.arange(n)
    last_received = np.maximum.accumulate(np.where(mask, index, -1), axis=-1)
    return np.where(mask, 0, index - last_received).astype(np.int64)


def burst_lengths(received) -> np.ndarray:
    """Lengths of all runs of consecutive losses, over every sequence of the batch.

    Parameters
    ----------
    received : array_like of bool, shape (..., T)
        True = received; runs never continue from one sequence into the next.

    Returns
    -------
    numpy.ndarray of int, shape (n_runs,)
        Run lengths, in row-major order of the batch and time.
    """
    mask = _check_mask(received, "received")
    rows = mask.reshape(-1, mask.shape[-1])
    lost = np.zeros((rows.shape[0], rows.shape[1] + 2), dtype=np.int8)
    lost[:, 1:-1] = ~rows
    edges = np.diff(lost, axis=-1).ravel()
    # Each row contributes equally many +1 (start) and -1 (end) edges, in order.
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    return (ends - starts).astype(np.int64)


def loss_fraction(received) -> np.ndarray:
    """Fraction of lost entries along the last axis, shape ``(...)``."""
    mask = _check_mask(received, "received")
    if mask.shape[-1] == 0:
        raise ValueError("received must have at least one entry along its last axis")
    return 1.0 - mask.mean(axis=-1)


def hold_last(values, received) -> np.ndarray:
    """What a receiver shows under loss: each lost sample holds the last received value.

    Used for estimators without internal state (single-frame TRIAD), which produce nothing
    while data are missing.  Samples before the first received one take the first received
    value (the receiver has nothing older to show).

    Parameters
    ----------
    values : array_like, shape (..., T, D)
        Per-sample values (e.g. quaternions, D = 4); lost samples are never read.
    received : array_like of bool, shape (..., T)
        True = received; broadcasts with the leading dimensions of ``values``.

    Returns
    -------
    numpy.ndarray, shape (broadcast(...), T, D)

    Raises
    ------
    ValueError
        If a sequence has no received sample at all.
    """
    values = np.asarray(values)
    if values.ndim < 2:
        raise ValueError(f"values must have shape (..., T, D), got {values.shape}")
    mask = _check_mask(received, "received")
    if mask.shape[-1] != values.shape[-2]:
        raise ValueError(f"received has {mask.shape[-1]} samples but values has {values.shape[-2]}")
    if not np.all(mask.any(axis=-1)):
        raise ValueError("received has a sequence with no received sample; nothing to hold")
    batch = np.broadcast_shapes(mask.shape[:-1], values.shape[:-2])
    n = mask.shape[-1]
    mask = np.broadcast_to(mask, batch + (n,))
    index = np.arange(n)
    source = np.maximum.accumulate(np.where(mask, index, -1), axis=-1)
    first = np.argmax(mask, axis=-1)[..., None]
    source = np.where(source < 0, first, source)
    values = np.broadcast_to(values, batch + values.shape[-2:])
    return np.take_along_axis(values, source[..., None], axis=-2)


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
    n_samples = _check_count(n_samples, "n_samples")
    period = _check_count(period_samples, "period_samples", minimum=1)
    n_packets = _check_count(n_packets, "n_packets", minimum=1)
    start = _check_count(start_sample, "start_sample")
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
