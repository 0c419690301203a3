"""A node's side: a recording as the packets a node would send (:func:`node_stream`, :func:`encode_stream`).

:func:`node_stream` quantises a node's signals to int16 with one scale per sensor (default: a
body-worn MEMS IMU's full scales, :data:`~wsnlib.stream.packet.GYR_FULL_SCALE` …; a reading
beyond it saturates), cuts them into packets of ``samples_per_packet`` samples (packet ``p``
holds samples ``p·S … p·S + S − 1``, as :mod:`wsnlib.loss`), and, with ``redundancy = K``,
computes each packet's summary of the earlier packets: the rotation of each covered span (Log of
``Π Exp(ω Δt)`` over its dequantised gyro samples, what the receiver's filter composes) and
optionally the mean accelerometer, quantised to ``bits`` bits with one float16 scale per packet
and quantity (:meth:`~wsnlib.stream.packet.Summary.quantise`).  A packet carries as many entries
as exist before it (none in the first packet).  The dequantised signals (``values``) are what a
receiver reconstructs: the reference an online-equals-batch check runs the batch filter on.
:func:`encode_stream` writes the packets as bytes.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wsnlib._validation import as_float_array, check_count, check_positive
from wsnlib.loss import SAMPLES_PER_PACKET, n_packets_for
from wsnlib.stream import _kernels as PK
from wsnlib.stream.packet import (
    ACC_FULL_SCALE,
    GYR_FULL_SCALE,
    INT16_MAX,
    LAYOUTS,
    MAG_FULL_SCALE,
    MAX_REDUNDANCY,
    MAX_SAMPLES_PER_PACKET,
    REDUNDANCY_BITS,
    Packet,
    Summary,
    encode_rows,
)


def default_scales(has_mag: bool = True) -> np.ndarray:
    """Scales (per LSB) of the default full scales: gyr rad/s, acc m/s², mag µT (0 without magnetometer)."""
    return np.array([GYR_FULL_SCALE, ACC_FULL_SCALE, MAG_FULL_SCALE if has_mag else 0.0]) / INT16_MAX


@dataclasses.dataclass(frozen=True, eq=False)
class NodeStream:
    """A recording as one node's packets (:func:`node_stream`).

    Attributes
    ----------
    fs : float
    samples_per_packet : int
    scales : numpy.ndarray (3,)
        gyr, acc, mag per LSB (float32 values; mag 0 without magnetometer).
    raw : numpy.ndarray (T, 6 or 9) int
        int16 readings.
    values : numpy.ndarray (T, 9)
        Dequantised readings ``raw × scale`` (gyr rad/s, acc m/s², mag µT; mag 0 without magnetometer).
    layout : str
    bits : int
    summary_raw : numpy.ndarray (P, K, 3 or 6) int
        Each packet's summary values (rotation vector, then mean acc); K = 0 without redundancy.
    summary_k : numpy.ndarray (P,) int
        Entries packet ``p`` carries.
    rotation_scale, mean_acc_scale : numpy.ndarray (P,)
        float16 scales (rad, m/s² per LSB); ``mean_acc_scale`` None without mean acc.
    """

    fs: float
    samples_per_packet: int
    scales: np.ndarray
    raw: np.ndarray
    values: np.ndarray
    layout: str
    bits: int
    summary_raw: np.ndarray
    summary_k: np.ndarray
    rotation_scale: np.ndarray
    mean_acc_scale: np.ndarray | None

    has_mag = property(lambda self: self.raw.shape[1] == 9)
    n_samples = property(lambda self: self.raw.shape[0])
    n_packets = property(lambda self: self.summary_k.shape[0])
    gyr = property(lambda self: self.values[:, 0:3])
    acc = property(lambda self: self.values[:, 3:6])
    mag = property(lambda self: self.values[:, 6:9] if self.has_mag else None)

    @property
    def summaries(self) -> np.ndarray:
        """Rotation vectors (P, K, 3) of the summaries, rad (what the receiver reads)."""
        return self.summary_raw[:, :, :3] * self.rotation_scale[:, None, None]

    @property
    def summary_sigma(self) -> np.ndarray:
        """Quantisation std of a rotation component per packet (rad): ``rotation_scale / √12``."""
        return self.rotation_scale / np.sqrt(12.0)

    def packet_bytes(self, p: int) -> int:
        """Size on the wire of packet ``p``."""
        n = min(self.samples_per_packet, self.n_samples - p * self.samples_per_packet)
        k = int(self.summary_k[p])
        block = 0
        if k:
            n_values = k * self.summary_raw.shape[2]
            scales = 4 if self.mean_acc_scale is not None else 2
            block = PK.BLOCK_HEADER_SIZE + scales + (n_values * self.bits + 7) // 8
        return PK.HEADER_SIZE + 2 * self.raw.shape[1] * n + block + PK.CRC_SIZE

    def packet(self, p: int, *, node: int = 0, seq: int | None = None) -> Packet:
        """Packet ``p`` as a :class:`~wsnlib.stream.packet.Packet` (``seq`` default ``p mod 65536``)."""
        s = self.samples_per_packet
        rows = self.raw[p * s: (p + 1) * s]
        k = int(self.summary_k[p])
        summary = None
        if k:
            values = self.summary_raw[p, :k]
            summary = Summary(self.layout, self.bits, float(self.rotation_scale[p]), values[:, :3],
                              None if self.mean_acc_scale is None else float(self.mean_acc_scale[p]),
                              None if self.mean_acc_scale is None else values[:, 3:6])
        return Packet(node=node, seq=p % 65536 if seq is None else seq, first_sample=p * s, fs=self.fs,
                      gyr_raw=rows[:, 0:3], acc_raw=rows[:, 3:6], gyr_scale=self.scales[0], acc_scale=self.scales[1],
                      mag_raw=rows[:, 6:9] if self.has_mag else None, mag_scale=self.scales[2], summary=summary)


def _quantise(values: np.ndarray, scale: float) -> np.ndarray:
    return np.clip(np.round(values / scale), -INT16_MAX, INT16_MAX).astype(np.int64)


def _f16_scales(largest: np.ndarray, limit: int) -> np.ndarray:
    """Per packet the smallest float16 ≥ ``largest / limit`` (> 0)."""
    wanted = largest / limit
    half = wanted.astype(np.float16)
    low = half.astype(float) < wanted
    half[low] = np.nextafter(half[low], np.float16(np.inf))
    half[half <= 0] = np.float16(2.0**-24)
    if not np.all(np.isfinite(half)):
        raise ValueError("a summary value is too large for a float16 scale")
    return half.astype(float)


def node_stream(gyr, acc, mag=None, *, fs: float, samples_per_packet: int = SAMPLES_PER_PACKET, redundancy: int = 0,
                bits: int = 12, layout: str = "doubling", mean_acc: bool = False, scales=None) -> NodeStream:
    """A node's recording (gyr rad/s, acc m/s², mag µT, ``(T, 3)``, body frame, at ``fs`` Hz) as packets.

    ``redundancy`` K = 0…8 summary entries per packet (``layout``, ``bits`` per value, ``mean_acc``);
    ``scales`` (3,) per LSB, default :func:`default_scales`.  ``ValueError`` on bad shapes, NaN, or
    an option out of range.
    """
    fs = check_positive(fs, "fs")
    gyr = as_float_array(gyr, "gyr", last_dim=3)
    acc = as_float_array(acc, "acc", last_dim=3)
    signals = [gyr, acc] + ([] if mag is None else [as_float_array(mag, "mag", last_dim=3)])
    if any(x.ndim != 2 or x.shape != gyr.shape for x in signals) or gyr.shape[0] == 0:
        raise ValueError(f"gyr, acc and mag must all be (T, 3) with T >= 1, got {[x.shape for x in signals]}")
    spp = check_count(samples_per_packet, "samples_per_packet")
    if spp > MAX_SAMPLES_PER_PACKET:
        raise ValueError(f"samples_per_packet must be <= {MAX_SAMPLES_PER_PACKET}, got {spp}")
    k_max = check_count(redundancy, "redundancy", 0)
    if k_max > MAX_REDUNDANCY:
        raise ValueError(f"redundancy must be <= {MAX_REDUNDANCY}, got {k_max}")
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    if not (isinstance(bits, int | np.integer) and REDUNDANCY_BITS[0] <= bits <= REDUNDANCY_BITS[1]):
        raise ValueError(f"bits must be an integer in {list(REDUNDANCY_BITS)}, got {bits!r}")
    scales = default_scales(mag is not None) if scales is None else np.asarray(scales, dtype=float)
    scales = scales.astype(np.float32).astype(float)
    if scales.shape != (3,) or not np.all(scales[: len(signals)] > 0) or not np.all(np.isfinite(scales)):
        raise ValueError(f"scales must be 3 finite numbers > 0 (mag's 0 without magnetometer), got {scales!r}")
    raw = np.concatenate([_quantise(x, scales[i]) for i, x in enumerate(signals)], axis=1)
    values = np.zeros((raw.shape[0], 9))
    values[:, : raw.shape[1]] = raw * np.repeat(scales[: len(signals)], 3)
    n_packets = n_packets_for(raw.shape[0], spp)
    starts = np.arange(n_packets, dtype=np.int64) * spp
    stops = np.minimum(starts + spp, raw.shape[0])
    per_entry = 6 if mean_acc else 3
    summary_raw = np.zeros((n_packets, k_max, per_entry), np.int64)
    k = np.zeros(n_packets, np.int64)
    rotation_scale = np.zeros(n_packets)
    mean_acc_scale = None
    if k_max:
        rotations = np.empty((n_packets, 4))
        PK.packet_rotations(np.ascontiguousarray(values[:, 0:3]), starts, stops, 1.0 / fs, rotations)
        code = LAYOUTS.index(layout)
        vectors = np.zeros((n_packets, k_max, 3))
        PK.summary_rotations(rotations, code, k_max, vectors, k)
        entry = np.arange(k_max)
        used = entry[None, :] < k[:, None]
        limit = (1 << (bits - 1)) - 1
        rotation_scale = _f16_scales(np.abs(np.where(used[..., None], vectors, 0.0)).max(axis=(1, 2)), limit)
        summary_raw[:, :, :3] = np.where(used[..., None], np.round(vectors / rotation_scale[:, None, None]), 0)
        if mean_acc:
            means = _mean_acc(values[:, 3:6], starts, stops, code, k_max)
            mean_acc_scale = _f16_scales(np.abs(np.where(used[..., None], means, 0.0)).max(axis=(1, 2)), limit)
            summary_raw[:, :, 3:6] = np.where(used[..., None], np.round(means / mean_acc_scale[:, None, None]), 0)
        summary_raw = np.clip(summary_raw, -limit, limit)
    return NodeStream(fs=fs, samples_per_packet=spp, scales=scales, raw=raw, values=values, layout=layout,
                      bits=int(bits), summary_raw=summary_raw, summary_k=k, rotation_scale=rotation_scale,
                      mean_acc_scale=mean_acc_scale)


def _mean_acc(acc: np.ndarray, starts, stops, layout_code: int, k_max: int) -> np.ndarray:
    """Mean accelerometer (P, k_max, 3) over the samples each entry covers (zeros where it does not exist)."""
    cumulative = np.concatenate([np.zeros((1, 3)), np.cumsum(acc, axis=0)])
    n_packets = starts.shape[0]
    out = np.zeros((n_packets, k_max, 3))
    for j in range(k_max):
        first = np.arange(n_packets) - (j + 1 if layout_code == PK.CONSECUTIVE else 1 << j)
        last = np.arange(n_packets) - (j + 1 if layout_code == PK.CONSECUTIVE else 1)
        ok = first >= 0
        lo, hi = starts[first[ok]], stops[last[ok]]
        out[ok, j] = (cumulative[hi] - cumulative[lo]) / (hi - lo)[:, None]
    return out


def encode_stream(stream: NodeStream, *, node: int = 0, packets=None, first_seq: int = 0) -> list[bytes]:
    """The bytes of packets ``packets`` (indices; default all) of ``stream``, sequence numbers
    ``first_seq + p`` (mod 65536); ``node`` in 0 … 65535 (the header's 16 bits)."""
    if not isinstance(stream, NodeStream):
        raise ValueError(f"stream must be a NodeStream (node_stream), got {type(stream).__name__}")
    if check_count(node, "node", minimum=0) > 0xFFFF:  # the header would keep its low 16 bits: another node
        raise ValueError(f"node must be an integer in [0, 65535], got {node!r}")
    check_count(first_seq, "first_seq", minimum=0)
    index = np.arange(stream.n_packets) if packets is None else np.asarray(packets)
    if index.ndim != 1 or not (index.size == 0 or np.issubdtype(index.dtype, np.integer)):
        raise ValueError(f"packets must be a 1-D array of packet indices, got shape {index.shape}, dtype {index.dtype}")
    index = index.astype(np.int64)
    if index.size and not (0 <= index.min() and index.max() < stream.n_packets):
        raise ValueError(f"packets must be indices in [0, {stream.n_packets - 1}] (the stream's packets), got "
                         f"{int(index.min())} … {int(index.max())}")
    spp, out = stream.samples_per_packet, {}
    n = np.minimum(spp, stream.n_samples - index * spp)
    shapes = np.stack([n, stream.summary_k[index]], axis=1)
    for shape in np.unique(shapes, axis=0):
        sel = index[np.all(shapes == shape, axis=1)]
        n_p, k = int(shape[0]), int(shape[1])
        rows = (sel[:, None] * spp + np.arange(n_p)[None, :])
        summary = None
        if k:
            summary = (LAYOUTS.index(stream.layout), stream.bits, stream.rotation_scale[sel],
                       None if stream.mean_acc_scale is None else stream.mean_acc_scale[sel],
                       stream.summary_raw[sel, :k])
        encoded = encode_rows(node=np.full(sel.size, node), seq=(first_seq + sel) % 65536, first_sample=sel * spp,
                              fs=stream.fs, scales=stream.scales, samples=stream.raw[rows], summary=summary)
        out.update({int(p): row.tobytes() for p, row in zip(sel, encoded, strict=True)})
    return [out[int(p)] for p in index]
