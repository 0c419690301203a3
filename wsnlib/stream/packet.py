"""The stream's binary packet, version 1: :func:`encode_packet`, :func:`decode_packet`.

A node sends its samples in packets of ``n_samples`` consecutive samples (6 in paper 001, Sec.
IV), each reading an int16 with one scale per sensor, an optional *redundancy block* that
summarises the rotation of the node's previous packets (so a receiver can bridge a burst of lost
packets with the measured rotation, :mod:`wsnlib.stream.receiver`), and a CRC.  Every multi-byte
field is big-endian (network order).  Version 1:

======  =====  ==================  ===================================================================
offset  bytes  field               meaning
======  =====  ==================  ===================================================================
0       2      magic               ``b"WS"``
2       1      version             1
3       1      flags               bit 0: magnetometer present; bit 1: redundancy block present;
                                   bits 2–7 zero
4       2      node                node id, 0–65535
6       2      seq                 sequence number, +1 per packet, wraps 65535 → 0
8       4      first_sample        index of the packet's first sample since the node started (u32)
12      4      fs                  sampling rate (Hz), float32, finite and > 0
16      1      n_samples           samples in this packet, 1–32
17      1      reserved            0
18      4      gyr_scale           rad/s per LSB, float32, finite and > 0
22      4      acc_scale           m/s² per LSB, float32, finite and > 0
26      4      mag_scale           µT per LSB, float32, finite and > 0 (0 without magnetometer)
30      2·w·n  samples             per sample ``gx gy gz ax ay az [mx my mz]`` int16 (w = 9 with
                                   magnetometer, 6 without); value = int16 × scale, body frame
…       1      k                   (redundancy block) entries, 1–8
…       1      bits                bits per value, 4–16
…       1      layout              0 consecutive: entry j (0-based) is the packet ``seq − 1 − j``;
                                   1 doubling: entry j covers the ``2^j`` packets ``seq − 2^j …
                                   seq − 1``
…       1      content             bit 0: mean accelerometer per entry; bits 1–7 zero
…       2      rotation_scale      rad per LSB, float16, finite and > 0
…       2      mean_acc_scale      m/s² per LSB, float16 (only with content bit 0)
…       ⌈v·b/8⌉ values             v = k·3 (·6 with mean acc) signed ``bits``-bit two's complement
                                   values, MSB first, entry by entry: the rotation vector (Log of
                                   ``Π Exp(ω Δt)`` over the covered samples, body frame, rad),
                                   then the mean accelerometer (m/s²); zero padding to a byte
end−2   2      crc                 CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, not reflected, no
                                   final XOR) of every byte before it
======  =====  ==================  ===================================================================

Sizes: 30 + 18·n + 2 bytes with magnetometer (140 for 6 samples); the block adds
``4 + 2 (+2) + ⌈v·b/8⌉`` (K = 4 doubling entries of 12 bits: 24 bytes, 17 %).

A datagram is rejected — never half-read — with one of :data:`REJECT_REASONS`: ``"short"``
(shorter than a header and CRC, or than its fields declare), ``"crc"``, ``"version"`` (magic or
version unknown), ``"field"`` (an impossible field: a reserved bit set, a count or scale out of
range, a zero accelerometer or magnetometer vector, a reading no sensor gives —
:data:`wsnlib.plausibility.SAMPLE_NORM_MAX` —, a rotation vector longer than π, non-zero
padding) or ``"length"`` (longer than its fields declare).  :func:`decode_packet` raises
:class:`PacketError` with that ``reason``; the receiver counts it.

Versioning: a reader accepts exactly the versions it knows (here 1); a change of the layout
gets a new version number, and this table stays as the definition of version 1.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from wsnlib.stream import _kernels as K

PACKET_VERSION = K.VERSION
MAGIC = bytes([K.MAGIC0, K.MAGIC1])
HEADER_SIZE = K.HEADER_SIZE
MAX_SAMPLES_PER_PACKET = K.MAX_SAMPLES
MAX_REDUNDANCY = K.MAX_REDUNDANCY
REDUNDANCY_BITS = (K.MIN_BITS, K.MAX_BITS)
#: Layouts of the redundancy block, in code order.
LAYOUTS = ("consecutive", "doubling")
#: Why a datagram is rejected (:attr:`PacketError.reason`), in the parser's code order.
REJECT_REASONS = ("short", "crc", "version", "field", "length")
#: Largest datagram of version 1 (32 samples with magnetometer, 8 entries of 16 bits with mean acc).
MAX_PACKET_SIZE = HEADER_SIZE + 18 * K.MAX_SAMPLES + K.BLOCK_HEADER_SIZE + 4 + 2 * 6 * K.MAX_REDUNDANCY + K.CRC_SIZE

#: Full scales of the default int16 quantisation (a body-worn MEMS IMU's ranges): ±2000 °/s, ±16 g, ±1300 µT.
GYR_FULL_SCALE = math.radians(2000.0)
ACC_FULL_SCALE = 16.0 * 9.80665
MAG_FULL_SCALE = 1300.0
INT16_MAX = 32767

_HEADER = np.dtype([("magic", "S2"), ("version", "u1"), ("flags", "u1"), ("node", ">u2"), ("seq", ">u2"),
                    ("first_sample", ">u4"), ("fs", ">f4"), ("n_samples", "u1"), ("reserved", "u1"),
                    ("gyr_scale", ">f4"), ("acc_scale", ">f4"), ("mag_scale", ">f4")])
assert _HEADER.itemsize == HEADER_SIZE


class PacketError(ValueError):
    """A datagram that is not a valid packet; ``reason`` is one of :data:`REJECT_REASONS`."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


def crc16_ccitt_false(data) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (bytes-like): ``crc16_ccitt_false(b"123456789") == 0x29B1``."""
    buf = np.frombuffer(bytes(data), dtype=np.uint8)
    return int(K.crc16(buf, 0, buf.size))


def _float32(value) -> float:
    return float(np.float32(value))


def _float16_at_least(value: float) -> float:
    """The smallest positive float16 ≥ ``value`` (≥ 0; finite)."""
    half = np.float16(value)
    if float(half) < value:
        half = np.nextafter(half, np.float16(np.inf))
    if half <= 0:
        half = np.float16(2.0**-24)
    if not np.isfinite(half):
        raise ValueError(f"a redundancy scale of {value!r} does not fit a float16")
    return float(half)


def _raw(values, name: str, width: int) -> np.ndarray:
    arr = np.asarray(values)
    if arr.ndim != 2 or arr.shape[1] != width or not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name} must be an integer array (n, {width}), got {arr.dtype} {arr.shape}")
    if arr.size and (arr.min() < -32768 or arr.max() > INT16_MAX):
        raise ValueError(f"{name} must hold int16 values")
    return arr.astype(np.int64)


@dataclasses.dataclass(frozen=True, eq=False)
class Summary:
    """A packet's redundancy block: the rotation (and optionally the mean accelerometer) of earlier packets.

    Build one from rotation vectors with :meth:`quantise`.  Attributes: ``layout``
    (:data:`LAYOUTS`), ``bits`` per value, ``rotation_scale`` (rad per LSB, a float16 value),
    ``rotation_raw`` (k, 3) ints; ``mean_acc_scale`` (m/s² per LSB) and ``mean_acc_raw`` (k, 3),
    or None.
    """

    layout: str
    bits: int
    rotation_scale: float
    rotation_raw: np.ndarray
    mean_acc_scale: float | None = None
    mean_acc_raw: np.ndarray | None = None

    def __post_init__(self):
        if self.layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}, got {self.layout!r}")
        if not (isinstance(self.bits, int | np.integer) and REDUNDANCY_BITS[0] <= self.bits <= REDUNDANCY_BITS[1]):
            raise ValueError(f"bits must be an integer in {list(REDUNDANCY_BITS)}, got {self.bits!r}")
        rot = np.asarray(self.rotation_raw)
        if rot.ndim != 2 or rot.shape[1] != 3 or not 1 <= rot.shape[0] <= MAX_REDUNDANCY:
            raise ValueError(f"rotation_raw must be (k, 3) with 1 <= k <= {MAX_REDUNDANCY}, got shape {rot.shape}")
        limit = (1 << (self.bits - 1)) - 1
        for name, raw in (("rotation_raw", rot), ("mean_acc_raw", self.mean_acc_raw)):
            if raw is not None and (np.asarray(raw).shape != rot.shape or np.abs(raw).max() > limit):
                raise ValueError(f"{name} must be (k, 3) integers within ±{limit} for {self.bits} bits")
        if (self.mean_acc_raw is None) != (self.mean_acc_scale is None):
            raise ValueError("mean_acc_raw and mean_acc_scale go together")
        for name in ("rotation_scale", "mean_acc_scale"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0 and float(np.float16(value)) == value):
                raise ValueError(f"{name} must be a positive float16 value, got {value!r}")

    @classmethod
    def quantise(cls, rotations, *, bits: int, layout: str, mean_acc=None) -> Summary:
        """Quantise rotation vectors ``(k, 3)`` (rad; and mean accelerometer readings (k, 3), m/s²) to
        ``bits`` signed bits with one float16 scale each, the smallest that holds the largest value."""
        rotations = np.asarray(rotations, dtype=float)
        limit = (1 << (bits - 1)) - 1 if isinstance(bits, int | np.integer) else 1

        def quantised(values):
            scale = _float16_at_least(float(np.max(np.abs(values), initial=0.0)) / limit)
            return scale, np.clip(np.round(values / scale), -limit, limit).astype(np.int64)

        rot_scale, rot_raw = quantised(rotations)
        acc_scale, acc_raw = (None, None) if mean_acc is None else quantised(np.asarray(mean_acc, dtype=float))
        return cls(layout, int(bits), rot_scale, rot_raw, acc_scale, acc_raw)

    @property
    def k(self) -> int:
        """Number of entries."""
        return int(np.asarray(self.rotation_raw).shape[0])

    @property
    def rotations(self) -> np.ndarray:
        """Rotation vectors (k, 3), rad, body frame: entry j covers the packets :meth:`covered` gives."""
        return np.asarray(self.rotation_raw, dtype=float) * self.rotation_scale

    @property
    def mean_acc(self) -> np.ndarray | None:
        """Mean accelerometer (k, 3), m/s², or None."""
        return None if self.mean_acc_raw is None else np.asarray(self.mean_acc_raw, dtype=float) * self.mean_acc_scale

    def covered(self, j: int) -> tuple[int, int]:
        """``(first, last)``: entry ``j`` covers the packets ``seq − first … seq − last`` before its own."""
        return (j + 1, j + 1) if self.layout == "consecutive" else (1 << j, 1)

    @property
    def size(self) -> int:
        """Bytes of the block in a packet."""
        n_values = self.k * (3 if self.mean_acc_raw is None else 6)
        return K.BLOCK_HEADER_SIZE + (2 if self.mean_acc_raw is None else 4) + (n_values * self.bits + 7) // 8


@dataclasses.dataclass(frozen=True, eq=False)
class Packet:
    """One packet: header, raw int16 readings with their scales, and an optional :class:`Summary`.

    ``gyr``, ``acc``, ``mag`` are the readings in physical units (``raw × scale``, float64: exactly
    what a receiver reconstructs).  Scales are stored as float32 values (as on the wire).
    """

    node: int
    seq: int
    first_sample: int
    fs: float
    gyr_raw: np.ndarray
    acc_raw: np.ndarray
    gyr_scale: float
    acc_scale: float
    mag_raw: np.ndarray | None = None
    mag_scale: float = 0.0
    summary: Summary | None = None

    def __post_init__(self):
        for name, top in (("node", 0xFFFF), ("seq", 0xFFFF), ("first_sample", 0xFFFFFFFF)):
            value = getattr(self, name)
            if not (isinstance(value, int | np.integer) and 0 <= value <= top):
                raise ValueError(f"{name} must be an integer in [0, {top}], got {value!r}")
        object.__setattr__(self, "gyr_raw", _raw(self.gyr_raw, "gyr_raw", 3))
        object.__setattr__(self, "acc_raw", _raw(self.acc_raw, "acc_raw", 3))
        n = self.gyr_raw.shape[0]
        if not 1 <= n <= MAX_SAMPLES_PER_PACKET or self.acc_raw.shape[0] != n:
            raise ValueError(f"a packet holds 1 to {MAX_SAMPLES_PER_PACKET} samples, gyr_raw and acc_raw alike; got "
                             f"{n} and {self.acc_raw.shape[0]}")
        if self.first_sample + n - 1 > 0xFFFFFFFF:
            raise ValueError("first_sample + n_samples − 1 must fit 32 bits")
        if self.mag_raw is not None:
            object.__setattr__(self, "mag_raw", _raw(self.mag_raw, "mag_raw", 3))
            if self.mag_raw.shape[0] != n:
                raise ValueError(f"mag_raw must have {n} rows, got {self.mag_raw.shape[0]}")
        for name in ("fs", "gyr_scale", "acc_scale") + (("mag_scale",) if self.mag_raw is not None else ()):
            value = _float32(getattr(self, name))
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0 as a float32, got {getattr(self, name)!r}")
            object.__setattr__(self, name, value)
        if self.mag_raw is None:
            object.__setattr__(self, "mag_scale", 0.0)
        if self.summary is not None and not isinstance(self.summary, Summary):
            raise ValueError(f"summary must be a Summary or None, got {type(self.summary).__name__}")

    @property
    def n_samples(self) -> int:
        return self.gyr_raw.shape[0]

    gyr = property(lambda self: self.gyr_raw * self.gyr_scale, doc="Angular rate (n, 3), rad/s, body frame.")
    acc = property(lambda self: self.acc_raw * self.acc_scale, doc="Specific force (n, 3), m/s², body frame.")
    mag = property(lambda self: None if self.mag_raw is None else self.mag_raw * self.mag_scale,
                   doc="Magnetic field (n, 3), µT, body frame, or None.")

    @property
    def size(self) -> int:
        """Bytes on the wire."""
        width = 6 if self.mag_raw is None else 9
        block = 0 if self.summary is None else self.summary.size
        return HEADER_SIZE + 2 * width * self.n_samples + block + K.CRC_SIZE


# ------------------------------------------------------------------------------------------
# Encoding: many packets of one shape at once (the sender), or one (encode_packet)
# ------------------------------------------------------------------------------------------


def encode_rows(*, node, seq, first_sample, fs: float, scales, samples, summary=None) -> np.ndarray:
    """Packets of one shape as rows of bytes ``(P, size)`` (uint8).

    ``node``, ``seq``, ``first_sample`` (P,) ints; ``fs`` Hz; ``scales`` (3,) gyr, acc, mag (0 without
    magnetometer); ``samples`` (P, n, 6 or 9) int16 readings; ``summary`` None or a tuple
    ``(layout_code, bits, rotation_scale (P,), mean_acc_scale (P,) or None, values (P, k, 3 or 6))``.
    Fields are not checked here (:class:`Packet` checks them).
    """
    samples = np.asarray(samples)
    n_packets, n, width = samples.shape
    header = np.zeros(n_packets, _HEADER)
    header["magic"], header["version"] = MAGIC, PACKET_VERSION
    header["flags"] = (K.FLAG_MAG if width == 9 else 0) | (K.FLAG_REDUNDANCY if summary is not None else 0)
    header["node"], header["seq"], header["first_sample"] = node, seq, first_sample
    header["fs"], header["n_samples"] = fs, n
    header["gyr_scale"], header["acc_scale"], header["mag_scale"] = scales
    parts = [header.view(np.uint8).reshape(n_packets, HEADER_SIZE),
             samples.astype(">i2").view(np.uint8).reshape(n_packets, 2 * n * width)]
    if summary is not None:
        layout, bits, rot_scale, acc_scale, values = summary
        k, per_entry = values.shape[1], values.shape[2]
        block = np.zeros((n_packets, K.BLOCK_HEADER_SIZE), dtype=np.uint8)
        block[:, 0], block[:, 1], block[:, 2] = k, bits, layout
        block[:, 3] = K.CONTENT_MEAN_ACC if per_entry == 6 else 0
        scales16 = [np.asarray(rot_scale, dtype=">f2")] + ([] if acc_scale is None else [np.asarray(acc_scale, ">f2")])
        parts += [block] + [s.reshape(n_packets, 1).view(np.uint8) for s in scales16]
        flat = values.reshape(n_packets, -1).astype(np.int64) & ((1 << bits) - 1)  # two's complement
        shifts = np.arange(bits - 1, -1, -1)
        bit_array = ((flat[..., None] >> shifts) & 1).astype(np.uint8).reshape(n_packets, -1)
        parts.append(np.packbits(bit_array, axis=1))
    parts.append(np.zeros((n_packets, K.CRC_SIZE), dtype=np.uint8))
    rows = np.ascontiguousarray(np.concatenate(parts, axis=1))
    K.crc_rows(rows, np.full(n_packets, rows.shape[1], dtype=np.int64))
    return rows


def encode_packet(packet: Packet) -> bytes:
    """The bytes of ``packet`` (version 1, the module's table)."""
    if not isinstance(packet, Packet):
        raise ValueError(f"packet must be a Packet, got {type(packet).__name__}")
    signals = [packet.gyr_raw, packet.acc_raw] + ([] if packet.mag_raw is None else [packet.mag_raw])
    s = packet.summary
    summary = None
    if s is not None:
        values = s.rotation_raw if s.mean_acc_raw is None else np.concatenate([s.rotation_raw, s.mean_acc_raw], axis=1)
        summary = (LAYOUTS.index(s.layout), s.bits, [s.rotation_scale],
                   None if s.mean_acc_scale is None else [s.mean_acc_scale], values[None])
    rows = encode_rows(node=[packet.node], seq=[packet.seq], first_sample=[packet.first_sample], fs=packet.fs,
                       scales=(packet.gyr_scale, packet.acc_scale, packet.mag_scale),
                       samples=np.concatenate(signals, axis=1)[None], summary=summary)
    return rows[0].tobytes()


# ------------------------------------------------------------------------------------------
# Decoding
# ------------------------------------------------------------------------------------------


class ParseBuffers:
    """Scratch for :func:`wsnlib.stream._kernels.parse` (one packet)."""

    def __init__(self):
        self.ints = np.zeros(K.N_INTS, dtype=np.int64)
        self.floats = np.zeros(K.N_FLOATS)
        self.samples = np.zeros((K.MAX_SAMPLES, 9), dtype=np.int64)
        self.summary = np.zeros((K.MAX_REDUNDANCY, 6), dtype=np.int64)


_REJECT_MESSAGES = {
    "short": "shorter than a header and CRC, or than its fields declare",
    "crc": "its CRC-16/CCITT-FALSE does not match",
    "version": f"not a version-{PACKET_VERSION} packet (magic {MAGIC!r} and version byte)",
    "field": "an impossible field (reserved bit, count or scale out of range, zero or implausible reading, "
             "rotation > π, non-zero padding)",
    "length": "longer than its fields declare",
}


def decode_packet(data) -> Packet:
    """Read one datagram (bytes-like) into a :class:`Packet`; :class:`PacketError` (a ``ValueError``)
    with ``reason`` in :data:`REJECT_REASONS` if it is not a valid version-1 packet.

    Everything is checked (the module's table) before anything is returned.
    """
    buf = np.frombuffer(bytes(data), dtype=np.uint8)
    out = ParseBuffers()
    code = K.parse(buf, buf.size, out.ints, out.floats, out.samples, out.summary)
    if code != K.OK:
        reason = REJECT_REASONS[code - 1]
        raise PacketError(reason, f"rejected packet of {buf.size} bytes: {_REJECT_MESSAGES[reason]}")
    ints, floats = out.ints, out.floats
    n, has_mag = int(ints[K.I_N]), bool(ints[K.I_HAS_MAG])
    raw = out.samples[:n]
    summary = None
    if ints[K.I_K]:
        k, has_acc = int(ints[K.I_K]), bool(ints[K.I_HAS_ACC])
        summary = Summary(LAYOUTS[int(ints[K.I_LAYOUT])], int(ints[K.I_BITS]), float(floats[K.F_ROT]),
                          out.summary[:k, :3].copy(), float(floats[K.F_RACC]) if has_acc else None,
                          out.summary[:k, 3:6].copy() if has_acc else None)
    return Packet(node=int(ints[K.I_NODE]), seq=int(ints[K.I_SEQ]), first_sample=int(ints[K.I_FIRST]),
                  fs=float(floats[K.F_FS]), gyr_raw=raw[:, :3].copy(), acc_raw=raw[:, 3:6].copy(),
                  gyr_scale=float(floats[K.F_GYR]), acc_scale=float(floats[K.F_ACC]),
                  mag_raw=raw[:, 6:9].copy() if has_mag else None, mag_scale=float(floats[K.F_MAG]), summary=summary)
