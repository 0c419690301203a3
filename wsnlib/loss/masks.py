"""Packet ↔ sample masks and what to read from a mask: λ, run lengths, hold-last.

Every mask is boolean with ``True`` = received; the last axis is time (packets or samples).
The package docstring (:mod:`wsnlib.loss`) describes the packet grid and λ.
"""

from __future__ import annotations

import numpy as np

from wsnlib._validation import check_count
from wsnlib.loss._checks import _check_mask

#: Samples per packet in paper 001, Section IV.
SAMPLES_PER_PACKET = 6


# --------------------------------------------------------------------------------------------
# Packets ↔ samples
# --------------------------------------------------------------------------------------------


def n_packets_for(n_samples: int, samples_per_packet: int = SAMPLES_PER_PACKET) -> int:
    """Packets needed to carry ``n_samples`` samples: ``ceil(n_samples / samples_per_packet)``."""
    n_samples = check_count(n_samples, "n_samples", 0)
    spp = check_count(samples_per_packet, "samples_per_packet")
    return -(-n_samples // spp)


def packets_to_samples(packet_received, samples_per_packet: int = SAMPLES_PER_PACKET,
                       n_samples: int | None = None) -> np.ndarray:
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
    spp = check_count(samples_per_packet, "samples_per_packet")
    n_packets = mask.shape[-1]
    samples = np.repeat(mask, spp, axis=-1)
    if n_samples is None:
        return samples
    n_samples = check_count(n_samples, "n_samples", 0)
    needed = n_packets_for(n_samples, spp)
    if n_packets != needed:
        raise ValueError(f"packet_received has {n_packets} packets, but n_samples = {n_samples} at "
                         f"{spp} samples per packet needs {needed}")
    return samples[..., :n_samples]


# --------------------------------------------------------------------------------------------
# Statistics of masks
# --------------------------------------------------------------------------------------------


def last_received_index(received, *, backfill: bool = False) -> np.ndarray:
    """Index (along the last axis) of the latest received sample at or before each sample.

    Parameters
    ----------
    received : array_like of bool, shape (..., T)
        True = received (or, for other callers, whatever sample counts as valid).
    backfill : bool
        Before the first received sample: that first received sample's index (0 in a sequence
        with none) instead of -1.

    Returns
    -------
    numpy.ndarray of int, shape (..., T)
    """
    mask = _check_mask(received, "received")
    index = np.maximum.accumulate(np.where(mask, np.arange(mask.shape[-1]), -1), axis=-1)
    if backfill:
        index = np.where(index < 0, np.argmax(mask, axis=-1)[..., None], index)
    return index


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
    index = np.arange(mask.shape[-1])
    return np.where(mask, 0, index - last_received_index(mask)).astype(np.int64)


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
    source = last_received_index(mask, backfill=True)
    values = np.broadcast_to(values, batch + values.shape[-2:])
    return np.take_along_axis(values, source[..., None], axis=-2)
