"""Fingertip-hub serial protocol: frame encoder and incremental stream parser.

Frame layout (all multi-byte integers little-endian; docs/protocols.md has the full spec):

    offset  size  field
    0       2     sync 0xA5 0x5A
    2       1     version (1)
    3       2     sequence number, uint16, +1 per frame, wraps 65535 -> 0
    5       1     finger mask: bit n set = finger n present (0 thumb .. 4 little), 1..0x1F
    6       14*n  per present finger, in bit order: 9 x 12-bit counts packed two per 3 bytes
                  (a0 = b0 | (b1 & 0x0F) << 8, a1 = b1 >> 4 | b2 << 4), the ninth in 2 bytes
                  (low byte, then high nibble; the upper 4 bits are 0)
    6+14n   2     CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over bytes 2 .. 5+14n

A five-finger frame is 78 bytes. The parser never raises on input bytes: it resynchronises on
the next sync pattern after garbage, a bad header or a CRC failure, and counts every event.
"""
from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field

import numpy as np

from prisma_common.hand import ADC_MAX, FINGERS, N_TAXELS

SYNC = b"\xa5\x5a"
VERSION = 1
HEADER_SIZE = 6  # sync(2) + version(1) + sequence(2) + mask(1)
FINGER_PAYLOAD = 14  # 9 x 12 bit = 13.5 bytes, padded to 14
CRC_SIZE = 2
ALL_FINGERS_MASK = (1 << len(FINGERS)) - 1
SEQUENCE_MODULO = 1 << 16
_HEADER = struct.Struct("<2sBHB")
_CRC = struct.Struct("<H")


def crc16_ccitt(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE (check value of b'123456789' is 0x29B1)."""
    return binascii.crc_hqx(data, crc)


def frame_size(mask: int) -> int:
    return HEADER_SIZE + FINGER_PAYLOAD * bin(mask).count("1") + CRC_SIZE


def mask_fingers(mask: int) -> tuple[str, ...]:
    return tuple(f for bit, f in enumerate(FINGERS) if mask >> bit & 1)


def pack_counts(counts: np.ndarray) -> bytes:
    """(n, 9) counts (0..4095) -> n * 14 bytes."""
    c = np.asarray(counts, dtype=np.uint16).reshape(-1, N_TAXELS)
    out = np.zeros((c.shape[0], FINGER_PAYLOAD), dtype=np.uint8)
    a, b = c[:, 0:8:2], c[:, 1:8:2]
    out[:, 0:12:3] = a & 0xFF
    out[:, 1:12:3] = (a >> 8) | ((b & 0x0F) << 4)
    out[:, 2:12:3] = b >> 4
    out[:, 12] = c[:, 8] & 0xFF
    out[:, 13] = c[:, 8] >> 8
    return out.tobytes()


def unpack_counts(payload: bytes | memoryview, n_fingers: int) -> np.ndarray:
    """n * 14 bytes -> (n, 9) uint16 counts."""
    raw = np.frombuffer(payload, dtype=np.uint8).reshape(n_fingers, FINGER_PAYLOAD).astype(np.uint16)
    counts = np.empty((n_fingers, N_TAXELS), dtype=np.uint16)
    b0, b1, b2 = raw[:, 0:12:3], raw[:, 1:12:3], raw[:, 2:12:3]
    counts[:, 0:8:2] = b0 | ((b1 & 0x0F) << 8)
    counts[:, 1:8:2] = (b1 >> 4) | (b2 << 4)
    counts[:, 8] = raw[:, 12] | ((raw[:, 13] & 0x0F) << 8)
    return counts


@dataclass
class HubFrame:
    """One decoded hub frame: the sequence number and 9 counts per present finger."""

    sequence: int
    mask: int
    counts: np.ndarray  # uint16[n_present, 9], rows in finger-bit order

    @property
    def fingers(self) -> tuple[str, ...]:
        return mask_fingers(self.mask)

    def by_finger(self) -> dict[str, np.ndarray]:
        return dict(zip(self.fingers, self.counts))


def encode_frame(sequence: int, counts: dict[str, np.ndarray] | np.ndarray, mask: int | None = None) -> bytes:
    """Encode one frame. `counts` maps finger -> 9 counts, or is an (n, 9) array for `mask`."""
    if isinstance(counts, dict):
        unknown = set(counts) - set(FINGERS)
        if unknown:
            raise ValueError(f"unknown finger(s) {sorted(unknown)}; expected names from {FINGERS}")
        mask = sum(1 << FINGERS.index(f) for f in counts)
        rows = np.array([counts[f] for f in mask_fingers(mask)], dtype=np.int64)
    else:
        if mask is None:
            mask = ALL_FINGERS_MASK
        rows = np.asarray(counts, dtype=np.int64).reshape(-1, N_TAXELS)
    if not 1 <= mask <= ALL_FINGERS_MASK:
        raise ValueError(f"finger mask must be 1..0x{ALL_FINGERS_MASK:02X}, got 0x{mask:X}")
    if rows.shape[0] != bin(mask).count("1"):
        raise ValueError(f"mask 0x{mask:02X} names {bin(mask).count('1')} fingers, got {rows.shape[0]} rows")
    if rows.size and (rows.min() < 0 or rows.max() > ADC_MAX):
        raise ValueError(f"counts must be 0..{ADC_MAX}, got {rows.min()}..{rows.max()}")
    body = struct.pack("<BHB", VERSION, sequence % SEQUENCE_MODULO, mask) + pack_counts(rows)
    return SYNC + body + _CRC.pack(crc16_ccitt(body))


@dataclass
class ParserStats:
    frames: int = 0  # frames delivered (CRC good)
    crc_errors: int = 0  # complete candidate frames whose CRC failed
    bad_headers: int = 0  # sync followed by an unknown version or an invalid finger mask
    resyncs: int = 0  # times the parser lost sync and had to search for the next sync pattern
    garbage_bytes: int = 0  # bytes skipped while resynchronising
    gaps: int = 0  # sequence discontinuities
    missed_frames: int = 0  # sequence numbers never delivered (sum over gaps)
    restarts: int = 0  # sequence jumped backwards (the hub restarted)

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass
class FrameParser:
    """Incremental parser: feed() any bytes, get whole good frames back, in stream order."""

    stats: ParserStats = field(default_factory=ParserStats)
    _buffer: bytearray = field(default_factory=bytearray, repr=False)
    _last_sequence: int | None = field(default=None, repr=False)
    _in_sync: bool = field(default=True, repr=False)

    def feed(self, data: bytes | bytearray | memoryview) -> list[HubFrame]:
        buf = self._buffer
        buf += data
        frames: list[HubFrame] = []
        start = 0  # consume by index; one deletion at the end keeps feed() linear
        stats = self.stats
        while True:
            found = buf.find(SYNC, start)
            if found < 0:
                # keep a trailing first sync byte: the pattern may straddle two reads
                keep = 1 if len(buf) > start and buf[-1] == SYNC[0] else 0
                self._skip(len(buf) - keep - start)
                start = len(buf) - keep
                break
            if found > start:
                self._skip(found - start)
                start = found
            if len(buf) - start < HEADER_SIZE:
                break
            _, version, sequence, mask = _HEADER.unpack_from(buf, start)
            if version != VERSION or not 1 <= mask <= ALL_FINGERS_MASK:
                stats.bad_headers += 1
                self._skip(1)
                start += 1
                continue
            size = frame_size(mask)
            if len(buf) - start < size:
                break
            body_end = start + size - CRC_SIZE
            (crc,) = _CRC.unpack_from(buf, body_end)
            if crc != crc16_ccitt(bytes(buf[start + 2:body_end])):
                stats.crc_errors += 1
                self._skip(1)
                start += 1
                continue
            n = (size - HEADER_SIZE - CRC_SIZE) // FINGER_PAYLOAD
            counts = unpack_counts(bytes(buf[start + HEADER_SIZE:body_end]), n)
            frames.append(HubFrame(sequence, mask, counts))
            self._track_sequence(sequence)
            stats.frames += 1
            self._in_sync = True
            start += size
        del buf[:start]
        return frames

    def discard_buffer(self) -> int:
        """Drop a partial frame (the link went down mid-frame); returns the bytes dropped."""
        dropped = len(self._buffer)
        if dropped:
            self._skip(dropped)
        self._buffer.clear()
        return dropped

    def _skip(self, n: int) -> None:
        if n > 0:
            if self._in_sync:  # count each loss of sync once, however many bytes it costs
                self.stats.resyncs += 1
                self._in_sync = False
            self.stats.garbage_bytes += n

    def _track_sequence(self, sequence: int) -> None:
        last = self._last_sequence
        self._last_sequence = sequence
        if last is None:
            return
        missing = (sequence - last - 1) % SEQUENCE_MODULO
        if missing == 0:
            return
        if missing >= SEQUENCE_MODULO // 2:  # a jump backwards: the hub restarted its counter
            self.stats.restarts += 1
            return
        self.stats.gaps += 1
        self.stats.missed_frames += missing
