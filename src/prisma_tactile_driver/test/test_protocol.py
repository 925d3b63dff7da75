"""Fingertip-hub serial protocol: encoder, incremental parser, resynchronisation."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from prisma_tactile_driver.protocol import (
    ALL_FINGERS_MASK,
    SYNC,
    FrameParser,
    crc16_ccitt,
    encode_frame,
    frame_size,
    pack_counts,
    unpack_counts,
)

RNG = np.random.default_rng(0)
COUNTS = RNG.integers(0, 4096, (5, 9))


def test_crc_is_ccitt_false():
    assert crc16_ccitt(b"123456789") == 0x29B1


def test_frame_layout_is_as_documented():
    frame = encode_frame(0x1234, COUNTS)
    assert len(frame) == frame_size(ALL_FINGERS_MASK) == 78
    assert frame[:2] == SYNC and frame[2] == 1
    assert frame[3:5] == b"\x34\x12" and frame[5] == 0x1F
    assert int.from_bytes(frame[-2:], "little") == crc16_ccitt(frame[2:-2])
    # first finger, first two counts packed in 3 bytes
    a0, a1 = COUNTS[0, 0], COUNTS[0, 1]
    assert frame[6] == a0 & 0xFF and frame[7] == (a0 >> 8) | ((a1 & 0xF) << 4) and frame[8] == a1 >> 4
    assert frame[6 + 12] == COUNTS[0, 8] & 0xFF and frame[6 + 13] == COUNTS[0, 8] >> 8


def test_pack_unpack_round_trip_extremes():
    counts = np.array([[0, 4095] * 4 + [4095], [4095, 0] * 4 + [0], list(range(0, 4096, 512)) + [1]])
    np.testing.assert_array_equal(unpack_counts(pack_counts(counts), 3), counts)


def test_partial_mask_and_dict_encoding():
    frame = encode_frame(3, {"index": COUNTS[1], "little": COUNTS[4]})
    [decoded] = FrameParser().feed(frame)
    assert decoded.fingers == ("index", "little")
    np.testing.assert_array_equal(decoded.by_finger()["little"], COUNTS[4])
    with pytest.raises(ValueError, match="pinky"):
        encode_frame(0, {"pinky": COUNTS[0]})
    with pytest.raises(ValueError, match="0..4095"):
        encode_frame(0, np.full((5, 9), 4096))


def test_byte_at_a_time_delivers_every_frame():
    stream = b"".join(encode_frame(i, COUNTS) for i in range(5))
    parser = FrameParser()
    got = [f for byte in stream for f in parser.feed(bytes([byte]))]
    assert [f.sequence for f in got] == [0, 1, 2, 3, 4]
    assert parser.stats.garbage_bytes == 0 and parser.stats.resyncs == 0


def test_garbage_crc_errors_and_gaps_are_counted():
    good = [encode_frame(i, COUNTS) for i in range(6)]
    bad_crc = bytearray(good[2])
    bad_crc[20] ^= 0x40
    stream = b"\x00\xa5\x11garbage" + good[0] + good[1] + bytes(bad_crc) + good[3] + good[5]
    parser = FrameParser()
    got = parser.feed(stream)
    assert [f.sequence for f in got] == [0, 1, 3, 5]
    s = parser.stats
    assert s.frames == 4 and s.crc_errors == 1
    assert s.gaps == 2 and s.missed_frames == 2  # 2 (CRC) and 4 (never sent)
    assert s.resyncs == 2  # leading garbage, then the damaged frame
    assert s.garbage_bytes == 10 + 78


def test_bad_version_and_mask_are_skipped():
    frame = bytearray(encode_frame(1, COUNTS))
    wrong_version = bytearray(frame)
    wrong_version[2] = 9
    zero_mask = bytearray(frame)
    zero_mask[5] = 0
    parser = FrameParser()
    got = parser.feed(bytes(wrong_version) + bytes(zero_mask) + bytes(frame))
    assert [f.sequence for f in got] == [1]
    assert parser.stats.bad_headers == 2


def test_sequence_wraps_without_a_gap_and_restart_is_not_a_gap():
    parser = FrameParser()
    got = parser.feed(encode_frame(65534, COUNTS) + encode_frame(65535, COUNTS) + encode_frame(0, COUNTS)
                      + encode_frame(0, COUNTS))
    assert [f.sequence for f in got] == [65534, 65535, 0, 0]
    assert parser.stats.gaps == 0 and parser.stats.restarts == 1


def test_discard_buffer_drops_a_partial_frame():
    parser = FrameParser()
    assert parser.feed(encode_frame(0, COUNTS)[:40]) == []
    assert parser.discard_buffer() == 40
    assert [f.sequence for f in parser.feed(encode_frame(1, COUNTS))] == [1]


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600), st.lists(st.integers(0, 599), max_size=8))
def test_parser_never_raises_and_only_yields_valid_frames(noise, cuts):
    parser = FrameParser()
    frames = []
    bounds = sorted(set([0, len(noise), *[c for c in cuts if c < len(noise)]]))
    for lo, hi in zip(bounds, bounds[1:]):
        frames += parser.feed(noise[lo:hi])
    for frame in frames:
        assert frame.counts.shape[1] == 9 and frame.counts.max(initial=0) <= 4095
        assert encode_frame(frame.sequence, frame.counts, frame.mask) is not None
    s = parser.stats
    assert s.frames == len(frames)
    assert s.garbage_bytes <= len(noise)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 65535), st.integers(1, 31)), min_size=1, max_size=6),
       st.binary(max_size=40), st.binary(max_size=40), st.integers(1, 97))
def test_valid_frames_survive_surrounding_garbage_and_any_chunking(specs, before, after, chunk):
    rng = np.random.default_rng(len(specs))
    frames = [(seq, mask, rng.integers(0, 4096, (bin(mask).count("1"), 9))) for seq, mask in specs]
    stream = before + b"".join(encode_frame(s, c, m) for s, m, c in frames) + after
    parser = FrameParser()
    got = []
    for i in range(0, len(stream), chunk):
        got += parser.feed(stream[i:i + chunk])
    # garbage before may swallow nothing; each real frame appears, in order (garbage can only add
    # frames if it happens to contain a complete valid frame, which the CRC makes negligible)
    real = [(f.sequence, f.mask, f.counts.tolist()) for f in got]
    expected = [(s, m, c.tolist()) for s, m, c in frames]
    it = iter(real)
    assert all(any(e == r for r in it) for e in expected)
