"""An emulated I2C bus with a TCA9548A multiplexer and MAX11617 ADCs, at the ioctl level.

`EmulatedI2CBus.ioctl` accepts exactly what smbus2's `SMBus.i2c_rdwr` hands the kernel
(I2C_RDWR with an i2c_rdwr_ioctl_data array of i2c_msg), so the driver's real smbus2 code runs
unchanged; `emulated_smbus(bus)` returns an `SMBus` wired to it. Like the Linux i2c-dev driver,
an address nobody acknowledges aborts the transfer with OSError(EREMOTEIO).

Device behaviour modelled from the datasheets:
- TCA9548A (0x70): one control byte, bit n enables downstream channel n; a new value takes effect
  at the STOP that ends the transaction; reading returns the control byte.
- MAX11617 (0x35): a written byte with b7 = 1 is the setup byte, b7 = 0 the configuration byte
  (SCAN b6..5, CS b4..1, SGL b0). With SCAN = 00 a read returns AIN0..CS, two bytes each,
  the first byte's four MSBs high: 0xF0 | D11..D8, then D7..D0.
"""
from __future__ import annotations

import ctypes
import errno
import os
from dataclasses import dataclass, field

import numpy as np
import smbus2
from smbus2.smbus2 import I2C_M_RD, I2C_RDWR

MUX_ADDRESS = 0x70
ADC_ADDRESS = 0x35


def _nack(address: int) -> OSError:
    return OSError(errno.EREMOTEIO, f"{os.strerror(errno.EREMOTEIO)} (no ACK from 0x{address:02X})")


@dataclass
class Max11617:
    """One 12-channel 12-bit ADC; `values` are the conversion results of AIN0..AIN11."""

    values: np.ndarray = field(default_factory=lambda: np.zeros(12, dtype=np.uint16))
    setup: int | None = None
    config: int | None = None
    failing: bool = False  # a broken sensor/cable: never acknowledges
    nack_next: int = 0  # transient trouble: NACK this many addressings, then recover
    glitch_next: int = 0  # a glitched bus (SDA held low): this many reads return all-zero bytes

    def write(self, data: bytes) -> None:
        for byte in data:
            if byte & 0x80:
                self.setup = byte
            else:
                self.config = byte

    def read(self, length: int) -> bytes:
        if self.config is None:
            raise _nack(ADC_ADDRESS)  # unconfigured: the model refuses rather than guess
        if self.glitch_next > 0:
            self.glitch_next -= 1
            return bytes(length)
        scan, cs = (self.config >> 5) & 0x3, (self.config >> 1) & 0xF
        channels = list(range(cs + 1)) if scan == 0 else [cs]
        out = bytearray()
        while len(out) < length:
            for ch in channels:
                value = int(self.values[ch]) & 0x0FFF
                out += bytes([0xF0 | (value >> 8), value & 0xFF])
        return bytes(out[:length])


@dataclass
class EmulatedI2CBus:
    """TCA9548A at MUX_ADDRESS; `adcs[channel]` is the MAX11617 wired to that mux channel."""

    adcs: dict[int, Max11617] = field(default_factory=dict)
    mux_address: int = MUX_ADDRESS
    mux_control: int = 0
    transfers: int = 0
    nacks: int = 0

    def _devices(self, address: int) -> list:
        if address == self.mux_address:
            return ["mux"]
        if address != ADC_ADDRESS:
            return []
        answering = []
        for ch, adc in self.adcs.items():
            if not self.mux_control >> ch & 1 or adc.failing:
                continue
            if adc.nack_next > 0:
                adc.nack_next -= 1
                continue
            answering.append(adc)
        return answering

    def transfer(self, messages: list[tuple[int, bool, int, bytes]]) -> list[bytes]:
        """messages: (address, is_read, length, data). Returns the data of each read message."""
        self.transfers += 1
        pending_mux = None
        results = []
        for address, is_read, length, data in messages:
            devices = self._devices(address)
            if not devices:
                self.nacks += 1
                raise _nack(address)
            if devices == ["mux"]:
                if is_read:
                    results.append(bytes([self.mux_control]) * length)
                elif data:
                    pending_mux = data[-1]
                continue
            if is_read:
                reads = [adc.read(length) for adc in devices]
                # several ADCs answering at once: open-drain lines give the wired AND
                results.append(bytes(np.bitwise_and.reduce([np.frombuffer(r, np.uint8) for r in reads]).tobytes()))
            else:
                for adc in devices:
                    adc.write(data)
        if pending_mux is not None:
            self.mux_control = pending_mux  # the TCA9548A latches its channel at STOP
        return results

    def ioctl(self, fd: int, request: int, arg) -> int:
        """Stands in for fcntl.ioctl on the i2c-dev file descriptor."""
        if request != I2C_RDWR:
            raise OSError(errno.ENOTTY, f"emulated bus only handles I2C_RDWR, got 0x{request:X}")
        msgs = [arg.msgs[i] for i in range(arg.nmsgs)]
        decoded = [(m.addr, bool(m.flags & I2C_M_RD), m.len,
                    b"" if m.flags & I2C_M_RD else ctypes.string_at(m.buf, m.len)) for m in msgs]
        reads = iter(self.transfer(decoded))
        for m in msgs:
            if m.flags & I2C_M_RD:
                ctypes.memmove(m.buf, next(reads), m.len)
        return 0


# Emulated buses get negative pseudo file descriptors; smbus2's module-level `ioctl` is routed
# through _routing_ioctl, which hands those to the emulator and everything else to fcntl.ioctl.
_EMULATED: dict[int, EmulatedI2CBus] = {}
_real_ioctl = smbus2.smbus2.ioctl


def _routing_ioctl(fd, request, arg=0, *rest):
    if isinstance(fd, int) and fd in _EMULATED:
        return _EMULATED[fd].ioctl(fd, request, arg)
    return _real_ioctl(fd, request, arg, *rest)


class EmulatedSMBus(smbus2.SMBus):
    """A real smbus2.SMBus (its own i2c_msg marshalling and i2c_rdwr) whose I2C_RDWR ioctl
    reaches the emulated bus instead of /dev/i2c-N."""

    def __init__(self, bus: EmulatedI2CBus) -> None:
        super().__init__(None)
        smbus2.smbus2.ioctl = _routing_ioctl
        self.emulated = bus
        self.fd = -1 - len(_EMULATED)
        _EMULATED[self.fd] = bus

    def close(self) -> None:
        _EMULATED.pop(self.fd, None)
        self.fd = None


def five_finger_bus(values: dict[int, np.ndarray] | None = None) -> EmulatedI2CBus:
    """A hub with one MAX11617 on each of mux channels 0..4."""
    bus = EmulatedI2CBus()
    for ch in range(5):
        adc = Max11617()
        if values and ch in values:
            adc.values[: len(values[ch])] = values[ch]
        bus.adcs[ch] = adc
    return bus
