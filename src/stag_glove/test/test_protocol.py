"""STAG readout protocol: packing, framing, CRC, resynchronisation (hypothesis fuzzing)."""
import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from stag_glove.protocol import SYNC, GloveStreamParser, crc16_ccitt, encode_frame, frame_size, pack10, unpack10


def frame(seed: int, rows: int = 32, cols: int = 32) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 1024, (rows, cols)).astype(np.uint16)


def test_crc_is_ccitt_false():
    assert crc16_ccitt(b"123456789") == 0x29B1


def test_pack10_known_bytes():
    # readings 0x3FF, 0, 0x155, 1: 40-bit LE word = 0x3FF | 0x155 << 20 | 1 << 30
    word = 0x3FF | (0x155 << 20) | (1 << 30)
    assert pack10(np.array([0x3FF, 0, 0x155, 1])) == word.to_bytes(5, "little")


@given(st.lists(st.integers(0, 1023), min_size=0, max_size=64).filter(lambda v: len(v) % 4 == 0))
def test_pack_unpack_round_trip(values):
    data = pack10(np.array(values, dtype=np.uint16))
    assert len(data) == len(values) * 5 // 4
    np.testing.assert_array_equal(unpack10(data, len(values)), values)


def test_frame_layout_and_size():
    raw = frame(0)
    data = encode_frame(raw, sequence=0x1234)
    assert len(data) == frame_size() == 1289
    assert data[:2] == SYNC and data[2:5] == bytes([1, 32, 32])
    assert struct.unpack("<H", data[5:7])[0] == 0x1234
    assert struct.unpack("<H", data[-2:])[0] == crc16_ccitt(data[2:-2])


def test_parser_returns_frames_fed_byte_by_byte():
    parser = GloveStreamParser()
    raws = [frame(i) for i in range(3)]
    stream = b"".join(encode_frame(r, i) for i, r in enumerate(raws))
    got = []
    for i in range(len(stream)):
        got += parser.feed(stream[i:i + 1])
    assert [f.sequence for f in got] == [0, 1, 2]
    for f, r in zip(got, raws):
        np.testing.assert_array_equal(f.raw, r)
    assert parser.stats.discarded_bytes == 0 and parser.stats.dropped_frames == 0


def test_crc_error_is_counted_and_the_next_frame_survives():
    parser = GloveStreamParser()
    bad = bytearray(encode_frame(frame(1), 0))
    bad[100] ^= 0x01
    got = parser.feed(bytes(bad) + encode_frame(frame(2), 1))
    assert [f.sequence for f in got] == [1]
    assert parser.stats.crc_errors == 1
    np.testing.assert_array_equal(got[0].raw, frame(2))


def test_sequence_gaps_count_dropped_frames_and_wrap():
    parser = GloveStreamParser()
    parser.feed(encode_frame(frame(0), 65534))
    parser.feed(encode_frame(frame(0), 1))  # 65535 and 0 lost across the wrap
    assert parser.stats.dropped_frames == 2
    parser.feed(encode_frame(frame(0), 2))
    assert parser.stats.dropped_frames == 2


def test_unexpected_header_is_rejected():
    parser = GloveStreamParser(rows=32, cols=32)
    small = encode_frame(frame(0, 4, 4), 0)
    got = parser.feed(small + encode_frame(frame(3), 1))
    assert [f.sequence for f in got] == [1]
    assert parser.stats.bad_headers >= 1


@settings(max_examples=40, deadline=None)
@given(garbage=st.lists(st.binary(max_size=300), min_size=3, max_size=3),
       cuts=st.lists(st.integers(1, 700), min_size=1, max_size=12))
def test_parser_resynchronises_after_arbitrary_garbage(garbage, cuts):
    """Valid frames between random garbage are all recovered, whatever the chunking; garbage that
    happens to contain a sync word is counted, never turned into a frame."""
    raws = [frame(10 + i) for i in range(3)]
    stream = b"".join(g + encode_frame(r, i) for i, (g, r) in enumerate(zip(garbage, raws)))
    parser = GloveStreamParser()
    got, pos = [], 0
    for cut in cuts:
        got += parser.feed(stream[pos:pos + cut])
        pos += cut
    got += parser.feed(stream[pos:])
    assert [f.sequence for f in got] == [0, 1, 2]
    for f, r in zip(got, raws):
        np.testing.assert_array_equal(f.raw, r)
    assert parser.stats.discarded_bytes >= sum(len(g) for g in garbage) - 2 * 3  # a stray 0xA5 may wait


def test_fake_header_in_garbage_does_not_swallow_the_next_frame():
    fake = SYNC + bytes([1, 32, 32, 0, 0]) + b"\x00" * 50  # plausible header, truncated body
    parser = GloveStreamParser()
    got = parser.feed(fake + encode_frame(frame(4), 9) + encode_frame(frame(5), 10))
    assert [f.sequence for f in got] == [9, 10]
    assert parser.stats.crc_errors == 1


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=4000))
def test_random_bytes_never_crash(data):
    parser = GloveStreamParser()
    frames = parser.feed(data)
    assert all(f.raw.shape == (32, 32) for f in frames)
    assert parser.stats.discarded_bytes <= len(data)
