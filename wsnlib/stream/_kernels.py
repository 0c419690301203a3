"""The stream's compiled code: CRC-16, the packet parser, a packet's integrated rotation.

One file, imported by :mod:`wsnlib.stream` inside :func:`wsnlib.orientation._numba_cache.caching_into_this_version`,
so numba's on-disk cache sees every edit: an edit of this file by its time stamp, an edit of
:mod:`wsnlib.orientation` (whose kernels these call) by the version folder.

The byte layout the parser reads is the table of :mod:`wsnlib.stream.packet`; field positions
below are named there and here alike.  Nothing here raises: :func:`parse` returns a reason code
(:data:`OK` or one of the rejections), and fills its outputs only when the whole packet is valid.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from wsnlib.orientation._scalar_kernels import COMPILE, quat_exp, quat_log, quat_multiply, quat_normalize

# ------------------------------------------------------------------------------------------
# Layout (see the table in wsnlib.stream.packet)
# ------------------------------------------------------------------------------------------

MAGIC0, MAGIC1 = 0x57, 0x53  # b"WS"
VERSION = 1
HEADER_SIZE = 30
CRC_SIZE = 2
BLOCK_HEADER_SIZE = 4  # k, bits, layout, content; then the f16 scale(s)
MAX_SAMPLES = 32
MAX_REDUNDANCY = 8
MIN_BITS, MAX_BITS = 4, 16
FLAG_MAG, FLAG_REDUNDANCY = 1, 2
CONTENT_MEAN_ACC = 1
CONSECUTIVE, DOUBLING = 0, 1
#: Largest plausible norm of one reading (rad/s, m/s², µT): :data:`wsnlib.plausibility.SAMPLE_NORM_MAX`.
GYR_MAX, ACC_MAX, MAG_MAX = 100.0, 2000.0, 1e4
#: A quantised rotation vector may exceed π by rounding, never by more than this factor.
ROTATION_NORM_SLACK = 1.01

#: Reason codes of :func:`parse` (names in :data:`wsnlib.stream.packet.REJECT_REASONS`, same order from 1).
OK, SHORT, BAD_CRC, BAD_VERSION, BAD_FIELD, BAD_LENGTH = 0, 1, 2, 3, 4, 5

#: Integer outputs of :func:`parse` (``ints[...]``).
I_NODE, I_SEQ, I_FIRST, I_N, I_HAS_MAG, I_K, I_BITS, I_LAYOUT, I_HAS_ACC, I_LENGTH = range(10)
N_INTS = 10
#: Float outputs of :func:`parse` (``floats[...]``).
F_FS, F_GYR, F_ACC, F_MAG, F_ROT, F_RACC = range(6)
N_FLOATS = 6


# ------------------------------------------------------------------------------------------
# CRC-16/CCITT-FALSE: polynomial 0x1021, initial 0xFFFF, not reflected, no final XOR
# ------------------------------------------------------------------------------------------


def _crc_table() -> np.ndarray:
    table = np.empty(256, dtype=np.uint16)
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
        table[byte] = crc & 0xFFFF
    return table


CRC_TABLE = _crc_table()


@njit(**COMPILE)
def crc16(buf, start, stop):
    """CRC-16/CCITT-FALSE of ``buf[start:stop]`` (uint8), table-driven (check value of b"123456789": 0x29B1)."""
    crc = 0xFFFF
    for i in range(start, stop):
        crc = ((crc << 8) & 0xFFFF) ^ CRC_TABLE[((crc >> 8) ^ buf[i]) & 0xFF]
    return crc


@njit(**COMPILE)
def crc_rows(packets, lengths):
    """Write each row's CRC (over its first ``lengths[i] − 2`` bytes) big-endian into its last two bytes."""
    for i in range(packets.shape[0]):
        n = lengths[i]
        crc = crc16(packets[i], 0, n - CRC_SIZE)
        packets[i, n - 2] = crc >> 8
        packets[i, n - 1] = crc & 0xFF


# ------------------------------------------------------------------------------------------
# Big-endian fields
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def _u16(buf, i):
    return (np.int64(buf[i]) << 8) | np.int64(buf[i + 1])


@njit(**COMPILE)
def _u32(buf, i):
    return (_u16(buf, i) << 16) | _u16(buf, i + 2)


@njit(**COMPILE)
def _i16(buf, i):
    v = _u16(buf, i)
    return v - 65536 if v >= 32768 else v


@njit(**COMPILE)
def _ieee(u, exponent_bits, mantissa_bits):
    """The IEEE 754 binary float whose bits are ``u`` (``exponent_bits`` + ``mantissa_bits`` + sign); inf and
    NaN come out as NaN: never a valid field here."""
    sign = -1.0 if (u >> (exponent_bits + mantissa_bits)) & 1 else 1.0
    top = (1 << exponent_bits) - 1
    exponent = (u >> mantissa_bits) & top
    mantissa = u & ((1 << mantissa_bits) - 1)
    shift = (top >> 1) + mantissa_bits - 1  # bias + mantissa bits − 1 for subnormals, + 1 for normals
    if exponent == top:
        return np.nan
    if exponent == 0:
        return sign * math.ldexp(float(mantissa), -shift)
    return sign * math.ldexp(float(mantissa | (1 << mantissa_bits)), exponent - shift - 1)


@njit(**COMPILE)
def _f32(buf, i):
    """binary32, big-endian."""
    return _ieee(_u32(buf, i), 8, 23)


@njit(**COMPILE)
def _f16(buf, i):
    """binary16, big-endian."""
    return _ieee(_u16(buf, i), 5, 10)


@njit(**COMPILE)
def _bits(buf, start, bit, width):
    """Unsigned ``width``-bit field at bit offset ``bit`` (MSB first) of the bytes from ``start``."""
    value = 0
    for b in range(bit, bit + width):
        value = (value << 1) | ((np.int64(buf[start + (b >> 3)]) >> (7 - (b & 7))) & 1)
    return value


@njit(**COMPILE)
def _good_scale(x):
    return x > 0.0 and x < np.inf  # NaN fails both


@njit(**COMPILE)
def _norm(x, y, z):
    return math.sqrt(x * x + y * y + z * z)


# ------------------------------------------------------------------------------------------
# The parser
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def parse(buf, n, ints, floats, samples, summary):
    """Validate and read the packet ``buf[:n]`` (uint8); returns :data:`OK` or a rejection code.

    On :data:`OK`: ``ints`` (:data:`N_INTS`,) and ``floats`` (:data:`N_FLOATS`,) hold the header,
    ``samples[:n_samples, :6 or 9]`` the raw int16 readings (gyr, acc, mag per sample) and
    ``summary[:k, :3 or 6]`` the redundancy block's signed values (rotation, then mean acc).
    Checked in this order: the length for a header (``SHORT``), the CRC (``BAD_CRC``), magic and
    version (``BAD_VERSION``), every field (``BAD_FIELD``: reserved bits set, a count or scale out
    of range, a zero accelerometer or magnetometer vector, a reading no sensor gives, a rotation
    longer than π, non-zero padding), the length the fields declare (``SHORT`` if the datagram is
    shorter, ``BAD_LENGTH`` if longer).
    """
    if n < HEADER_SIZE + CRC_SIZE:
        return SHORT
    if crc16(buf, 0, n - CRC_SIZE) != _u16(buf, n - CRC_SIZE):
        return BAD_CRC
    if buf[0] != MAGIC0 or buf[1] != MAGIC1 or buf[2] != VERSION:
        return BAD_VERSION
    flags = np.int64(buf[3])
    if flags & ~(FLAG_MAG | FLAG_REDUNDANCY) or buf[17] != 0:
        return BAD_FIELD
    has_mag = (flags & FLAG_MAG) != 0
    n_samples = np.int64(buf[16])
    fs, gyr_scale, acc_scale, mag_scale = _f32(buf, 12), _f32(buf, 18), _f32(buf, 22), _f32(buf, 26)
    first = _u32(buf, 8)
    if not (1 <= n_samples <= MAX_SAMPLES and _good_scale(fs) and _good_scale(gyr_scale) and _good_scale(acc_scale)
            and (_good_scale(mag_scale) if has_mag else mag_scale == 0.0) and first + n_samples - 1 <= 0xFFFFFFFF):
        return BAD_FIELD
    width = 9 if has_mag else 6
    pos = HEADER_SIZE + n_samples * width * 2
    k, bits, layout, has_acc = 0, 0, 0, False
    rot_scale, racc_scale = 0.0, 0.0
    if flags & FLAG_REDUNDANCY:
        if pos + BLOCK_HEADER_SIZE + CRC_SIZE > n:
            return SHORT
        k, bits = np.int64(buf[pos]), np.int64(buf[pos + 1])
        layout, content = np.int64(buf[pos + 2]), np.int64(buf[pos + 3])
        if not (1 <= k <= MAX_REDUNDANCY and MIN_BITS <= bits <= MAX_BITS and layout in (CONSECUTIVE, DOUBLING)
                and content & ~CONTENT_MEAN_ACC == 0):
            return BAD_FIELD
        has_acc = content & CONTENT_MEAN_ACC != 0
        pos += BLOCK_HEADER_SIZE
        if pos + (4 if has_acc else 2) + CRC_SIZE > n:
            return SHORT
        rot_scale = _f16(buf, pos)
        pos += 2
        if has_acc:
            racc_scale = _f16(buf, pos)
            pos += 2
        if not (_good_scale(rot_scale) and (_good_scale(racc_scale) or not has_acc)):
            return BAD_FIELD
        n_values = k * (6 if has_acc else 3)
        n_bytes = (n_values * bits + 7) // 8
        if pos + n_bytes + CRC_SIZE > n:
            return SHORT
        if pos + n_bytes + CRC_SIZE < n:
            return BAD_LENGTH
        if _bits(buf, pos, n_values * bits, n_bytes * 8 - n_values * bits) != 0:
            return BAD_FIELD  # padding must be zero
        half = np.int64(1) << (bits - 1)
        for v in range(n_values):
            raw = _bits(buf, pos, v * bits, bits)
            summary[v // (6 if has_acc else 3), v % (6 if has_acc else 3)] = raw - 2 * half if raw >= half else raw
        limit = math.pi * ROTATION_NORM_SLACK
        for j in range(k):
            if _norm(summary[j, 0] * rot_scale, summary[j, 1] * rot_scale, summary[j, 2] * rot_scale) > limit:
                return BAD_FIELD
            if has_acc and _norm(summary[j, 3] * racc_scale, summary[j, 4] * racc_scale,
                                 summary[j, 5] * racc_scale) > ACC_MAX:
                return BAD_FIELD
    else:
        if pos + CRC_SIZE > n:
            return SHORT
        if pos + CRC_SIZE < n:
            return BAD_LENGTH
    for s in range(n_samples):
        at = HEADER_SIZE + s * width * 2
        for a in range(width):
            samples[s, a] = _i16(buf, at + 2 * a)
        g = _norm(samples[s, 0], samples[s, 1], samples[s, 2]) * gyr_scale
        acc = _norm(samples[s, 3], samples[s, 4], samples[s, 5]) * acc_scale
        mag = _norm(samples[s, 6], samples[s, 7], samples[s, 8]) * mag_scale if has_mag else 1.0
        if acc == 0.0 or mag == 0.0 or g > GYR_MAX or acc > ACC_MAX or (has_mag and mag > MAG_MAX):
            return BAD_FIELD
    ints[I_NODE], ints[I_SEQ], ints[I_FIRST], ints[I_N] = _u16(buf, 4), _u16(buf, 6), first, n_samples
    ints[I_HAS_MAG], ints[I_K], ints[I_BITS], ints[I_LAYOUT] = has_mag, k, bits, layout
    ints[I_HAS_ACC], ints[I_LENGTH] = has_acc, n
    floats[F_FS], floats[F_GYR], floats[F_ACC], floats[F_MAG] = fs, gyr_scale, acc_scale, mag_scale
    floats[F_ROT], floats[F_RACC] = rot_scale, racc_scale
    return OK


# ------------------------------------------------------------------------------------------
# A packet's integrated rotation (what the redundancy block summarises)
# ------------------------------------------------------------------------------------------


@njit(**COMPILE)
def integrated_rotation(gyr, start, stop, dt):
    """``Π_k Exp(ω_k Δt)`` over ``gyr[start:stop]`` (rad/s, body frame): the rotation of the body
    frame over those samples, as the filter's strapdown prediction composes it (a quaternion tuple)."""
    q = (1.0, 0.0, 0.0, 0.0)
    for k in range(start, stop):
        q = quat_normalize(quat_multiply(q, quat_exp((gyr[k, 0] * dt, gyr[k, 1] * dt, gyr[k, 2] * dt))))
    return q


@njit(**COMPILE)
def packet_rotations(gyr, starts, stops, dt, out):
    """``out[p]`` (P, 4): :func:`integrated_rotation` of ``gyr[starts[p]:stops[p]]``."""
    for p in range(starts.shape[0]):
        q = integrated_rotation(gyr, starts[p], stops[p], dt)
        for a in range(4):
            out[p, a] = q[a]


@njit(**COMPILE)
def span_rotation_vectors(rotations, packet, layout, k, out):
    """The redundancy entries of ``packet``: ``out[j]`` (k, 3) the rotation vector (Log) of the
    packets entry ``j`` covers — consecutive: packet ``packet − 1 − j``; doubling: packets
    ``packet − 2^j … packet − 1`` — from the per-packet quaternions ``rotations`` (P, 4)."""
    for j in range(k):
        if layout == CONSECUTIVE:
            first = last = packet - 1 - j
        else:
            first, last = packet - (1 << j), packet - 1
        q = (1.0, 0.0, 0.0, 0.0)
        for p in range(first, last + 1):
            q = quat_normalize(quat_multiply(q, (rotations[p, 0], rotations[p, 1], rotations[p, 2], rotations[p, 3])))
        r = quat_log(q)
        for a in range(3):
            out[j, a] = r[a]


@njit(**COMPILE)
def summary_rotations(rotations, layout, k_max, out, k):
    """Every packet's redundancy entries: ``out[p, :k[p]]`` (P, k_max, 3) from the per-packet rotations
    ``rotations`` (P, 4); ``k[p]`` the entries packet ``p`` can carry (its covered packets exist)."""
    for p in range(rotations.shape[0]):
        n = 0
        while n < k_max and (p - 1 - n >= 0 if layout == CONSECUTIVE else p - (1 << n) >= 0):
            n += 1
        k[p] = n
        span_rotation_vectors(rotations, p, layout, n, out[p])
