"""Dynamixel Protocol 2.0 packet codec: CRC-16, byte stuffing, instruction and status packets.

Written independently of dynamixel-sdk so that the servo emulator (the other end of the wire)
checks the SDK rather than sharing its code. Packet layout:

    FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAMS... | CRC_L CRC_H

LEN counts INST + PARAMS + CRC after stuffing. Stuffing: inside INST..PARAMS every FF FF FD is
followed by an extra FD, so a header can never appear inside a packet. The CRC is CRC-16 with
polynomial 0x8005, initial value 0, no reflection, no final xor, over the stuffed packet from the
first header byte to the last parameter byte.
"""
from __future__ import annotations

from dataclasses import dataclass

HEADER = bytes([0xFF, 0xFF, 0xFD, 0x00])
BROADCAST_ID = 0xFE

INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REG_WRITE = 0x04
INST_ACTION = 0x05
INST_REBOOT = 0x08
INST_STATUS = 0x55
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83

# Error numbers carried in bits 0..6 of a status packet's error byte.
ERR_RESULT_FAIL = 1
ERR_INSTRUCTION = 2
ERR_CRC = 3
ERR_DATA_RANGE = 4
ERR_DATA_LENGTH = 5
ERR_DATA_LIMIT = 6
ERR_ACCESS = 7

CRC_POLYNOMIAL = 0x8005


def _make_crc_table(poly: int) -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ poly) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _make_crc_table(CRC_POLYNOMIAL)


def crc16(data: bytes | bytearray, crc: int = 0) -> int:
    """Protocol 2.0 CRC-16 (polynomial 0x8005, MSB first, init 0)."""
    for b in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ b) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert FD after every FF FF FD of INST..PARAMS. Only runs inside the body count: the byte
    before the body is LEN_H and the first body byte is an instruction code, never FF."""
    out = bytearray()
    for b in body:
        out.append(b)
        if b == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Inverse of `stuff`: drop the FD that follows every FF FF FD."""
    out = bytearray()
    i = 0
    while i < len(body):
        b = body[i]
        out.append(b)
        if b == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF:
            if i + 1 < len(body) and body[i + 1] == 0xFD:
                i += 1  # the stuffed byte
        i += 1
    return bytes(out)


def encode(packet_id: int, instruction: int, params: bytes = b"") -> bytes:
    """A complete packet (instruction or status: a status packet passes INST_STATUS and puts its
    error byte first in `params`)."""
    body = stuff(bytes([instruction]) + bytes(params))
    length = len(body) + 2
    head = HEADER + bytes([packet_id, length & 0xFF, length >> 8])
    crc = crc16(head + body)
    return head + body + bytes([crc & 0xFF, crc >> 8])


def encode_status(packet_id: int, error: int, params: bytes = b"") -> bytes:
    return encode(packet_id, INST_STATUS, bytes([error & 0xFF]) + bytes(params))


@dataclass(frozen=True)
class Packet:
    packet_id: int
    instruction: int
    params: bytes  # unstuffed; for a status packet params[0] is the error byte


@dataclass
class DecodeStats:
    packets: int = 0
    crc_errors: int = 0
    discarded_bytes: int = 0


class PacketDecoder:
    """Incremental decoder: feed bytes, get whole packets; garbage and bad CRC are skipped and
    counted (resync on the next header)."""

    MAX_LENGTH = 1024

    def __init__(self) -> None:
        self._buf = bytearray()
        self.stats = DecodeStats()

    def feed(self, data: bytes) -> list[Packet]:
        self._buf.extend(data)
        packets: list[Packet] = []
        while True:
            start = self._buf.find(HEADER[:3])
            if start < 0:
                # keep a possible partial header at the end
                keep = 2 if self._buf.endswith(b"\xff\xff") else (1 if self._buf.endswith(b"\xff") else 0)
                self.stats.discarded_bytes += len(self._buf) - keep
                del self._buf[: len(self._buf) - keep]
                return packets
            if start:
                self.stats.discarded_bytes += start
                del self._buf[:start]
            if len(self._buf) < 7:
                return packets
            if self._buf[3] != 0x00:
                self.stats.discarded_bytes += 1
                del self._buf[:1]
                continue
            length = self._buf[5] | (self._buf[6] << 8)
            if length < 3 or length > self.MAX_LENGTH:
                self.stats.discarded_bytes += 1
                del self._buf[:1]
                continue
            total = 7 + length
            if len(self._buf) < total:
                return packets
            raw = bytes(self._buf[:total])
            crc = raw[-2] | (raw[-1] << 8)
            if crc16(raw[:-2]) != crc:
                self.stats.crc_errors += 1
                self.stats.discarded_bytes += 1
                del self._buf[:1]
                continue
            del self._buf[:total]
            body = unstuff(raw[7:-2])
            self.stats.packets += 1
            packets.append(Packet(raw[4], body[0], body[1:]))
