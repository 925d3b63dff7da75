"""STAG readout serial protocol, version 1 (docs/protocols.md, section "STAG glove readout").

One frame = the whole 32x32 grid of 10-bit ADC readings:

    offset  size  field
    0       2     sync 0xA5 0x5A
    2       1     version (1)
    3       1     rows
    4       1     cols
    5       2     sequence number, uint16 little-endian, +1 per frame, wraps at 65536
    7       P     readings, row-major, 10 bits each, packed 4 readings -> 5 bytes
                  (the 40-bit little-endian group word holds reading k in bits 10k..10k+9)
    7+P     2     CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of bytes 2..7+P-1, little-endian

P = rows*cols*10/8 (1280 bytes for 32x32; 1289 bytes per frame). The parser resynchronises on the
sync word after garbage, rejects frames with a bad CRC or an unexpected header, and counts every
discarded byte, CRC error and sequence gap.
"""
from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field

import numpy as np

SYNC = b"\xa5\x5a"
VERSION = 1
HEADER_SIZE = 7
CRC_SIZE = 2
MAX_DIM = 64


def crc16_ccitt(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (binascii implements it as crc_hqx)."""
    return binascii.crc_hqx(data, 0xFFFF)


def payload_size(rows: int, cols: int) -> int:
    return rows * cols * 10 // 8


def frame_size(rows: int = 32, cols: int = 32) -> int:
    return HEADER_SIZE + payload_size(rows, cols) + CRC_SIZE


def pack10(values: np.ndarray) -> bytes:
    """10-bit readings (count divisible by 4) -> packed bytes, 4 readings per 5 bytes."""
    flat = np.asarray(values).reshape(-1)
    if flat.size % 4:
        raise ValueError(f"reading count must be a multiple of 4, got {flat.size}")
    if flat.size and (flat.min() < 0 or flat.max() > 1023):
        raise ValueError(f"readings must be 0..1023, got range {flat.min()}..{flat.max()}")
    groups = flat.astype(np.uint64).reshape(-1, 4)
    words = groups[:, 0] | (groups[:, 1] << 10) | (groups[:, 2] << 20) | (groups[:, 3] << 30)
    out = np.empty((groups.shape[0], 5), dtype=np.uint8)
    for k in range(5):
        out[:, k] = (words >> np.uint64(8 * k)) & np.uint64(0xFF)
    return out.tobytes()


def unpack10(data: bytes, count: int) -> np.ndarray:
    """Inverse of pack10: uint16 array of `count` readings."""
    need = count * 10 // 8
    if count % 4 or len(data) < need:
        raise ValueError(f"need {need} bytes for {count} readings, got {len(data)}")
    groups = np.frombuffer(data, dtype=np.uint8, count=need).reshape(-1, 5).astype(np.uint64)
    words = np.zeros(groups.shape[0], dtype=np.uint64)
    for k in range(5):
        words |= groups[:, k] << np.uint64(8 * k)
    out = np.empty((groups.shape[0], 4), dtype=np.uint16)
    for k in range(4):
        out[:, k] = (words >> np.uint64(10 * k)) & np.uint64(0x3FF)
    return out.reshape(-1)


def encode_frame(raw: np.ndarray, sequence: int) -> bytes:
    """One protocol frame for a [rows, cols] grid of 10-bit counts (what the firmware sends)."""
    raw = np.asarray(raw)
    if raw.ndim != 2 or not (1 <= raw.shape[0] <= MAX_DIM and 1 <= raw.shape[1] <= MAX_DIM):
        raise ValueError(f"frame must be [rows, cols] with 1..{MAX_DIM} each, got {raw.shape}")
    rows, cols = raw.shape
    body = struct.pack("<BBBH", VERSION, rows, cols, sequence & 0xFFFF) + pack10(raw)
    return SYNC + body + struct.pack("<H", crc16_ccitt(body))


@dataclass
class RawFrame:
    sequence: int
    raw: np.ndarray  # uint16 [rows, cols]


@dataclass
class ParserStats:
    frames: int = 0
    crc_errors: int = 0
    bad_headers: int = 0
    discarded_bytes: int = 0
    dropped_frames: int = 0  # inferred from sequence gaps


@dataclass
class GloveStreamParser:
    """Incremental parser: feed() any chunk of bytes, get back the complete valid frames."""

    rows: int = 32
    cols: int = 32
    stats: ParserStats = field(default_factory=ParserStats)
    max_buffer: int = 1 << 16

    def __post_init__(self) -> None:
        self._buffer = bytearray()
        self._last_sequence: int | None = None
        self._size = frame_size(self.rows, self.cols)

    def reset(self) -> None:
        """Forget partial data and the sequence history (after a reconnect)."""
        self._buffer.clear()
        self._last_sequence = None

    def feed(self, data: bytes) -> list[RawFrame]:
        self._buffer += data
        frames: list[RawFrame] = []
        while True:
            start = self._buffer.find(SYNC)
            if start < 0:
                # keep a trailing 0xA5: it may be the first half of the next sync word
                keep = 1 if self._buffer.endswith(SYNC[:1]) else 0
                self._discard(len(self._buffer) - keep)
                break
            if start:
                self._discard(start)
            if len(self._buffer) < HEADER_SIZE:
                break
            version, rows, cols = self._buffer[2], self._buffer[3], self._buffer[4]
            if version != VERSION or rows != self.rows or cols != self.cols:
                self.stats.bad_headers += 1
                self._discard(1)
                continue
            if len(self._buffer) < self._size:
                break
            frame = bytes(self._buffer[:self._size])
            body, (crc,) = frame[2:-CRC_SIZE], struct.unpack("<H", frame[-CRC_SIZE:])
            if crc16_ccitt(body) != crc:
                self.stats.crc_errors += 1
                self._discard(1)
                continue
            del self._buffer[:self._size]
            (sequence,) = struct.unpack("<H", frame[5:7])
            self._count_gap(sequence)
            raw = unpack10(frame[HEADER_SIZE:-CRC_SIZE], self.rows * self.cols).reshape(self.rows, self.cols)
            frames.append(RawFrame(sequence, raw))
            self.stats.frames += 1
        if len(self._buffer) > self.max_buffer:  # cannot happen with sane input; bounded anyway
            self._discard(len(self._buffer) - self._size)
        return frames

    def _discard(self, count: int) -> None:
        if count > 0:
            del self._buffer[:count]
            self.stats.discarded_bytes += count

    def _count_gap(self, sequence: int) -> None:
        if self._last_sequence is not None:
            gap = (sequence - self._last_sequence - 1) & 0xFFFF
            # a huge "gap" is a firmware restart (sequence back to 0), not 60000 lost frames
            if gap < 0x8000:
                self.stats.dropped_frames += gap
        self._last_sequence = sequence
