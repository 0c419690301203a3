"""The stream's packet format (issue 27): CRC, round trip, and every rejection counted by reason."""

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wsnlib.stream import (
    LAYOUTS,
    REJECT_REASONS,
    Packet,
    PacketError,
    Summary,
    crc16_ccitt_false,
    decode_packet,
    encode_packet,
)
from wsnlib.stream import packet as P


def test_crc_matches_the_catalogued_check_value():
    # CRC-16/CCITT-FALSE ("CRC-16/IBM-3740" in Greg Cook's catalogue): check 0x29B1, init 0xFFFF
    assert crc16_ccitt_false(b"123456789") == 0x29B1
    assert crc16_ccitt_false(b"") == 0xFFFF
    assert crc16_ccitt_false(b"A") == 0xB915


def _packet(rng, *, n=6, mag=True, summary=None, seq=3, node=11, first=18):
    return Packet(node=node, seq=seq, first_sample=first, fs=50.0, gyr_raw=rng.integers(-3000, 3000, (n, 3)),
                  acc_raw=rng.integers(500, 3000, (n, 3)), gyr_scale=1.0652e-3, acc_scale=4.7883e-3,
                  mag_raw=rng.integers(200, 2000, (n, 3)) if mag else None, mag_scale=0.0397 if mag else 0.0,
                  summary=summary)


def _summary(rng, k=4, bits=12, layout="doubling", acc=False):
    return Summary.quantise(rng.uniform(-1.0, 1.0, (k, 3)), bits=bits, layout=layout,
                            mean_acc=rng.uniform(-12, 12, (k, 3)) if acc else None)


def _same(a: Packet, b: Packet) -> bool:
    fields = ("node", "seq", "first_sample", "fs", "gyr_scale", "acc_scale", "mag_scale")
    same = all(getattr(a, f) == getattr(b, f) for f in fields)
    same &= np.array_equal(a.gyr, b.gyr) and np.array_equal(a.acc, b.acc)
    same &= (a.mag is None) == (b.mag is None) and (a.mag is None or np.array_equal(a.mag, b.mag))
    if a.summary is None or b.summary is None:
        return same and a.summary is None and b.summary is None
    sa, sb = a.summary, b.summary
    same &= (sa.layout, sa.bits, sa.rotation_scale, sa.mean_acc_scale) == (sb.layout, sb.bits, sb.rotation_scale,
                                                                             sb.mean_acc_scale)
    same &= np.array_equal(sa.rotations, sb.rotations)
    return same and (sa.mean_acc is None) == (sb.mean_acc is None) and (
        sa.mean_acc is None or np.array_equal(sa.mean_acc, sb.mean_acc))


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 32), mag=st.booleans(), k=st.integers(0, 8), bits=st.integers(4, 16),
       layout=st.sampled_from(LAYOUTS), acc=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_round_trip_and_size(n, mag, k, bits, layout, acc, seed):
    rng = np.random.default_rng(seed)
    summary = _summary(rng, k, bits, layout, acc) if k else None
    packet = _packet(rng, n=n, mag=mag, summary=summary, seq=int(rng.integers(0, 65536)),
                     node=int(rng.integers(0, 65536)), first=int(rng.integers(0, 2**32 - n)))
    data = encode_packet(packet)
    assert len(data) == packet.size
    assert _same(decode_packet(data), packet)


def test_summary_quantisation_error_is_at_most_half_a_step():
    rng = np.random.default_rng(3)
    rotations = rng.uniform(-3.0, 3.0, (4, 3))
    for bits in (4, 8, 12, 16):
        s = Summary.quantise(rotations, bits=bits, layout="consecutive")
        assert s.rotation_scale * ((1 << (bits - 1)) - 1) >= np.abs(rotations).max()
        assert np.abs(s.rotations - rotations).max() <= 0.5 * s.rotation_scale
    assert Summary.quantise(np.zeros((1, 3)), bits=8, layout="doubling").rotation_scale > 0


def _with_crc(data: bytes) -> bytes:
    body = bytes(data[:-2])
    return body + struct.pack(">H", crc16_ccitt_false(body))


def _edit(data: bytes, offset: int, new: bytes) -> bytes:
    out = bytearray(data)
    out[offset:offset + len(new)] = new
    return _with_crc(bytes(out))


def _reason(data) -> str:
    with pytest.raises(PacketError) as info:
        decode_packet(data)
    assert isinstance(info.value, ValueError)
    return info.value.reason


def test_short_and_long_datagrams():
    rng = np.random.default_rng(1)
    data = encode_packet(_packet(rng, summary=_summary(rng)))
    assert _reason(b"") == "short"
    assert _reason(data[:31]) == "short"
    for cut in range(32, len(data)):  # cut anywhere, CRC fixed: the fields declare more than is there
        assert _reason(_with_crc(data[:cut - 2] + b"\0\0")) == "short", cut
    assert _reason(_with_crc(data[:-2] + b"\0" + b"\0\0")) == "length"
    plain = encode_packet(_packet(rng))
    assert _reason(_with_crc(plain[:-2] + b"\0\0" + b"\0\0")) == "length"


@settings(max_examples=200, deadline=None)
@given(bit=st.integers(0, 8 * 140 - 1))
def test_every_single_bit_error_is_caught_by_the_crc(bit):
    data = bytearray(encode_packet(_packet(np.random.default_rng(2))))
    data[bit // 8] ^= 1 << (bit % 8)
    assert _reason(bytes(data)) == "crc"


@settings(max_examples=300, deadline=None)
@given(data=st.binary(min_size=0, max_size=300))
def test_garbage_is_rejected_never_raises_otherwise(data):
    try:
        decode_packet(data)
    except PacketError as exc:
        assert exc.reason in REJECT_REASONS


def test_unknown_version_or_magic():
    data = encode_packet(_packet(np.random.default_rng(4)))
    assert _reason(_edit(data, 2, b"\x02")) == "version"
    assert _reason(_edit(data, 0, b"WT")) == "version"


def _f32(x):
    return struct.pack(">f", x)


def _f16(x):
    return np.array([x], dtype=">f2").tobytes()


@pytest.mark.parametrize("offset,new", [
    (3, b"\x05"),                        # a reserved flag bit
    (17, b"\x01"),                       # the reserved byte
    (16, b"\x00"),                       # no samples
    (16, b"\x21"),                       # 33 samples
    (12, _f32(0.0)), (12, _f32(-50.0)), (12, _f32(float("nan"))), (12, _f32(float("inf"))),  # fs
    (18, _f32(0.0)), (22, _f32(-1.0)), (26, _f32(float("nan"))),  # scales
    (18, _f32(1.0)),                     # gyro readings of thousands of rad/s
    (30 + 6, b"\0\0\0\0\0\0"),           # a zero accelerometer vector
    (30 + 12, b"\0\0\0\0\0\0"),          # a zero magnetometer vector
])
def test_impossible_header_and_sample_fields(offset, new):
    data = encode_packet(_packet(np.random.default_rng(5)))
    assert _reason(_edit(data, offset, new)) == "field"


def test_magnetometer_scale_must_be_zero_without_magnetometer():
    data = encode_packet(_packet(np.random.default_rng(6), mag=False))
    assert _reason(_edit(data, 26, _f32(0.04))) == "field"


@pytest.mark.parametrize("offset,new", [
    (0, b"\x00"), (0, b"\x09"),          # k
    (1, b"\x03"), (1, b"\x11"),          # bits
    (2, b"\x02"),                        # layout
    (3, b"\x02"),                        # content
    (4, _f16(0.0)), (4, _f16(float("nan"))), (4, _f16(-0.01)),   # rotation scale
    (4, _f16(0.5)),                      # rotation vectors far longer than π
])
def test_impossible_redundancy_fields(offset, new):
    rng = np.random.default_rng(7)
    data = encode_packet(_packet(rng, summary=_summary(rng, k=2, bits=12)))
    block = 30 + 18 * 6
    assert _reason(_edit(data, block + offset, new)) == "field"


def test_redundancy_counts_that_change_the_length_are_caught():
    rng = np.random.default_rng(8)
    data = encode_packet(_packet(rng, summary=_summary(rng, k=2, bits=12)))
    block = 30 + 18 * 6
    assert _reason(_edit(data, block, b"\x00")) == "field"    # k = 0
    assert _reason(_edit(data, block, b"\x03")) == "short"    # k = 3: more values than sent
    assert _reason(_edit(data, block, b"\x01")) == "length"   # k = 1: fewer
    assert _reason(_edit(data, block + 1, b"\x03")) == "field"


def test_non_zero_padding_is_an_impossible_field():
    rng = np.random.default_rng(9)
    data = encode_packet(_packet(rng, summary=_summary(rng, k=1, bits=5)))  # 15 bits: 1 padding bit
    assert _reason(_edit(data, len(data) - 3, bytes([data[-3] | 1]))) == "field"


def test_packet_and_summary_refuse_bad_fields():
    rng = np.random.default_rng(10)
    with pytest.raises(ValueError, match="seq"):
        _packet(rng, seq=65536)
    with pytest.raises(ValueError, match="1 to 32"):
        _packet(rng, n=33)
    with pytest.raises(ValueError, match="bits"):
        Summary.quantise(np.zeros((1, 3)), bits=17, layout="doubling")
    with pytest.raises(ValueError, match="layout"):
        Summary.quantise(np.zeros((1, 3)), bits=8, layout="fibonacci")
    with pytest.raises(ValueError, match="k <= 8"):
        Summary.quantise(np.zeros((9, 3)), bits=8, layout="doubling")
    with pytest.raises(ValueError, match="Packet"):
        encode_packet(b"not a packet")
    assert P.MAX_PACKET_SIZE >= _packet(rng, n=32, summary=_summary(rng, 8, 16, acc=True)).size
