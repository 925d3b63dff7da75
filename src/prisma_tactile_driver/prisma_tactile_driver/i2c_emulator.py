"""An emulated I2C bus with a TCA9548A multiplexer and MAX11617 ADCs, at the ioctl level.

`EmulatedI2CBus.ioctl` accepts exactly what smbus2's `SMBus.i2c_rdwr` hands the kernel
(I2C_RDWR with an i2c_rdwr_ioctl_data array of i2c_msg), so the driver's real smbus2 code runs
unchanged; `EmulatedSMBus(bus)` is an `SMBus` wired to it (`i2c_socket.SocketSMBus` reaches one
in another process). Like the Linux i2c-dev driver, an address nobody acknowledges aborts the
transfer with OSError(EREMOTEIO), and more than 42 messages or one longer than 8192 bytes are
refused with OSError(EINVAL).

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
import itertools
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import smbus2
from smbus2.smbus2 import I2C_M_RD, I2C_RDWR

MUX_ADDRESS = 0x70
ADC_ADDRESS = 0x35
I2C_RDWR_MAX_MSGS = 42  # the kernel's I2C_RDWR_IOCTL_MAX_MSGS
I2C_MSG_MAX_LEN = 8192  # i2c-dev refuses longer messages

# (address, is_read, length, write data) of each message of one I2C_RDWR transaction
Messages = list[tuple[int, bool, int, bytes]]


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

    def transfer(self, messages: Messages) -> list[bytes]:
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

    def ioctl(self, fd: int, request: int, arg: Any) -> int:
        """Stands in for fcntl.ioctl on the i2c-dev file descriptor."""
        return i2c_rdwr_ioctl(self.transfer, request, arg)


def check_messages(messages: Messages) -> None:
    """OSError(EINVAL) for a transaction i2c-dev refuses before it reaches the bus."""
    if not 1 <= len(messages) <= I2C_RDWR_MAX_MSGS:
        raise OSError(errno.EINVAL, f"{os.strerror(errno.EINVAL)} ({len(messages)} messages in one I2C_RDWR, "
                                    f"i2c-dev takes 1..{I2C_RDWR_MAX_MSGS})")
    for address, _is_read, length, _data in messages:
        if length > I2C_MSG_MAX_LEN:
            raise OSError(errno.EINVAL, f"{os.strerror(errno.EINVAL)} ({length}-byte message to 0x{address:02X}, "
                                        f"i2c-dev takes at most {I2C_MSG_MAX_LEN})")


def i2c_rdwr_ioctl(transfer: Callable[[Messages], list[bytes]], request: int, arg: Any) -> int:
    """The I2C_RDWR ioctl on top of `transfer` (`EmulatedI2CBus.transfer` or a remote one): decodes
    smbus2's i2c_rdwr_ioctl_data and copies the data read back into its i2c_msg buffers."""
    if request != I2C_RDWR:
        raise OSError(errno.ENOTTY, f"emulated bus only handles I2C_RDWR, got 0x{request:X}")
    msgs = [arg.msgs[i] for i in range(arg.nmsgs)]
    decoded = [(m.addr, bool(m.flags & I2C_M_RD), m.len,
                b"" if m.flags & I2C_M_RD else ctypes.string_at(m.buf, m.len)) for m in msgs]
    check_messages(decoded)
    reads = iter(transfer(decoded))
    for m in msgs:
        if m.flags & I2C_M_RD:
            ctypes.memmove(m.buf, next(reads), m.len)
    return 0


# Emulated buses get negative pseudo file descriptors, never one the OS hands out and never
# reused while the process lives (a closed bus's number must not reach a newer one); smbus2's
# module-level `ioctl` is routed through _routing_ioctl, which hands those to their handler and
# everything else to fcntl.ioctl.
IoctlHandler = Callable[[int, int, Any], int]  # (fd, request, arg) -> result, like fcntl.ioctl
_ROUTES: dict[int, IoctlHandler] = {}
_pseudo_fds = itertools.count(-1, -1)
# (smbus2's type stub does not declare the `ioctl` its module imports from fcntl)
_real_ioctl = smbus2.smbus2.ioctl  # type: ignore[attr-defined]


def _routing_ioctl(fd, request, arg=0, *rest):
    handler = _ROUTES.get(fd) if isinstance(fd, int) else None
    if handler is not None:
        return handler(fd, request, arg)
    return _real_ioctl(fd, request, arg, *rest)


def route_ioctl(handler: IoctlHandler) -> int:
    """A pseudo file descriptor for an SMBus whose ioctls `handler` serves instead of the kernel."""
    smbus2.smbus2.ioctl = _routing_ioctl  # type: ignore[attr-defined]
    fd = next(_pseudo_fds)
    _ROUTES[fd] = handler
    return fd


def unroute_ioctl(fd: int | None) -> None:
    if fd is not None:
        _ROUTES.pop(fd, None)


class EmulatedSMBus(smbus2.SMBus):
    """A real smbus2.SMBus (its own i2c_msg marshalling and i2c_rdwr) whose I2C_RDWR ioctl
    reaches the emulated bus instead of /dev/i2c-N."""

    def __init__(self, bus: EmulatedI2CBus) -> None:
        super().__init__(None)
        self.emulated = bus
        self.fd = route_ioctl(bus.ioctl)

    def close(self) -> None:
        unroute_ioctl(self.fd)  # SMBus.close would os.close() the pseudo descriptor
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
